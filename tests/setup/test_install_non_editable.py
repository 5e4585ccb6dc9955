"""The core and the experiments work from a plain (non-editable) install, outside the source
tree: the experiments find the papers' scenario files as package data.

A scratch venv gets the third-party dependencies of the project's venv on its path (a .pth line,
which does not run the editable installs' hooks) and the two packages installed by pip from
copies of their sources; a reproduction then runs from an unrelated directory with ``-I``
(no current directory, no PYTHONPATH on the path).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("activetrack", "activetrack_experiments")


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> Path:
    """A venv with the two packages installed by pip, non-editable."""
    base = tmp_path_factory.mktemp("install")
    venv = base / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    site = Path(
        subprocess.run(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    )
    (site / "project_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    sources = []
    for name in PACKAGES:  # copies: the build leaves nothing in the source tree
        dest = base / "src" / name
        shutil.copytree(ROOT / "src" / name, dest, symlinks=False)
        sources.append(str(dest))
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "--disable-pip-version-check",
            "--target",
            str(site),
            *sources,
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return python


def _run(python: Path, code: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(python), "-I", "-c", code], cwd=cwd, capture_output=True, text=True, check=False
    )


def test_packages_import_from_the_install(scratch, tmp_path):
    code = (
        "import activetrack, activetrack_experiments as ax\n"
        "print(activetrack.__file__); print(ax.__file__)\n"
        "print(ax.find_scenarios_dir())\n"
        "print(ax.scenario_path('hernandez_1sensor_single'))\n"
    )
    out = _run(scratch, code, tmp_path)
    assert out.returncode == 0, out.stderr
    files = out.stdout.split()
    assert all(str(scratch.parents[1]) in f for f in files), files
    assert not any(str(ROOT / "src") in f for f in files), files
    assert Path(files[3]).is_file()


def test_a_reproduction_runs_from_the_install(scratch, tmp_path):
    code = (
        "from activetrack_experiments import vanderhook\n"
        "import sys\n"
        "sys.exit(vanderhook.main(['--runs', '20', '--quick', '--out', 'vh']))\n"
    )
    out = _run(scratch, code, tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "Table I" in out.stdout
    assert (tmp_path / "vh").is_dir()


def test_a_reproduction_finds_its_scenario_files_in_the_install(scratch, tmp_path):
    code = (
        "from activetrack_experiments import hernandez\n"
        "import sys\n"
        "args = ['--runs', '2', '--particles', '500', '--no-figures', '--no-comparison',\n"
        "        '--sensors', '1', '--horizons', '1', '--jobs', '1']\n"
        "sys.exit(hernandez.main(args))\n"
    )
    out = _run(scratch, code, tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    # Hernandez' 1-sensor single-step bound, as from the source tree (docs/hernandez.md).
    assert "1 sensor(s), single-step: bound (12.46, 10.93) m" in out.stdout + out.stderr
