# The two commands of the README: `make run` and `make test`. Both set up first (fast when
# nothing changed); `make setup` alone just sets up.
PY := .venv/bin/python

.PHONY: setup run test lint format bench clean

setup:
	@bash tools/setup.sh

run: setup
	$(PY) -m activetrack_bringup.cli smoke

test: setup
	$(PY) -m pytest

lint: setup
	.venv/bin/ruff check .
	.venv/bin/ruff format --check .

format: setup
	.venv/bin/ruff format .
	.venv/bin/ruff check --fix .

clean:
	rm -rf build .venv runs
