"""Plugins: Python modules a scenario file names, imported before the rest of it is validated
(docs/extending.md, "Plugins").

A scenario's top-level ``plugins: [my_sensors, my_package.filters]`` lists modules that register
what the file uses (a sensor kind, a filter, a planner criterion); :func:`import_plugins`
imports them, in order, so every process that loads the scenario knows them. Importing a module
runs its code with the rights of the process: a scenario file that names plugins is as trusted
as a Python script. The names are checked first (dotted identifiers, no paths, no relative
imports); modules are found on the ordinary import path, never next to the scenario file.
"""

from __future__ import annotations

import importlib
import keyword
from typing import Annotated

from pydantic import AfterValidator, Field

from activetrack.scenarios.fields import shown

__all__ = ["MAX_PLUGINS", "PluginError", "Plugins", "check_plugin_names", "import_plugins"]

MAX_PLUGINS = 32  # modules per scenario
MAX_PLUGIN_NAME = 200  # characters of one dotted name
_SHOW = 200  # characters of an exception message shown in an error


class PluginError(ValueError):
    """A ``plugins:`` entry that is not a module name or that cannot be imported (one line)."""


def _is_module_name(name: object) -> bool:
    if not isinstance(name, str) or not 0 < len(name) <= MAX_PLUGIN_NAME:
        return False
    return all(part.isidentifier() and not keyword.iskeyword(part) for part in name.split("."))


def check_plugin_names(value: object) -> list[str]:
    """``value`` as a list of module names; PluginError naming the first bad entry."""
    if not isinstance(value, list):
        raise PluginError(
            f"plugins: must be a list of Python module names, got {type(value).__name__} "
            f"{shown(value)}"
        )
    if len(value) > MAX_PLUGINS:
        raise PluginError(f"plugins: at most {MAX_PLUGINS} modules, got {len(value)}")
    for i, name in enumerate(value):
        if not _is_module_name(name):
            raise PluginError(
                f"plugins[{i}]: must be a Python module name (identifiers joined by '.', e.g. "
                f"my_package.my_sensors; at most {MAX_PLUGIN_NAME} characters), "
                f"got {shown(name)}"
            )
    return list(value)


# A file's ``plugins:`` field: the names only (the loader imports them).
Plugins = Annotated[list[str], Field(max_length=MAX_PLUGINS), AfterValidator(check_plugin_names)]


def import_plugins(value: object) -> list[str]:
    """Check the names (:func:`check_plugin_names`) and import each module, in order.

    A module imported before (in this process) is not run again. Any failure, including an
    exception raised by the module's own code (e.g. a registration it makes), becomes one
    PluginError line naming ``plugins[i]`` and the module. Returns the names.
    """
    names = check_plugin_names(value)
    for i, name in enumerate(names):
        try:
            importlib.import_module(name)
        except (Exception, SystemExit) as exc:
            detail = " ".join(str(exc).split())
            if len(detail) > _SHOW:
                detail = detail[:_SHOW] + "..."
            hint = ""
            missing = getattr(exc, "name", None)  # the plugin itself, or a package of it?
            if isinstance(exc, ModuleNotFoundError) and f"{name}.".startswith(f"{missing}."):
                hint = (
                    "; it must be importable in every process that loads the scenario "
                    "(installed, or its folder on PYTHONPATH)"
                )
            raise PluginError(
                f"plugins[{i}]: cannot import module {name!r} ({type(exc).__name__}: "
                f"{detail}){hint}"
            ) from None
    return names
