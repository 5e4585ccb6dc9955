# The two commands of the README: `make run` and `make test`. Both set up first (fast when
# nothing changed); `make setup` alone just sets up.
PY := .venv/bin/python

.PHONY: setup run test lint format bench clean

setup:
	@bash tools/setup.sh

run: setup
	.venv/bin/activetrack run scenarios/default.yaml

# Two workers, each test file on one (its module fixtures computed once).
test: setup
	$(PY) -m pytest -n 2 --dist loadfile

lint: setup
	.venv/bin/ruff check .
	.venv/bin/ruff format --check .

format: setup
	.venv/bin/ruff format .
	.venv/bin/ruff check --fix .

# Filter benchmarks against Stone Soup and filterpy; Stone Soup is installed for this only.
bench: setup
	$(PY) -m pip install -qq -r requirements-bench.txt -c constraints.txt
	$(PY) benchmarks/filters.py
	$(PY) benchmarks/multitarget.py --quick

clean:
	rm -rf build .venv runs
