"""What a scene allows is detected once per derived system (vcigen.structure) and read by both backends.

The CasADi kernels, the C render context and the C kernels all read ``system.structure``: one object,
one call of :func:`vcigen.structure.detect` per system; the generated header prints each flag and why.
"""

from __future__ import annotations

import shutil

import pytest
import sympy as sp
from scenes import star_nonlinear

import vcigen
from vcigen import structure as structure_module
from vcigen.backends import registry
from vcigen.backends.c import render
from vcigen.backends.ccontext import render_context
from vcigen.structure import FLAGS


def _ball() -> vcigen.Model:
    """A ball bouncing to rest on a floor (e = 1/2): every specialisation (explicit, quadratic jump, held)."""
    x, y, xd, yd, e = sp.symbols("x y xd yd e")
    return vcigen.Model(
        name="structure_ball",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - 9.81 * y,
        contacts={"floor": y},
        params={e: 0.5},
        restitution={"floor": e},
    )


def _counted(monkeypatch: pytest.MonkeyPatch) -> list:
    """Record every system :func:`vcigen.structure.detect` runs on."""
    calls = []
    detect = structure_module.detect

    def counting(system):
        calls.append(system)
        return detect(system)

    monkeypatch.setattr(structure_module, "detect", counting)
    return calls


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_both_backends_read_one_structure_detected_once(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _counted(monkeypatch)
    system = vcigen.derive(_ball())
    tol = vcigen.Tolerances()
    casadi = registry.factory("casadi")(system, tol=tol)
    c = registry.factory("c")(system, tol=tol)
    structure = system.structure
    assert casadi.kernels.structure is structure and c.kernels.structure is structure
    assert calls == [system]  # the CasADi kernels, the render context and the C kernels: one detection
    assert structure.explicit_grid and structure.jump_quadratic and structure.held  # the paths at stake
    assert casadi.kernels.held and c.kernels.held and casadi.kernels.explicit_path and c.kernels.explicit_path
    # and the two run the same trajectory from it
    runs = [sim.simulate([0.0, 1.0], [0.3, 0.0], h=0.01, t_end=3.0, progress=False) for sim in (casadi, c)]
    assert len(runs[0].impacts) == len(runs[1].impacts) > 0
    assert abs(runs[0].q[-1] - runs[1].q[-1]).max() < 1e-9
    other = vcigen.derive(_ball())  # another system: detected for it, not shared across systems
    assert other.structure is not structure and other.structure == structure and calls == [system, other]


@pytest.mark.parametrize(
    "model,rule", [(_ball, "trapezoid"), (star_nonlinear, "midpoint"), (star_nonlinear, "lobatto3")]
)
def test_header_prints_each_flag_and_why(model, rule: str) -> None:
    system = vcigen.derive(model(), rule)
    header = render(render_context(system), ["model.h.j2"])[f"{system.model.name}.h"]
    comment = " ".join(line.strip(" */") for line in header.split("*/")[0].splitlines())
    structure = system.structure
    for flag in FLAGS:
        assert f"{flag} = {int(getattr(structure, flag))}: {structure.why[flag]}" in comment


def test_internal_points_take_the_general_path_and_say_so() -> None:
    """lobatto3 (an internal point): every phase is Newton on (x, u); none of the specialisations applies."""
    system = vcigen.derive(star_nonlinear(), "lobatto3")
    s = system.structure
    assert s.stages == system.n
    assert s.implicit_grid and s.carry
    assert not (s.smooth_linear or s.smooth_diagonal or s.explicit_grid or s.explicit_path)
    assert not (s.jump_quadratic or s.held)
    assert all(
        s.why[f].startswith("internal points") for f in ("smooth_linear", "explicit_grid", "explicit_path")
    )
    trapezoid = vcigen.derive(star_nonlinear(), "trapezoid").structure  # the same scene, no internal points
    assert trapezoid.stages == 0 and trapezoid.explicit_grid and not trapezoid.jump_quadratic
    assert trapezoid.why["jump_quadratic"].startswith("E_d is not quadratic")
