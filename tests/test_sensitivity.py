"""``simulate(..., sensitivities=True)`` (MATH.md, *Exact sensitivities*; ``vcigen.sensitivity``).

The exact tangent ``d(q_k, p_k)/d(q0, v0, params)`` against central finite differences of whole ``simulate``
runs (the perturbed runs must have the same mode sequence: the same impacts in the same steps), the
symplecticity of impact steps from the tangent itself, the steps no tangent goes through, and runs with
sensitivities off unchanged bit for bit.
"""

from __future__ import annotations

import math
from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from forced_scenes import driven_oscillator
from scenes import load_example

import vcigen
from vcigen.analysis import jacobian_symplectic_defect


def chain(count: int = 4) -> vcigen.Model:
    """``count`` unit particles joined by springs ``k``, each above its own floor (n = 8: more coordinates
    than ``vcigen.sensitivity.SYMBOLIC_SOLVE``, the smooth step's tangent solves at run time)."""
    xs, ys = sp.symbols(f"x0:{count}"), sp.symbols(f"y0:{count}")
    us, ws = sp.symbols(f"u0:{count}"), sp.symbols(f"w0:{count}")
    k = sp.Symbol("k")
    springs = sum((xs[i + 1] - xs[i]) ** 2 + (ys[i + 1] - ys[i]) ** 2 for i in range(count - 1))
    return vcigen.Model(
        name="chain",
        q=[s for pair in zip(xs, ys) for s in pair],
        qdot=[s for pair in zip(us, ws) for s in pair],
        lagrangian=sum((u**2 + w**2) / 2 for u, w in zip(us, ws)) - k / 2 * springs,
        contacts={f"floor{i}": ys[i] for i in range(count)},
        params={k: 3.0},
    )


BACKENDS = ["casadi", hard_scenes.backend_param("c")]

# scene -> (model maker, q0, v0, h, t_end, params): each a run through impacts away from mode changes
SCENES = {
    # the particle in a box under gravity: several impacts on all four walls
    "box": (hard_scenes.box, [0.3, 0.6], [2.3, -1.1], 0.01, 1.6, {"g": 9.81}),
    # the paper's star (Abs in phi, eq. 81), two impacts
    "star": (lambda: load_example("star").model(), [0.0, 1.2, 0.0], [-2.0, 0.0, 5.0], 0.005, 1.2, None),
    # configuration-dependent mass matrix, nonlinear contact
    "double_pendulum": (hard_scenes.double_pendulum, [0.3, 0.6], [1.5, 2.0], 0.01, 0.6, None),
    # restitution e < 1 on every wall: the loss of (39) and its parameter e
    "box_lossy": (
        lambda: hard_scenes.box(lossy=True),
        [0.5, 0.5],
        [1.3, -0.7],
        0.01,
        1.1,
        {"e": 0.6, "g": 9.81},
    ),
    # several impacts in one step (78): two walls 0.01 apart, h = 0.02
    "walls": (hard_scenes.walls, [0.004, 0.0], [0.9, 0.3], 0.02, 0.2, None),
    # a corner hit in one step: the left wall, then the floor, inside one step
    "corner": (hard_scenes.corner, [0.03, 0.05], [-1.0, -1.2], 0.1, 0.3, {"g": 9.81}),
    # restitution on several impacts in one step: the loss of (39) after a jump ending on a contact (78)
    "corner_lossy": (
        lambda: hard_scenes.box(lossy=True),
        [0.05, 0.08],
        [-1.0, -1.3],
        0.1,
        0.5,
        {"e": 0.7, "g": 0.0},
    ),
    # many coordinates: four floors struck in turn
    "chain": (
        chain,
        [0.0, 0.2, 0.3, 0.3, 0.6, 0.4, 0.9, 0.5],
        [0.1, -1.0, 0.1, -1.3, 0.1, -1.6, 0.1, -1.9],
        0.01,
        0.5,
        None,
    ),
    # forces of velocity and of time (Lagrange-d'Alembert), restitution: the time slot
    "driven": (driven_oscillator, [0.0], [3.0], 0.01, 4.0, None),
}


@cache
def simulator(scene: str, backend: str, rule: str = "trapezoid") -> vcigen.Simulator:
    return vcigen.build(SCENES[scene][0](), backend=backend, rule=rule)


def mode(res: vcigen.Result) -> list[tuple[int, str, str]]:
    """The mode sequence of a run: each impact's grid step, contact and kind."""
    return [(im.step, im.contact, im.kind) for im in res.impacts]


def finite_differences(sim: vcigen.Simulator, scene: str, eps: float = 1e-6, setup: tuple | None = None):
    """``(run, exact, fd, per-step impacts)``: the tangent and central differences of ``simulate``
    (``setup``: the scene's ``SCENES`` entry, or another one of its form)."""
    _, q0, v0, h, t_end, params = setup or SCENES[scene]
    res = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    n = len(q0)
    z0 = np.concatenate([q0, v0]).astype(float)
    names = [str(s) for s in sim.model.defaults]
    values = dict(zip(names, sim.model.resolve_params(params)))
    fd = np.empty_like(res.sensitivity)
    for c in range(res.sensitivity.shape[2]):
        ends = []
        for sign in (1.0, -1.0):
            z, par = z0.copy(), dict(values)
            if c < 2 * n:
                z[c] += sign * eps
            else:
                par[names[c - 2 * n]] += sign * eps * max(1.0, abs(values[names[c - 2 * n]]))
            r = sim.simulate(z[:n], z[n:], h, t_end=t_end, params=par, progress=False)
            assert mode(r) == mode(res), f"column {res.sensitivity_names[c]}: the mode sequence changed"
            ends.append(np.hstack([r.q, r.p]))
        scale = eps * (1.0 if c < 2 * n else max(1.0, abs(values[names[c - 2 * n]])))
        fd[:, :, c] = (ends[0] - ends[1]) / (2 * scale)
    return res, fd


def relative_error(exact: np.ndarray, fd: np.ndarray) -> float:
    """``max |exact - fd| / max |exact|`` over every grid point, row and column."""
    return float(np.abs(exact - fd).max() / np.abs(exact).max())


def scene_backends():
    """Every scene on every backend (the chain, whose C build takes a minute, on CasADi only)."""
    for scene in sorted(SCENES):
        for b in BACKENDS:
            backend, marks = (b, ()) if isinstance(b, str) else (b.values[0], b.marks)
            if scene != "chain" or backend == "casadi":
                yield pytest.param(scene, backend, marks=marks, id=f"{scene}-{backend}")


@pytest.mark.parametrize("scene, backend", list(scene_backends()))
def test_sensitivity_matches_finite_differences(scene: str, backend: str) -> None:
    sim = simulator(scene, backend)
    res, fd = finite_differences(sim, scene)
    n = sim.model.n
    assert res.sensitivity.shape == (res.t.size, 2 * n, 2 * n + len(sim.model.defaults))
    assert res.sensitivity_breaks == [] and "sensitivity_lost" not in res.stats
    rel = relative_error(res.sensitivity, fd)
    print(f"{scene} [{backend}]: {res.n_impacts} impacts, relative FD agreement {rel:.1e}")
    assert res.n_impacts >= 1 and rel <= 1e-6, (res.n_impacts, rel)


@pytest.mark.parametrize("scene", ["star", "corner_lossy", "driven"])
def test_midpoint_rule(scene: str) -> None:
    """The tangent holds under the midpoint rule (57) as well (casadi)."""
    res, fd = finite_differences(simulator(scene, "casadi", "midpoint"), scene)
    rel = relative_error(res.sensitivity, fd)
    print(f"{scene} [midpoint]: {res.n_impacts} impacts, relative FD agreement {rel:.1e}")
    assert res.n_impacts >= 1 and not res.sensitivity_breaks and rel <= 1e-6, rel


def step_jacobians(res: vcigen.Result, steps) -> list[np.ndarray]:
    """``d(q_k+1, p_k+1)/d(q_k, p_k) = S_k+1 S_k^-1`` (the ``(q0, v0)`` columns) of grid steps ``steps``."""
    d = res.q.shape[1] * 2
    return [res.sensitivity[k + 1][:, :d] @ np.linalg.inv(res.sensitivity[k][:, :d]) for k in steps]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", ["box", "star", "double_pendulum", "walls", "corner"])
def test_impact_steps_are_symplectic(scene: str, backend: str) -> None:
    """Elastic impact steps (and smooth ones) from the exact tangent: ``|J^T Omega J - Omega| <= 1e-12``."""
    sim = simulator(scene, backend)
    _, q0, v0, h, t_end, params = SCENES[scene]
    res = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    impact_steps = sorted({im.step for im in res.impacts})
    defects = [jacobian_symplectic_defect(j) for j in step_jacobians(res, impact_steps)]
    free = [k for k in range(res.t.size - 1) if k not in impact_steps]
    smooth = max((jacobian_symplectic_defect(j) for j in step_jacobians(res, free)), default=0.0)
    print(f"{scene} [{backend}]: {len(defects)} impact steps, defect {max(defects):.1e}, smooth {smooth:.1e}")
    assert max(defects) <= 1e-12 and smooth <= 1e-12, (defects, smooth)


def test_restitution_is_not_symplectic() -> None:
    """The measure sees dissipation: the impact steps of the lossy box (e = 0.6) have a large defect."""
    sim = simulator("box_lossy", "casadi")
    _, q0, v0, h, t_end, params = SCENES["box_lossy"]
    res = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    steps = sorted({im.step for im in res.impacts})
    assert min(jacobian_symplectic_defect(j) for j in step_jacobians(res, steps)) > 0.1


def assert_lost(res: vcigen.Result, reason: str) -> int:
    """The tangent is finite up to the first break, NaN after it, and the break is reported."""
    lost = res.stats["sensitivity_lost"]
    assert res.sensitivity_breaks and res.sensitivity_breaks[0][0] == lost
    assert reason in res.sensitivity_breaks[0][1], res.sensitivity_breaks
    assert np.isfinite(res.sensitivity[: lost + 1]).all()
    assert np.isnan(res.sensitivity[lost + 1 :]).all() and res.sensitivity.shape[0] > lost + 1
    return lost


@pytest.mark.parametrize("backend", BACKENDS)
def test_simultaneous_impact_is_reported_not_differentiated(backend: str) -> None:
    """A corner hit exactly (both walls at once: the normal-cone weights switch) is no smooth map."""
    sim = simulator("corner", backend)
    res = sim.simulate([0.05, 0.05], [-1.0, -1.0], 0.1, t_end=0.3, sensitivities=True, progress=False)
    assert assert_lost(res, "simultaneous") == res.impacts[0].step


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_ball_coming_to_rest_matches_finite_differences(backend: str) -> None:
    """A lossy ball bouncing to rest (Zeno): restitution impacts, then the plastic impact that starts
    sustained contact (the contact time (47), the impulse law onto the row, the constrained rest of its
    step), then held steps sliding on: covered throughout, against central differences of every column
    (the perturbed runs have the same impacts, kinds and active sets)."""
    sim = vcigen.build(hard_scenes.ball(), backend=backend)
    q0, v0, h, t_end = [0.0, 1.0], [0.3, 0.0], 0.01, 2.0
    res = sim.simulate(q0, v0, h, t_end=t_end, sensitivities=True, progress=False)
    kinds = [im.kind for im in res.impacts]
    assert kinds[-1] == "plastic" and kinds.count("restitution") >= 4 and res.active[-1].all()
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    fd = np.empty_like(res.sensitivity)
    z0 = np.array(q0 + v0 + [0.5])
    for c in range(5):
        ends = []
        for sign in (1.0, -1.0):
            z = z0.copy()
            z[c] += sign * 1e-6
            r = sim.simulate(z[:2], z[2:4], h, t_end=t_end, params={"e": z[4]}, progress=False)
            assert held_mode(r) == held_mode(res), res.sensitivity_names[c]
            ends.append(np.hstack([r.q, r.p]))
        fd[:, :, c] = (ends[0] - ends[1]) / 2e-6
    err = relative_error(res.sensitivity, fd)
    print(f"ball to rest ({backend}): {len(kinds)} impacts, FD {err:.1e}")
    assert err <= 1e-6


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", ["box_lossy", "driven", "walls"])
def test_sensitivities_leave_the_run_unchanged(scene: str, backend: str) -> None:
    """Asking for sensitivities changes nothing else, bit for bit; not asking leaves them out."""
    sim = simulator(scene, backend)
    _, q0, v0, h, t_end, params = SCENES[scene]
    off = sim.simulate(q0, v0, h, t_end=t_end, params=params, progress=False)
    on = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    assert off.sensitivity is None and off.sensitivity_names == [] and off.sensitivity_breaks == []
    for name in ("t", "q", "p", "energy", "work"):
        assert np.array_equal(getattr(off, name), getattr(on, name)), name
    assert off.impacts == on.impacts and on.n_impacts >= 1
    n = sim.model.n
    coords = sim.model.coordinate_names
    expect = (
        [f"q0[{c}]" for c in coords] + [f"v0[{c}]" for c in coords] + [str(s) for s in sim.model.defaults]
    )
    assert on.sensitivity_names == expect and on.sensitivity.shape == (on.t.size, 2 * n, len(expect))


@pytest.mark.parametrize("backend", BACKENDS)
def test_simulate_many_with_sensitivities_is_simulate_per_run(backend: str) -> None:
    """``simulate_many(..., sensitivities=True)``: each run's tangent (and the rest of its result) is the one
    ``simulate(..., sensitivities=True)`` gives, parameters per run included; bad input names its run."""
    sim = simulator("box_lossy", backend)
    _, q0, v0, h, t_end, params = SCENES["box_lossy"]
    q0s = [q0, [0.45, 0.3], [0.7, 0.55]]
    v0s = [v0, [-1.7, 2.2], [0.4, -3.0]]
    per_run = [params, {**params, "e": 0.3}, None]
    many = sim.simulate_many(q0s, v0s, h, t_end=t_end, params=per_run, progress=False, sensitivities=True)
    for q, v, par, res in zip(q0s, v0s, per_run, many):
        one = sim.simulate(q, v, h, t_end=t_end, params=par, progress=False, sensitivities=True)
        assert res.n_impacts >= 1 and res.impacts == one.impacts
        assert np.array_equal(res.q, one.q) and np.array_equal(res.sensitivity, one.sensitivity)
        assert res.sensitivity_names == one.sensitivity_names and np.isfinite(res.sensitivity).all()
    assert not np.array_equal(many[0].sensitivity[-1], many[1].sensitivity[-1])
    with pytest.raises(ValueError, match="run 1:"):
        sim.simulate_many([q0, [0.5, -0.2]], [v0, v0], h, t_end=t_end, sensitivities=True)


@pytest.mark.parametrize("scene", ["box_lossy", "star", "walls", "driven"])
def test_c_equals_casadi(scene: str) -> None:
    """The two backends' tangents agree to 1e-9 (relative)."""
    if hard_scenes.c_backend_problem():
        pytest.skip(hard_scenes.c_backend_problem())
    _, q0, v0, h, t_end, params = SCENES[scene]
    a, b = (
        simulator(scene, backend).simulate(
            q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False
        )
        for backend in ("casadi", "c")
    )
    assert relative_error(a.sensitivity, b.sensitivity) <= 1e-9


def test_long_runs_and_failed_runs_keep_their_tangent() -> None:
    """An ``n_impacts`` run grows its buffers (past 1024 steps) like a ``t_end`` run; a run that stops with
    a ``SolverError`` carries the tangent up to its last completed step."""
    sim = simulator("box", "casadi")
    kw = {"params": {"g": 9.81}, "sensitivities": True, "progress": False}
    a = sim.simulate([0.3, 0.6], [2.3, -1.1], 0.001, n_impacts=8, **kw)
    b = sim.simulate([0.3, 0.6], [2.3, -1.1], 0.001, t_end=a.t[-1] + 1e-12, **kw)
    assert a.t.size > 1025 and np.array_equal(a.sensitivity, b.sensitivity)
    assert np.isfinite(a.sensitivity).all()
    ball = vcigen.build(hard_scenes.ball(), tol=vcigen.Tolerances(grazing="error"))
    with pytest.raises(vcigen.SolverError) as info:  # the paper's jump alone: a grazing impact has no root
        ball.simulate([0.0, 1.0], [0.3, 0.0], 0.01, t_end=2.8, sensitivities=True, progress=False)
    res = info.value.result
    assert res.sensitivity.shape == (res.t.size, 4, 5) and np.isfinite(res.sensitivity).all()
    assert res.n_impacts >= 2


def test_grazing_impact_is_reported() -> None:
    """A grazing impact taking the continuous law (``Tolerances(grazing="reflect")``) is no smooth map."""
    ball = vcigen.build(hard_scenes.ball(), tol=vcigen.Tolerances(grazing="reflect"))
    with pytest.warns(RuntimeWarning, match="grazing"):
        res = ball.simulate([0.0, 1.0], [0.3, 0.0], 0.01, t_end=1.335, sensitivities=True, progress=False)
    grazing = [im.step for im in res.impacts if im.kind == "grazing"]
    assert grazing and assert_lost(res, "grazing") == grazing[0]


def test_a_non_finite_or_singular_tangent_is_reported(monkeypatch) -> None:
    """The safety nets: a NaN tangent, or a singular matrix in a hook, is a break, never a silent NaN or a
    failed run."""
    from vcigen import sensitivity

    sim = simulator("box", "casadi")
    _, q0, v0, h, t_end, params = SCENES["box"]
    kw = {"params": params, "sensitivities": True, "progress": False}

    def nan_step(self, q, p, h, v):
        self.next = np.full((2 * self.n, self.K), np.nan)

    with monkeypatch.context() as m:
        m.setattr(sensitivity.Tracker, "smooth", nan_step)
        assert assert_lost(sim.simulate(q0, v0, h, t_end=t_end, **kw), "non-finite") == 0

    def singular(*args):
        raise np.linalg.LinAlgError("Singular matrix")

    with monkeypatch.context() as m:
        m.setattr(sensitivity.Tracker, "_ift", singular)  # the implicit function of (47), (48), (78)
        res = sim.simulate(q0, v0, h, t_end=t_end, **kw)
        assert assert_lost(res, "singular") == res.impacts[0].step


# ------------------------------------------------------------------ held steps (sustained contact)


def _rotated(q, angle: float) -> list[float]:
    c, s = np.cos(angle), np.sin(angle)
    return [c * q[0] - s * q[1], s * q[0] + c * q[1]]


def _dragged() -> vcigen.Model:
    """A unit particle on the floor ``y = 0`` under gravity, viscous drag ``c`` and a push ``A cos(W t)``."""
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    c, A, W = sp.symbols("c A W")
    return vcigen.Model(
        name="dragged",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - 9.81 * y,
        contacts={"floor": y},
        params={c: 0.4, A: 2.0, W: 1.7},
        forces=[-c * xd + A * sp.cos(W * t), 0],
        time=t,
    )


def _held_scenes() -> dict:
    """scene -> (model maker, q0, v0, h, t_end, params, paths): runs held from the start (sustained contact,
    the active set never changing); each path ``eps -> (q0, v0, params)`` moves the start without changing
    the mode (along the contact, normal speeds below the jump's resolution, parameters that keep q0 on it)."""
    from test_c_agreement_sustained import _bowl, _box, _star
    from test_sustained_closed_forms import incline, pendulum

    a = 0.3
    along = np.array([np.cos(a), np.sin(a)])
    rod = [float(np.sin(1.0)), -float(np.cos(1.0))]
    return {
        # a particle sliding on a floor (one linear row; the held grid step of vcigen.held)
        "slide": (
            hard_scenes.ball,
            [0.0, 0.0],
            [1.0, 0.0],
            0.01,
            1.0,
            None,
            {
                "q0[x]": lambda e: ([e, 0.0], [1.0, 0.0], {}),
                "v0[x]": lambda e: ([0.0, 0.0], [1.0 + e, 0.0], {}),
                "v0[y]": lambda e: ([0.0, 0.0], [1.0, e], {}),
            },
        ),
        # resting on the floor
        "rest": (
            hard_scenes.ball,
            [0.0, 0.0],
            [0.0, 0.0],
            0.01,
            1.0,
            None,
            {"v0[x]": lambda e: ([0.0, 0.0], [e, 0.0], {}), "v0[y]": lambda e: ([0.0, 0.0], [0.0, e], {})},
        ),
        # sliding down a frictionless incline; its angle a a parameter (q0 = 0 stays on the line)
        "incline": (
            incline,
            [0.0, 0.0],
            list(0.5 * along),
            0.01,
            1.0,
            None,
            {
                "q0 along": lambda e: (list(e * along), list(0.5 * along), {}),
                "v0 along": lambda e: ([0.0, 0.0], list((0.5 + e) * along), {}),
                "a": lambda e: ([0.0, 0.0], list(0.5 * along), {"a": a + e}),
            },
        ),
        # the box on its long face: two vertices held, two nonlinear rows
        "box_face": (
            _box,
            [0.0, 0.5, 0.0],
            [1.0, 0.0, 0.0],
            0.002,
            0.4,
            None,
            {
                "q0[x]": lambda e: ([e, 0.5, 0.0], [1.0, 0.0, 0.0], {}),
                "v0[x]": lambda e: ([0.0, 0.5, 0.0], [1.0 + e, 0.0, 0.0], {}),
                "v0[theta]": lambda e: ([0.0, 0.5, 0.0], [1.0, 0.0, e], {}),
            },
        ),
        # the paper's star on a face: the two branch rows of its Abs contact, its mass m a parameter
        "star_face": (
            _star,
            [0.0, 0.5, 0.0],
            [1.0, 0.0, 0.0],
            0.001,
            0.4,
            None,
            {
                "v0[x]": lambda e: ([0.0, 0.5, 0.0], [1.0 + e, 0.0, 0.0], {}),
                "m": lambda e: ([0.0, 0.5, 0.0], [1.0, 0.0, 0.0], {"m": 1.0 + e}),
            },
        ),
        # inside a circle: a curved row that moves (the held Newton iterates every step)
        "bowl": (
            _bowl,
            [0.6, -0.8],
            [0.0, 0.0],
            0.001,
            0.5,
            None,
            {
                "q0 along": lambda e: (_rotated([0.6, -0.8], e), [0.0, 0.0], {}),
                "v0 along": lambda e: ([0.6, -0.8], [0.8 * e, 0.6 * e], {}),
            },
        ),
        # forces (drag c, a push A cos(W t)): no held grid step, the chain's constrained segment takes each
        "drag": (
            _dragged,
            [0.0, 0.0],
            [1.0, 0.0],
            0.01,
            1.0,
            None,
            {
                "v0[x]": lambda e: ([0.0, 0.0], [1.0 + e, 0.0], {}),
                "c": lambda e: ([0.0, 0.0], [1.0, 0.0], {"c": 0.4 + e}),
                "W": lambda e: ([0.0, 0.0], [1.0, 0.0], {"W": 1.7 + e}),
            },
        ),
        # a bilateral rod (Cartesian pendulum): always held, its length l a parameter
        "rod": (
            pendulum,
            rod,
            [0.0, 0.0],
            0.01,
            1.0,
            None,
            {
                "q0 along": lambda e: (_rotated(rod, e), [0.0, 0.0], {}),
                "l": lambda e: ([(1.0 + e) * c for c in rod], [0.0, 0.0], {"l": 1.0 + e}),
            },
        ),
    }


HELD_SCENES = _held_scenes()


@cache
def held_simulator(scene: str, backend: str) -> vcigen.Simulator:
    return vcigen.build(HELD_SCENES[scene][0](), backend=backend)


def held_mode(res: vcigen.Result) -> tuple:
    """The mode of a held run: its impacts, active sets and lift-offs."""
    return mode(res), res.active.tobytes(), len(res.liftoffs)


def held_finite_differences(sim: vcigen.Simulator, scene: str, eps: float = 1e-6, scenes=None) -> tuple:
    """``(run, {path: (S dz, central difference)})`` along each path of the scene (``dz`` its direction in
    ``(q0, v0, params)``, by a central difference of the path itself: exact for straight paths)."""
    _, q0, v0, h, t_end, params, paths = (scenes or HELD_SCENES)[scene]
    res = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    names = [str(s) for s in sim.model.defaults]

    def z_of(point) -> np.ndarray:
        q, v, par = point
        values = dict(zip(names, sim.model.resolve_params(params)))
        values.update(par)
        return np.concatenate([q, v, [values[k] for k in names]])

    out = {}
    for label, path in paths.items():
        dz = (z_of(path(1e-4)) - z_of(path(-1e-4))) / 2e-4
        ends = []
        for sign in (1.0, -1.0):
            q, v, par = path(sign * eps)
            r = sim.simulate(q, v, h, t_end=t_end, params={**(params or {}), **par}, progress=False)
            assert held_mode(r) == held_mode(res), f"{label}: the mode changed"
            ends.append(np.hstack([r.q, r.p]))
        out[label] = (res.sensitivity @ dz, (ends[0] - ends[1]) / (2 * eps))
    return res, out


def held_backends():
    for scene in sorted(HELD_SCENES):
        for b in BACKENDS:
            backend, marks = (b, ()) if isinstance(b, str) else (b.values[0], b.marks)
            yield pytest.param(scene, backend, marks=marks, id=f"{scene}-{backend}")


@pytest.mark.parametrize("scene, backend", list(held_backends()))
def test_held_steps_match_finite_differences(scene: str, backend: str) -> None:
    """Sustained contact with a fixed active set: the tangent through ``rattle`` and ``rattle_project``
    (whichever path took the step: the held grid step of ``vcigen.held``, its C glide, or the chain) against
    central differences of whole runs along paths that keep the mode; every step is covered."""
    sim = held_simulator(scene, backend)
    res, per = held_finite_differences(sim, scene)
    assert res.active[1:].any(axis=1).all() or sim.model.constraint  # held throughout (a rod: always)
    assert res.sensitivity_breaks == []
    assert np.isfinite(res.sensitivity).all()
    errs = {label: relative_error(exact, fd) for label, (exact, fd) in per.items()}
    print(f"{scene} ({backend}): " + ", ".join(f"{k} {v:.1e}" for k, v in errs.items()))
    assert max(errs.values()) <= 1e-6, errs
    assert max(np.abs(exact[-1]).max() for exact, _ in per.values()) > 0.1  # the paths do move the end


def _lift_dome() -> vcigen.Model:
    """A particle on the dome ``sqrt(x^2 + y^2) >= R`` (gravity ``g``): it slides, then lifts off."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g, r = sp.symbols("g R", positive=True)
    return vcigen.Model(
        name="lift_dome",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"dome": sp.sqrt(x**2 + y**2) - r},
        params={g: 9.81, r: 1.0},
    )


def _lift_hump() -> vcigen.Model:
    """A particle launched up the hump ``y >= exp(-x^2)`` from its concave foot: held, then it lifts off
    short of the top (where ``v^2 kappa`` exceeds ``g cos``) and flies."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g = sp.Symbol("g", positive=True)
    return vcigen.Model(
        name="lift_hump",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"hump": y - sp.exp(-(x**2))},
        params={g: 9.81},
    )


def _on_hump(x0: float, speed: float) -> tuple[list[float], list[float], dict]:
    """A start on the hump at ``x0``, its velocity along the surface."""
    slope = -2.0 * x0 * math.exp(-(x0**2))
    norm = math.hypot(1.0, slope)
    return [x0, math.exp(-(x0**2))], [speed / norm, speed * slope / norm], {}


# (model, q0, v0, h, t_end, params, paths): a held run with a lift-off located inside a step, then free
LIFT_SCENES = {
    "dome": (
        _lift_dome,
        [0.0, 1.0],
        [0.1, 0.0],
        0.005,
        1.6,
        None,
        {
            "q0 along": lambda e: (_rotated([0.0, 1.0], e), _rotated([0.1, 0.0], e), {}),
            "v0[x]": lambda e: ([0.0, 1.0], [0.1 + e, 0.0], {}),
            "g": lambda e: ([0.0, 1.0], [0.1, 0.0], {"g": 9.81 + e}),
            "R": lambda e: ([0.0, 1.0 + e], [0.1, 0.0], {"R": 1.0 + e}),
        },
    ),
    "hump": (
        _lift_hump,
        *_on_hump(-1.5, 5.0)[:2],
        0.005,
        0.6,
        None,
        {
            "q0 along": lambda e: _on_hump(-1.5 + e, 5.0),
            "speed": lambda e: _on_hump(-1.5, 5.0 + e),
            "g": lambda e: (*_on_hump(-1.5, 5.0)[:2], {"g": 9.81 + e}),
        },
    ),
}


@cache
def lift_simulator(scene: str, backend: str) -> vcigen.Simulator:
    return vcigen.build(LIFT_SCENES[scene][0](), backend=backend)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", sorted(LIFT_SCENES))
def test_liftoff_matches_finite_differences(scene: str, backend: str) -> None:
    """A lift-off at a located time (``Tracker.liftoff``): the held sub-step to the root of the contact
    force, its time by the implicit-function theorem, then the free rest of the step, against central
    differences of whole runs across the lift-off along paths that keep the mode (the same lift-off step);
    covered to the end."""
    liftoff_tangent_matches_finite_differences(lift_simulator(scene, backend), scene, f"{scene} ({backend})")


def liftoff_tangent_matches_finite_differences(sim: vcigen.Simulator, scene: str, label: str) -> None:
    """The lift-off scene's tangent against central differences along paths that keep the mode, over the
    whole run and over the step across the lift-off on its own (every rule)."""
    res, per = held_finite_differences(sim, scene, scenes=LIFT_SCENES)
    assert len(res.liftoffs) == 1 and res.n_impacts == 0
    lift = int((res.liftoffs[0][0] - res.t[0]) / (res.t[1] - res.t[0]))
    assert res.active[: lift + 1, 0].all() and not res.active[lift + 1 :].any() and lift > 50
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {column: relative_error(exact, fd) for column, (exact, fd) in per.items()}
    print(f"{label}: " + ", ".join(f"{k} {v:.1e}" for k, v in errs.items()))
    assert max(errs.values()) <= 1e-6, errs
    for exact, fd in per.values():  # the step across the lift-off on its own
        jump = exact[lift + 1] - exact[lift]
        assert np.abs(jump - (fd[lift + 1] - fd[lift])).max() <= 1e-6 * max(1.0, np.abs(exact).max())
