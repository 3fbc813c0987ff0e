"""Backends by name (PyDy's pattern): ``vcigen.build(model, backend=...)`` looks the backend up here.

A backend is a factory ``(system, tol, **options) -> Simulator``. The built-in ones are named by the
module that defines them and imported on first use, so neither the simulator nor this module imports a
backend (the C wrapper imports the simulator, never the other way round). ``register`` adds another.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

Factory = Callable[..., Any]

_FACTORIES: dict[str, str | Factory] = {
    "casadi": "vcigen.backends.casadi:build_casadi",
    "c": "vcigen.backends.c:build_c",
}


def register(name: str, factory: Factory) -> None:
    """Make ``build(..., backend=name)`` call ``factory(system, tol, **options)``."""
    if not name or not isinstance(name, str):
        raise ValueError(f"a backend name must be a non-empty string, got {name!r}")
    _FACTORIES[name] = factory


def names() -> tuple[str, ...]:
    """The registered backends."""
    return tuple(_FACTORIES)


def factory(name: str) -> Factory:
    """The factory of backend ``name``; a ``ValueError`` listing the choices if there is none."""
    entry = _FACTORIES.get(name) if isinstance(name, str) else None
    if entry is None:
        raise ValueError(f"unknown backend {name!r}; choose one of {list(_FACTORIES)}")
    if isinstance(entry, str):
        module, attr = entry.split(":")
        entry = _FACTORIES[name] = getattr(importlib.import_module(module), attr)
    return entry
