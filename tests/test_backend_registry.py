"""Backends by name (``vcigen.backends.registry``): ``build`` looks them up; no import cycle."""

from __future__ import annotations

import subprocess
import sys

import pytest
from hard_scenes import ball

import vcigen
from vcigen.backends import registry


def test_unknown_backend_lists_the_choices() -> None:
    with pytest.raises(ValueError, match=r"unknown backend 'fortran'; choose one of \['casadi', 'c'"):
        vcigen.build(ball(), backend="fortran")


def test_a_registered_backend_is_built_by_name(monkeypatch) -> None:
    seen = {}

    def factory(system, tol, **options):
        seen.update(system=system, tol=tol, options=options)
        return "a simulator"

    monkeypatch.setattr(registry, "_FACTORIES", dict(registry._FACTORIES))
    registry.register("mine", factory)
    assert "mine" in registry.names()
    tol = vcigen.Tolerances(residual=1e-10)
    assert vcigen.build(ball(), backend="mine", tol=tol, flag=1) == "a simulator"
    assert seen["tol"] is tol and seen["options"] == {"flag": 1} and seen["system"].model.name == "ball"
    with pytest.raises(ValueError, match="non-empty string"):
        registry.register("", factory)


def test_the_simulator_does_not_import_a_backend() -> None:
    """``vcigen`` (simulator, registry) loads no backend module until one is built: no cycle
    c.py -> cwrap.py -> simulator.py -> c.py."""
    code = (
        "import sys, vcigen; print(sorted(m for m in sys.modules "
        "if m.startswith('vcigen.backends.') and m != 'vcigen.backends.registry'))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
