"""The held step on a circle as a rotation (vcigen.held_circle): which rows take it, the step against its
closed form on a circle without forces, against the closed step (held_step.closed_step) from states on the
row, the C loop against CasADi's Python stepper, and the hand-over the loop carries."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
import sympy as sp
from test_held_closed import CLOSED, NOT_CLOSED, XD, YD, X, Y, _kernels, _states

import vcigen
from vcigen import held_circle, held_step
from vcigen.derive import derive

R = sp.Symbol("R", positive=True)
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
CIRCLES = ("bowl", "dome", "offset", "rod", "spring")


def _free_circle(kind: str) -> vcigen.Model:
    """A particle on a circle of radius R about (0.3, -0.2) with no force: inside a bowl (a contact, pressed
    into it by its motion) or on a rod (a constraint)."""
    f = (X - 0.3) ** 2 + (Y + 0.2) ** 2
    rows = {"contacts": {"row": R - sp.sqrt(f)}} if kind == "bowl" else {"constraints": {"row": f - R**2}}
    lag = 2 * (XD**2 + YD**2) / 2  # m = 2
    return vcigen.Model(
        name=f"hcr_free_{kind}", q=[X, Y], qdot=[XD, YD], lagrangian=lag, params={R: 1.5}, **rows
    )


def _spring_circle() -> vcigen.Model:
    """A circle's row under a force affine in q (a spring to the centre, and gravity): a rotation whose next
    omega is a polynomial in s (held_circle.circle_pieces)."""
    return vcigen.Model(
        name="hcr_spring",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - 3 * (X**2 + Y**2) / 2 - 9.81 * Y,
        contacts={"row": R - sp.sqrt(X**2 + Y**2)},
        params={R: 1.0},
    )


def _model(name: str):
    return _spring_circle if name == "spring" else CLOSED[name][0]


def _state(name: str) -> str:
    """The states of ``test_held_closed._states`` a row is tested from (the rod's, the spring's: the unit
    circle's lower half)."""
    return {"rod": "bowl", "spring": "bowl"}.get(name, name)


@pytest.mark.parametrize("name", sorted({*CLOSED, *CIRCLES}))
def test_circle_rows_are_detected(name: str) -> None:
    """A circle's row in the plane with an isotropic mass under a force affine in ``q`` is a rotation (with
    its centre, radius, mass and ``grad psi = gamma n``); the sphere (n = 3) is not; the header says which."""
    system = derive(_model(name)())
    circle = name in CIRCLES
    assert system.structure.held_circle == (circle,)
    assert any(line.startswith("held_circle = [1]") for line in system.structure.lines()) == circle
    if not circle:
        return
    (c,) = system.structure.held_circle_forms
    at = dict(zip(system.params, system.model.resolve_params(None)))
    centre, radius, mass, gamma = {
        "bowl": ((0, 0), 1.0, 1.0, -1.0),
        "dome": ((0, 0), 1.0, 2.0, 1.0),
        "offset": ((0.3, -0.2), 1.5, 1.0, -1.0),
        "rod": ((0, 0), 1.0, 1.0, 2.0),  # grad (x^2 + y^2 - 1) = 2 q = 2 R n
        "spring": ((0, 0), 1.0, 1.0, -1.0),
    }[name]
    got = [float(sp.sympify(e).subs(at)) for e in (*c.centre, c.radius, c.mass, c.gamma)]
    np.testing.assert_allclose(got, [*centre, radius, mass, gamma], rtol=1e-15, atol=1e-15)


def _cubic_spring_circle() -> vcigen.Model:
    """A circle's row under a force not affine in q (a cubic spring): closed, not a rotation."""
    return vcigen.Model(
        name="hcr_cubic",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - (X**4 + Y**4) / 4 - 9.81 * Y,
        contacts={"row": R - sp.sqrt(X**2 + Y**2)},
        params={R: 1.0},
    )


@pytest.mark.parametrize(
    "model", [_cubic_spring_circle, *NOT_CLOSED.values()], ids=["cubic", *sorted(NOT_CLOSED)]
)
def test_other_rows_are_not_rotations(model) -> None:
    """A circle under a force not affine in ``q`` keeps the closed step; rows that are not closed have no
    rotation."""
    system = derive(model())
    assert system.structure.held_circle in ((), (False,))
    assert not any(line.startswith("held_circle") for line in system.structure.lines())


@pytest.mark.parametrize("backend", ["casadi", pytest.param("c", marks=needs_cc)])
@pytest.mark.parametrize("kind", ["bowl", "rod"])
def test_free_particle_on_a_circle_is_a_uniform_rotation(backend: str, kind: str) -> None:
    """With no force RATTLE on a circle is a rotation by ``asin(h omega / R)`` a step, the tangential speed
    ``omega`` kept (by hand: ``q1 = sqrt(R^2 - h^2 omega^2) n0 + h omega t0``, then ``v . t1 = omega``), and
    the impulse of each step ``2 m omega tan(theta / 2) / |gamma|`` along ``-(n0 + n1)``: 10^4 steps against
    that closed form."""
    sim = vcigen.build(_free_circle(kind), backend=backend)
    c, big_r, m, om, h, steps = np.array([0.3, -0.2]), 1.5, 2.0, 1.7, 1e-3, 10_000
    q0 = c + big_r * np.array([math.cos(0.4), math.sin(0.4)])
    v0 = om * np.array([-math.sin(0.4), math.cos(0.4)])
    res = sim.simulate(q0, v0, h, t_end=steps * h)
    assert res.active.all() and res.t.size == steps + 1
    theta = math.asin(h * om / big_r)
    ang = 0.4 + theta * np.arange(steps + 1)
    exact = c + big_r * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    np.testing.assert_allclose(res.q, exact, rtol=0, atol=2e-16 * steps)
    np.testing.assert_allclose(
        res.p, m * om * np.stack([-np.sin(ang), np.cos(ang)], axis=1), atol=4e-16 * steps
    )
    gamma = 2 * big_r if kind == "rod" else 1.0
    force = 2 * m * om * math.tan(theta / 2) / (gamma * h)
    got = res.contact_force[:, 0] if kind == "bowl" else -res.constraint_force[:, 0]
    np.testing.assert_allclose(got, force, rtol=1e-9)


@pytest.mark.parametrize("name", CIRCLES)
@pytest.mark.parametrize("h", [1e-5, 1e-3, 1e-2])
def test_rotation_is_the_closed_step(name: str, h: float) -> None:
    """From states on the row, the rotation and the closed step take the same steps (both or neither: a
    lift-off, a failed test), with the same end, impulse and E_d to round-off, and its Lam to the rounding of
    ``q1`` in ``v`` (``eps / h``, as the closed step's own)."""
    s, k = _kernels(_model(name))
    act = np.ones(1, dtype=bool)
    taken = refused = 0
    for q, p, _, _ in _states(_state(name), np.random.default_rng(5), 40):
        if name == "rod":
            p = p / 1.0
        got = held_circle.circle_step(k, q, p, None, 0, act, h, s.tol.residual, s.tol.phi)
        ref = held_step.closed_step(k, q, p, 0, act, h, s.tol.residual, s.tol.phi)
        assert (got is None) == (ref is None), (q, p)
        if got is None:
            refused += 1
            continue
        taken += 1
        rot, _ = got
        scale = 1.0 + np.abs(p).max()
        np.testing.assert_allclose(rot.q1, ref.q1, rtol=0, atol=1e-15 * 4)
        np.testing.assert_allclose(rot.p1, ref.p1, rtol=0, atol=1e-15 * 8 * scale)
        # v = (q1 - q) / h carries the rounding of q1 over h (the closed step's v its own, as the Newton's)
        assert rot.energy == pytest.approx(ref.energy, abs=8e-15 * scale**2 + 2e-15 * scale / h)
        np.testing.assert_allclose(rot.lam + rot.lam1, ref.lam + ref.lam1, rtol=0, atol=1e-14 * scale)
        np.testing.assert_allclose(rot.lam, ref.lam, rtol=0, atol=1e-13 / h)
    assert taken >= 10
    if name == "dome":
        assert refused >= 5


@pytest.mark.parametrize("name", CIRCLES)
def test_rotation_force_is_the_closed_force(name: str) -> None:
    """``held_circle_end``'s normal force, written with ``|q1 - c| = R`` (``|p1|^2 = pt^2 R^2``), is the
    closed step's (``held_root_end``'s, from the row's gradient and Hessian at ``q1``) at the rotation's end,
    and so is its residual."""
    s, k = _kernels(_model(name))
    for h in (1e-5, 1e-3, 1e-2):
        kc = k.held_consts(h)
        for q, p, _, _ in _states(_state(name), np.random.default_rng(11), 20):
            w = k.held_circle_start(q, p, kc)[0]
            if not w[1] >= 0.0:
                continue
            sq = math.sqrt(w[1])
            q1, p1, pt, _, _ = (x[0] for x in k.held_circle_step(q, p, w, [sq], kc))
            _, _, force, res = (x[0] for x in k.held_circle_end(q, p, q1, p1, [pt, sq], kc))
            _, _, _, _, y, wn, _, _, iw = k.held_root_dir(q1, kc)
            _, _, ref_force, ref_res = k.held_root_end(q1, p1, y, wn, iw, kc)
            scale = 1.0 + np.abs(p).max()
            assert abs(force) > 0.1  # not a force that vanishes
            assert force == pytest.approx(ref_force[0], rel=0, abs=1e-13 * scale**2)
            assert res == pytest.approx(ref_res[0], rel=0, abs=1e-15 * scale)


@needs_cc
@pytest.mark.parametrize(
    ("name", "q0", "v0", "t_end"),
    [
        ("bowl", [0.6, -0.8], [0.0, 0.0], 3.0),
        ("dome", [0.0, 1.0], [0.1, 0.0], 3.0),  # slides, then lifts off
        ("offset", [1.2, -1.4], [0.5, 0.375], 3.0),
        ("rod", [0.0, -1.0], [3.0, 0.0], 3.0),
        ("spring", [0.6, -0.8], [0.0, 0.0], 3.0),
    ],
)
def test_c_rotation_loop_is_casadis(name: str, q0, v0, t_end: float) -> None:
    """The C loop (<model>_held_circle_loop, carrying (omega, arg)) against the Python stepper's rotation
    steps on CasADi's kernels: the same run to round-off, the same active sets, lift-offs and impacts."""
    model = _model(name)
    c = vcigen.build(model(), backend="c").simulate(q0, v0, 1e-3, t_end=t_end)
    py = vcigen.build(model(), backend="casadi").simulate(q0, v0, 1e-3, t_end=t_end)
    assert c.t.size == py.t.size
    np.testing.assert_array_equal(c.active, py.active)
    assert [lo[1] for lo in c.liftoffs] == [lo[1] for lo in py.liftoffs]
    np.testing.assert_allclose(
        [lo[0] for lo in c.liftoffs], [lo[0] for lo in py.liftoffs], rtol=0, atol=1e-12
    )
    assert len(c.impacts) == len(py.impacts)
    np.testing.assert_allclose(c.q, py.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(c.p, py.p, rtol=0, atol=1e-11)
    if name == "dome":
        assert c.liftoffs  # the run leaves the dome: the loop's exit and the general chain's start


def test_the_carry_is_handed_on_within_a_run_only(monkeypatch) -> None:
    """The Python stepper forms (omega, arg) from the state once per run of rotation steps (as the C loop
    does at its entry) and carries them on: one start for a run held throughout. A carry is handed on only to
    the state, step and parameters it belongs to."""
    sim = vcigen.build(CLOSED["bowl"][0](), backend="casadi")
    k = sim.kernels
    starts = []
    real = k.held_circle_start

    def spy(q, p, kc):
        starts.append(q.copy())
        return real(q, p, kc)

    monkeypatch.setattr(k, "held_circle_start", spy)
    a = sim.simulate([0.6, -0.8], [0.0, 0.0], 1e-3, t_end=0.5)
    assert a.active.all() and len(starts) == 1
    b = sim.simulate([0.6, -0.8], [0.0, 0.0], 1e-3, t_end=0.5)
    assert len(starts) == 2 and np.array_equal(a.q, b.q)  # a new run forms its own
    q, p, par, w = np.array([0.6, -0.8]), np.zeros(2), np.array([1.0]), np.array([0.5, 0.25])
    carry = held_circle.Carry(q, p, 1e-3, par, w)
    assert carry.at(q.copy(), p.copy(), 1e-3, par.copy()) is w
    assert carry.at(q, p, 2e-3, par) is None
    assert carry.at(q, p, 1e-3, par + 1e-12) is None
    assert carry.at(q + 1e-16, p, 1e-3, par) is None
    assert carry.at(q, p + 1e-300, 1e-3, par) is None


@pytest.mark.parametrize("backend", ["casadi", pytest.param("c", marks=needs_cc)])
def test_a_carried_step_is_the_fresh_step(backend: str) -> None:
    """A step from the carried (omega, arg) and one that forms them from the state: the same step to round-off
    (the carried argument takes the modulus's drift off to first order, as 1 / |n|^2 does)."""
    sim = vcigen.build(CLOSED["offset"][0](), backend=backend)
    k = sim.kernels.bind(sim.model.resolve_params(None))
    act, tol = np.ones(1, dtype=bool), sim.tol
    q, p, w = np.array([1.2, -1.4]), np.array([0.5, 0.375]), None
    for _ in range(200):
        held, w1 = k.circle_step(q, p, w, 0, act, 1e-2, tol.residual, tol.phi)
        fresh, _ = k.circle_step(held.q1, held.p1, None, 0, act, 1e-2, tol.residual, tol.phi)
        carried, w = k.circle_step(held.q1, held.p1, w1, 0, act, 1e-2, tol.residual, tol.phi)
        np.testing.assert_allclose(carried.q1, fresh.q1, rtol=0, atol=1e-14 * (1 + np.abs(q).max()))
        np.testing.assert_allclose(carried.p1, fresh.p1, rtol=0, atol=1e-14 * (1 + np.abs(p).max()))
        q, p = held.q1, held.p1


@pytest.mark.parametrize("backend", ["casadi", pytest.param("c", marks=needs_cc)])
@pytest.mark.parametrize(
    ("name", "centre", "radius"), [("offset", (0.3, -0.2), 1.5), ("spring", (0.0, 0.0), 1.0)]
)
def test_a_run_with_its_tangent_takes_the_same_rotation_steps(
    backend: str, name: str, centre: tuple, radius: float
) -> None:
    """The tangent reads each rotation step's Lam, Lam' and u1: a run with it takes the same steps bit for
    bit, and its tangent through 400 held steps on the off-centre circle (and on the circle under a spring)
    is the central differences', along directions that keep the start held: q0 along the row, v0 along it,
    R with q0 moved out with it."""
    sim = vcigen.build(_model(name)(), backend=backend)
    c, n0, t0 = np.array(centre, float), np.array([0.6, -0.8]), np.array([0.8, 0.6])
    x0 = np.array([*(c + radius * n0), *(0.625 * t0), radius])  # offset: q0 = (1.2, -1.4), v0 = (0.5, 0.375)
    h, t_end = 1e-3, 0.4

    def run(x, sens=False):
        return sim.simulate(
            x[:2], x[2:4], h, t_end=t_end, params={"R": x[4]}, progress=False, sensitivities=sens
        )

    plain, tan = run(x0), run(x0, True)
    assert plain.active.all() and np.array_equal(plain.q, tan.q) and np.array_equal(plain.p, tan.p)
    assert tan.sensitivity_names[4] == "R" and not tan.sensitivity_breaks
    for d in ([*t0, 0, 0, 0], [0, 0, *t0, 0], [*n0, 0, 0, 1]):
        d = np.array(d, float)
        eps = 1e-6
        hi, lo = run(x0 + eps * d), run(x0 - eps * d)
        fd = (np.r_[hi.q[-1], hi.p[-1]] - np.r_[lo.q[-1], lo.p[-1]]) / (2 * eps)
        np.testing.assert_allclose(tan.sensitivity[-1] @ d, fd, rtol=0, atol=1e-7 * (1 + np.abs(fd).max()))
