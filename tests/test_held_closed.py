"""The closed-form held step on one curved row (vcigen.held.closed_forms, closed_step).

A row ``psi`` whose zero set is that of a quadratic ``F`` (a circle's, a sphere's, a rod's), held alone:
RATTLE's position step ``q1 = a + Lam b`` with ``psi(q1) = 0`` is the quadratic ``F(a + Lam b) = 0`` in
``Lam``, solved by one square root; the tangent projection divides by ``W = grad F . M^-1 grad F``, a
constant on the surface when the mass is isotropic (else a quadric's step: tests/test_held_quadric.py).
Checked here: which rows are detected, the surface
values, and each step against the held Newton (held_step.held_step with the closed form off) and against the
geometry (q1 on the row, q1 - a along grad psi(q0)). Whole trajectories across the backends:
tests/test_c_agreement_sustained.py.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import sympy as sp

import vcigen
from vcigen import held, held_step
from vcigen.derive import derive

X, Y, Z, XD, YD, ZD = sp.symbols("x y z xd yd zd")
R, M = sp.symbols("R m", positive=True)
G = 9.81


def _planar(name, psi, masses=(1, 1), params=None, constraint=False) -> vcigen.Model:
    kinetic = (masses[0] * XD**2 + masses[1] * YD**2) / 2
    rows = {"constraints": {"row": psi}} if constraint else {"contacts": {"row": psi}}
    return vcigen.Model(
        name=name,
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=kinetic - masses[1] * G * Y,
        params=params or {},
        **rows,
    )


def _bowl() -> vcigen.Model:
    return _planar("hc_bowl", R - sp.sqrt(X**2 + Y**2), params={R: 1.0})


def _dome() -> vcigen.Model:
    return _planar("hc_dome", sp.sqrt(X**2 + Y**2) - R, masses=(M, M), params={R: 1.0, M: 2.0})


def _offset() -> vcigen.Model:
    return _planar("hc_offset", R - sp.sqrt((X - 0.3) ** 2 + (Y + 0.2) ** 2), params={R: 1.5})


def _rod() -> vcigen.Model:
    return _planar("hc_rod", X**2 + Y**2 - 1, constraint=True)


def _sphere() -> vcigen.Model:
    return vcigen.Model(
        name="hc_sphere",
        q=[X, Y, Z],
        qdot=[XD, YD, ZD],
        lagrangian=(XD**2 + YD**2 + ZD**2) / 2 - G * Z,
        contacts={"row": R - sp.sqrt(X**2 + Y**2 + Z**2)},
        params={R: 1.0},
    )


CLOSED = {  # name: (model, gain, w0) at the default parameters; gain = dF/dpsi on the row
    "bowl": (_bowl, -2.0, 4.0),
    "dome": (_dome, 2.0, 2.0),  # W = |2 q|^2 / m = 4 R^2 / m
    "offset": (_offset, -3.0, 9.0),
    "rod": (_rod, 1.0, 4.0),
    "sphere": (_sphere, -2.0, 4.0),
}
NOT_CLOSED = {  # name: model of a row with no line form; an ellipse's row: tests/test_held_quadric.py
    "floor": lambda: _planar("hc_floor", Y),
    "hump": lambda: _planar("hc_hump", Y - sp.exp(-(X**2))),
}


@pytest.mark.parametrize("name", sorted(CLOSED))
def test_closed_rows_are_detected_with_their_constants(name: str) -> None:
    """A sphere's or a rod's row with an isotropic mass is closed: its ``gain`` and ``w0`` are those of the
    geometry, and the structure (both backends read it) and the generated header say so."""
    model, gain, w0 = CLOSED[name]
    system = derive(model())
    assert system.structure.held_closed == (True,)
    (cf,) = held.closed_forms(system)
    at = dict(zip(system.params, system.model.resolve_params(None)))
    assert float(cf.gain.subs(at)) == pytest.approx(gain, rel=1e-15)
    assert float(cf.w0.subs(at)) == pytest.approx(w0, rel=1e-15)
    assert any(line.startswith("held_closed = [1]") for line in system.structure.lines())


@pytest.mark.parametrize("name", sorted(NOT_CLOSED))
def test_other_rows_are_not_closed(name: str) -> None:
    """Rows without a line form (a floor's, a hump's) have no closed step: the held Newton keeps them (no
    ``held_closed`` line in the header)."""
    system = derive(NOT_CLOSED[name]())
    assert held.closed_forms(system) == [None]
    assert system.structure.held_closed == (False,)
    assert not any(line.startswith("held_closed") for line in system.structure.lines())


def test_on_surface_is_the_value_on_the_surface() -> None:
    """``on_surface(e, F)`` is ``e``'s value on ``F = 0`` where ``e`` is constant there, else ``None``."""
    q = (X, Y, Z)
    f = (X - 1) ** 2 + Y**2 + Z**2 - R**2
    e = 3 * (X - 1) ** 2 + 3 * Y**2 + 3 * Z**2 + 7
    assert sp.simplify(held.on_surface(e, f, q) - (3 * R**2 + 7)) == 0
    assert held.on_surface(X**2 + 4 * Y**2, X**2 + Y**2 - 1, q[:2]) is None
    assert held.on_surface(X, X**2 + Y**2 - 1, q[:2]) is None


def _kernels(model):
    s = vcigen.build(model(), backend="casadi")
    return s, s.kernels.bind(s.model.resolve_params(None))


def closed_and_newton(s, k, q, p, h: float):
    """The held step of ``k`` (CasADi kernels of ``s``, one row held) from ``(q, p)`` over ``h`` with its
    closed form and with the held Newton (the closed form off): both ``Held``, or both ``None``."""
    act, lam0 = np.ones(1, dtype=bool), np.zeros(1)
    fast = k.held_step(q, p, lam0, act, h, s.tol.residual, s.tol.phi)
    k.held_closed = [False]
    try:
        slow = k.held_step(q, p, lam0, act, h, s.tol.residual, s.tol.phi)
    finally:
        k.held_closed = [True]
    assert (fast is None) == (slow is None), (q, p)
    return fast, slow


def _states(name: str, rng, count: int):
    """Points on the row with tangent momenta (some fast enough to leave a dome), and the row's centre and
    radius at the default parameters."""
    centre = {"offset": np.array([0.3, -0.2])}.get(name)
    radius = {"offset": 1.5}.get(name, 1.0)
    mass = 2.0 if name == "dome" else 1.0
    n = 3 if name == "sphere" else 2
    centre = np.zeros(n) if centre is None else centre
    for _ in range(count):
        d = rng.normal(size=n)
        d /= np.linalg.norm(d)
        if name in ("bowl", "offset", "sphere"):
            d[-1] = -abs(d[-1])  # the lower half: pressed into it
        if name == "dome":
            d[-1] = abs(d[-1]) + 0.5
            d /= np.linalg.norm(d)
        t = rng.normal(size=n)
        t -= (t @ d) * d
        speed = rng.uniform(0.0, 4.0)
        yield centre + radius * d, mass * speed * t / np.linalg.norm(t), centre, radius


@pytest.mark.parametrize("name", sorted(CLOSED))
@pytest.mark.parametrize("h", [1e-5, 1e-3, 1e-2])
def test_closed_step_is_the_held_newton_step(name: str, h: float) -> None:
    """From states on the row, the closed step and the held Newton (the same kernels, the closed form off)
    take the same steps: both or neither (a lift-off, a failed test); the same end, multipliers and E_d to
    the Newton's tolerance. The closed end is on the row to round-off, ``q1 - a`` along ``grad psi(q0)``."""
    s, k = _kernels(CLOSED[name][0])
    taken = refused = 0
    for q, p, centre, radius in _states(name, np.random.default_rng(3), 40):
        fast, slow = closed_and_newton(s, k, q, p, h)
        if fast is None:
            refused += 1
            continue
        taken += 1
        # the Newton ends where |psi(q1)| <= held_step.ABSTOL (1e-13): q1 within that; p1's error is its
        # tangential part, O(h) of it
        scale = 1.0 + np.abs(p).max()
        np.testing.assert_allclose(fast.q1, slow.q1, rtol=0, atol=2 * held_step.ABSTOL)
        np.testing.assert_allclose(fast.p1, slow.p1, rtol=0, atol=2 * held_step.ABSTOL * scale)
        assert fast.energy == pytest.approx(slow.energy, abs=1e-12 * scale**2)
        # psi(q1) = 0 fixes Lam only to the rounding of q1 (eps |q1|): in v that is eps |q1| / h, which Lam
        # and Lam' each carry and their sum (the impulse the step books, the contact force) does not
        np.testing.assert_allclose(fast.lam, slow.lam, rtol=0, atol=1e-13 / h)
        np.testing.assert_allclose(fast.lam1, slow.lam1, rtol=0, atol=1e-13 / h)
        np.testing.assert_allclose(fast.lam + fast.lam1, slow.lam + slow.lam1, rtol=0, atol=1e-13 * scale)
        assert abs(np.linalg.norm(fast.q1 - centre) - radius) <= 4e-16 * (1 + radius) * 4
        kc = k.held_consts(h)
        v0, _ = k.held_free(q, p, kc)
        step, normal = fast.q1 - (q + h * v0), q - centre
        cross = step - (step @ normal) / (normal @ normal) * normal
        assert np.linalg.norm(cross) <= 1e-15 * (1 + np.linalg.norm(step) / h)
    assert taken >= 10
    if name == "dome":
        assert refused >= 5  # fast states leave the dome: the lift-off test refuses them on both paths


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
@pytest.mark.parametrize(
    ("name", "q0", "v0"),
    [("sphere", [0.6, 0.0, -0.8], [0.0, 1.0, 0.0]), ("offset", [1.2, -1.4], [0.5, 0.375])],
)
def test_c_closed_step_is_the_held_newton_in_3d_and_off_centre(name: str, q0, v0) -> None:
    """The C loop's closed step on a sphere (n = 3) and an off-centre circle, 2000 held steps, against
    CasADi's held Newton (the closed form off): the same run to the Newton's tolerance."""
    from test_c_agreement_sustained import _same_to_newton_tolerance

    from vcigen.stepper import Stepper

    c = vcigen.build(CLOSED[name][0](), backend="c").simulate(q0, v0, 1e-3, t_end=2.0)
    s, k = _kernels(CLOSED[name][0])
    k.held_closed = [False]
    newton = Stepper(k, s.tol).simulate(q0, v0, 1e-3, t_end=2.0)
    assert c.active.all() and not c.liftoffs  # held throughout: every step is a closed one
    _same_to_newton_tolerance(c, newton)
