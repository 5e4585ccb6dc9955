"""Reproductions of the papers activetrack implements, as clients of the core library.

Each module has a ``reproduce(...)`` function taking plain arguments and returning a dataclass
of results (arrays, tables, ``to_json()``), and a command line on top (``main(argv)``,
``activetrack reproduce NAME``): a :class:`~activetrack_experiments.reproduction.Reproduction`,
the driver every paper shares, that prints, plots and writes JSON::

    from activetrack_experiments import hernandez
    res = hernandez.reproduce(runs=4, jobs=2)

The core never imports this package.
"""

from activetrack_experiments.paths import find_scenarios_dir, scenario_path

__all__ = ["find_scenarios_dir", "scenario_path"]
