"""Controllers by name, the way python-can finds interfaces: ``controller.type`` names a built-in or
an installed plugin.

A plugin package declares its controller in its own ``pyproject.toml``::

    [project.entry-points."ankle_rt.controllers"]
    phase = "my_package.controller:PhaseController"

The entry point names a callable taking a :class:`~ankle_rt.control.base.ControllerContext` and
returning a controller (usually a :class:`~ankle_rt.control.base.Controller` subclass). The
built-ins are registered the same way, as ``module:attribute`` strings loaded only when chosen;
a plugin cannot take a built-in's name. ``examples/ankle-rt-example-controller`` is a complete plugin.
"""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from ankle_rt.control import CycleController
    from ankle_rt.control.base import ControllerContext

ENTRY_POINT_GROUP = "ankle_rt.controllers"

BUILTIN_CONTROLLERS: dict[str, str] = {
    "pd": "ankle_rt.control:pd_controller",
    "impedance": "ankle_rt.control:impedance_controller",
    "gait_phase": "ankle_rt.control:gait_phase_controller",
}


class ControllerNotFound(ValueError):
    """``controller.type`` names no built-in and no installed plugin, or the plugin cannot be loaded."""


def available_controllers() -> dict[str, str]:
    """Name -> ``module:attribute`` of every built-in and installed plugin controller."""
    found = dict(BUILTIN_CONTROLLERS)
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(ep.name, ep.value)
    return found


def check_controller_name(name: str) -> None:
    """Raise ControllerNotFound (a ValueError) unless ``name`` is a known controller."""
    if name in BUILTIN_CONTROLLERS:       # no entry-point scan (~15 ms) for a built-in
        return
    known = available_controllers()
    if name not in known:
        raise ControllerNotFound(f"unknown controller {name!r} (built-in or installed: {', '.join(sorted(known))}; "
                                 f"a plugin registers itself under the entry-point group {ENTRY_POINT_GROUP!r})")


def load_controller_factory(name: str) -> Callable[["ControllerContext"], "CycleController"]:
    """The factory ``name`` refers to (imported now)."""
    check_controller_name(name)
    spec = BUILTIN_CONTROLLERS.get(name) or available_controllers()[name]   # built-ins win, as there
    module_name, _, attr = spec.partition(":")
    try:
        obj = importlib.import_module(module_name)
        for part in attr.split(".") if attr else ():
            obj = getattr(obj, part)
    except Exception as exc:   # a plugin's import may raise anything (SyntaxError, its own errors, ...)
        raise ControllerNotFound(f"controller {name!r}: cannot load {spec}: {type(exc).__name__}: {exc}") from None
    if not callable(obj):
        raise ControllerNotFound(f"controller {name!r}: {spec} is not callable")
    return obj
