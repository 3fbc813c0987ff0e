"""Exact sensitivities through events inside a held step (``vcigen.sensitivity``: ``Tracker.event``,
``impulse``, ``free_end``; C ``templates/sens_events.c.j2``): an impact of another contact while rows are
held (a particle sliding on the floor into a wall, elastic and with restitution; a box landing on a vertex
and settling on its long face, the second vertex plastic or bouncing while the first is held), located like
(47) along the constrained sub-step map, the impulse law onto the rows, then the constrained rest of the step
with the new active set. Against central differences of whole runs along paths that keep the mode, on both
backends; C = CasADi; the step across an elastic impact while held is symplectic (its exact Jacobian on the
free coordinates); the events still not covered give their break.
"""

from __future__ import annotations

from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from test_c_agreement_sustained import _pendulum
from test_sensitivity import (
    BACKENDS,
    _rotated,
    assert_lost,
    held_finite_differences,
    held_mode,
    relative_error,
)
from test_sensitivity_c import assert_same_tangent

import vcigen
from vcigen.analysis import jacobian_symplectic_defect

G = 9.81
ROD = [float(np.sin(1.0)), -float(np.cos(1.0))]  # the rod's end, 1 rad from the vertical


def floor_wall() -> vcigen.Model:
    """A unit particle on the floor ``y >= 0`` under gravity ``g``, sliding into the wall ``x <= W`` with
    restitution ``e`` (1 by default: elastic)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g, w, e = sp.symbols("g W e", positive=True)
    return vcigen.Model(
        name="ev_wall",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"floor": y, "wall": w - x},
        params={g: G, w: 0.455, e: 1.0},
        restitution={"wall": e},
    )


def box() -> vcigen.Model:
    """A 2 x 1 box with a contact at each vertex, restitution ``e`` (a parameter) at every one."""
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    e = sp.Symbol("e")
    corners = [(1.0, -0.5), (-1.0, -0.5), (1.0, 0.5), (-1.0, 0.5)]
    contacts = {f"v{i}": y + a * sp.sin(th) + b * sp.cos(th) for i, (a, b) in enumerate(corners)}
    return vcigen.Model(
        name="ev_box",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + sp.Rational(5, 24) * thd**2 - G * y,
        contacts=contacts,
        params={e: 0.0},
        restitution=dict.fromkeys(contacts, e),
    )


def twin() -> vcigen.Model:
    """Two unit particles on the floor, each lifted by a force of time (``A t``, ``B t``): they leave it at
    ``g / A`` and ``g / B``, both inside one grid step (0.5771, 0.5774 at ``h = 0.01``)."""
    x1, y1, x2, y2, a1, b1, a2, b2, t = sp.symbols("x1 y1 x2 y2 x1d y1d x2d y2d t")
    g, a, b = sp.symbols("g A B", positive=True)
    return vcigen.Model(
        name="ev_twin",
        q=[x1, y1, x2, y2],
        qdot=[a1, b1, a2, b2],
        lagrangian=(a1**2 + b1**2 + a2**2 + b2**2) / 2 - g * (y1 + y2),
        contacts={"left": y1, "right": y2},
        params={g: G, a: 17.0, b: 16.99},
        forces=[0, a * t, 0, b * t],
        time=t,
    )


def pop() -> vcigen.Model:
    """A unit particle dropped on a plastic floor under a vertical force ``A + c yd`` (``A > g``): falling
    fast it is pressed in, so the impact is plastic, but with the normal velocity gone the floor pulls: its
    force is negative at the start of the rest of the step, released there (a lift-off at its start)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g, a, c = sp.symbols("g A c", positive=True)
    return vcigen.Model(
        name="ev_pop",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"floor": y},
        params={g: G, a: 12.0, c: 5.0},
        forces=[0, a + c * yd],
        restitution={"floor": 0},
    )


def lift_wall() -> vcigen.Model:
    """A unit particle sliding on the floor, lifted by a force of time ``A t`` (it leaves the floor at
    ``g / A``), into the wall ``x <= W`` in the same step as its lift-off (an impact in the free rest)."""
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    g, a, w = sp.symbols("g A W", positive=True)
    return vcigen.Model(
        name="ev_lift_wall",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"floor": y, "wall": w - x},
        params={g: G, a: 17.0, w: 0.2887},
        forces=[0, a * t],
        time=t,
    )


def pair() -> vcigen.Model:
    """Two unit particles sliding on the floor into two walls that both meet at the same instant."""
    x1, y1, x2, y2, a1, b1, a2, b2 = sp.symbols("x1 y1 x2 y2 x1d y1d x2d y2d")
    return vcigen.Model(
        name="ev_pair",
        q=[x1, y1, x2, y2],
        qdot=[a1, b1, a2, b2],
        lagrangian=(a1**2 + b1**2 + a2**2 + b2**2) / 2 - G * (y1 + y2),
        contacts={"floor1": y1, "floor2": y2, "right": 0.455 - x1, "left": 0.455 + x2},
    )


def _tilted(dx: float = 0.0, dth: float = 0.0, dvx: float = 0.0, dw: float = 0.0):
    return [dx, 0.6, 0.1 + dth], [0.3 + dvx, 0.0, dw], {}


# scene -> (model maker, q0, v0, h, t_end, params, paths): paths keep the mode (test_sensitivity.held_mode)
SCENES = {
    # the particle slides on the floor (held) into the wall: an elastic impact while held, inside step 45
    "wall": (
        floor_wall,
        [0.0, 0.0],
        [1.0, 0.0],
        0.01,
        0.8,
        None,
        {
            "q0[x]": lambda e: ([e, 0.0], [1.0, 0.0], {}),
            "v0[x]": lambda e: ([0.0, 0.0], [1.0 + e, 0.0], {}),
            "W": lambda e: ([0.0, 0.0], [1.0, 0.0], {"W": 0.455 + e}),
        },
    ),
    # the same with restitution e at the wall (its target -e g.qdot moves with e)
    "wall_lossy": (
        floor_wall,
        [0.0, 0.0],
        [1.0, 0.0],
        0.01,
        0.8,
        {"e": 0.6},
        {
            "v0[x]": lambda e: ([0.0, 0.0], [1.0 + e, 0.0], {}),
            "W": lambda e: ([0.0, 0.0], [1.0, 0.0], {"W": 0.455 + e}),
            "e": lambda e: ([0.0, 0.0], [1.0, 0.0], {"e": 0.6 + e}),
        },
    ),
    # dropped tilted, plastic (e = 0): lands on v1 (the plastic entry), rotates about it, v0 lands while v1 is
    # held (an impact while held, plastic: both held after it)
    "box_settle": (
        box,
        *_tilted()[:2],
        0.005,
        0.4,
        None,
        {
            "q0[x]": lambda e: _tilted(dx=e),
            "q0[theta]": lambda e: _tilted(dth=e),
            "v0[x]": lambda e: _tilted(dvx=e),
            "v0[theta]": lambda e: _tilted(dw=e),
        },
    ),
    # e = 0.3: v0 bounces twice while v1 is held (restitution impacts while held), then lands plastic
    "box_bounce": (
        box,
        *_tilted()[:2],
        0.005,
        0.4,
        {"e": 0.3},
        {
            "q0[theta]": lambda e: _tilted(dth=e),
            "v0[x]": lambda e: _tilted(dvx=e),
            "v0[theta]": lambda e: _tilted(dw=e),
        },
    ),
    # two lift-offs in one step: the first, then a constrained segment with the other row, its lift-off, then
    # the free rest (a lift-off followed by a second event; the time slot of the forces in both roots)
    "twin": (
        twin,
        [0.0, 0.0, 1.0, 0.0],
        [0.5, 0.0, -0.5, 0.0],
        0.01,
        0.7,
        None,
        {
            "v0[x1]": lambda e: ([0.0, 0.0, 1.0, 0.0], [0.5 + e, 0.0, -0.5, 0.0], {}),
            "g": lambda e: ([0.0, 0.0, 1.0, 0.0], [0.5, 0.0, -0.5, 0.0], {"g": G + e}),
            "A": lambda e: ([0.0, 0.0, 1.0, 0.0], [0.5, 0.0, -0.5, 0.0], {"A": 17.0 + e}),
            "B": lambda e: ([0.0, 0.0, 1.0, 0.0], [0.5, 0.0, -0.5, 0.0], {"B": 16.99 + e}),
        },
    ),
    # released at the start of the rest of its plastic impact's step: the free rest from the impact point
    "pop": (
        pop,
        [0.0, 0.3],
        [0.4, -1.0],
        0.01,
        0.5,
        None,
        {
            "q0[y]": lambda e: ([0.0, 0.3 + e], [0.4, -1.0], {}),
            "v0[x]": lambda e: ([0.0, 0.3], [0.4 + e, -1.0], {}),
            "v0[y]": lambda e: ([0.0, 0.3], [0.4, -1.0 + e], {}),
            "A": lambda e: ([0.0, 0.3], [0.4, -1.0], {"A": 12.0 + e}),
            "c": lambda e: ([0.0, 0.3], [0.4, -1.0], {"c": 5.0 + e}),
        },
    ),
    # lifted off the floor, then into the wall in the same step: the free rest's impact chain (47)-(48)
    "lift_wall": (
        lift_wall,
        [0.0, 0.0],
        [0.5, 0.0],
        0.01,
        0.7,
        None,
        {
            "v0[x]": lambda e: ([0.0, 0.0], [0.5 + e, 0.0], {}),
            "g": lambda e: ([0.0, 0.0], [0.5, 0.0], {"g": G + e}),
            "A": lambda e: ([0.0, 0.0], [0.5, 0.0], {"A": 17.0 + e}),
            "W": lambda e: ([0.0, 0.0], [0.5, 0.0], {"W": 0.2887 + e}),
        },
    ),
    # a bilateral rod (Cartesian pendulum), always held, swinging into the wall x >= -0.5 (elastic)
    "rod_wall": (
        _pendulum,
        ROD,
        [0.0, 0.0],
        0.01,
        1.5,
        None,
        {
            "q0 along": lambda e: (_rotated(ROD, e), [0.0, 0.0], {}),
            "v0 along": lambda e: (ROD, [e * ROD[1] * -1.0, e * ROD[0]], {}),
        },
    ),
}
KINDS = {
    "rod_wall": {"elastic"},
    "wall": {"elastic"},
    "wall_lossy": {"restitution"},
    "box_settle": {"plastic"},
    "box_bounce": {"restitution"},
}


@cache
def _built(maker, backend: str) -> vcigen.Simulator:
    return vcigen.build(maker(), backend=backend)


def simulator(scene: str, backend: str) -> vcigen.Simulator:
    """The scene's simulator, one build per model (the walls and the boxes share theirs)."""
    return _built(SCENES[scene][0], backend)


def impacts_while_held(res: vcigen.Result) -> list:
    """The impacts whose step started with another contact held, or with a bilateral constraint (always)."""
    names, bilateral = res.contact_names, res.constraint_force.shape[1] > 0
    return [
        im
        for im in res.impacts
        if bilateral or any(res.active[im.step, j] for j, c in enumerate(names) if c != im.contact)
    ]


def _pairs():
    for scene in sorted(SCENES):
        for b in BACKENDS:
            backend, marks = (b, ()) if isinstance(b, str) else (b.values[0], b.marks)
            yield pytest.param(scene, backend, marks=marks, id=f"{scene}-{backend}")


@pytest.mark.parametrize("scene, backend", list(_pairs()))
def test_impacts_while_held_match_finite_differences(scene: str, backend: str) -> None:
    """The tangent across impacts while held against central differences of whole runs (every grid point),
    covered throughout (no break), the impacts while held of the kinds the scene makes."""
    events_match_finite_differences(simulator(scene, backend), scene, backend)


def events_match_finite_differences(sim: vcigen.Simulator, scene: str, tag: str) -> None:
    """The scene's events inside held steps (:func:`assert_scene_events`), no break, and its tangent along
    each of its paths within 1e-6 of central differences of whole runs (relative to the largest entry)."""
    res, per = held_finite_differences(sim, scene, scenes=SCENES)
    held = assert_scene_events(scene, res)
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {label: relative_error(exact, fd) for label, (exact, fd) in per.items()}
    print(
        f"{scene} ({tag}): {len(held)} impacts while held, {len(res.liftoffs)} lift-offs; "
        + ", ".join(f"{k} {v:.1e}" for k, v in errs.items())
    )
    assert max(errs.values()) <= 1e-6, errs
    assert max(np.abs(exact[-1]).max() for exact, _ in per.values()) > 0.1  # the paths do move the end


def assert_scene_events(scene: str, res: vcigen.Result) -> list:
    """The events inside held steps the scene is made for (its impacts while held, of the kinds it makes, or
    its lift-offs inside one step); returns the impacts while held."""
    held = impacts_while_held(res)
    if scene == "pop":  # the plastic impact and the lift-off at the same instant
        (im,) = res.impacts
        assert im.kind == "plastic" and len(res.liftoffs) == 1 and res.liftoffs[0][0] == pytest.approx(im.t)
    elif scene == "lift_wall":  # the lift-off and the wall impact inside one step
        (im,) = res.impacts
        assert (
            len(res.liftoffs) == 1 and int((res.liftoffs[0][0] - res.t[0]) / (res.t[1] - res.t[0])) == im.step
        )
    elif scene == "twin":  # both lift-offs inside one step
        steps = {int((t - res.t[0]) / (res.t[1] - res.t[0])) for t, _ in res.liftoffs}
        assert len(res.liftoffs) == 2 and len(steps) == 1 and res.n_impacts == 0, res.liftoffs
    else:
        assert held and KINDS[scene] <= {im.kind for im in held}, [(im.step, im.kind) for im in res.impacts]
    return held


@pytest.mark.skipif(hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem()))
@pytest.mark.parametrize("scene", sorted(SCENES))
def test_c_equals_casadi(scene: str) -> None:
    """The C loop's tangent (sens_events.c.j2) is the Python stepper's (Tracker.event, impulse), to 1e-9, and
    its run the plain library's bit for bit (its hooks give the forces' time slot back: without that the twin
    met a spurious impact, 4e-11, at its first lift-off)."""
    c_equals_casadi(simulator, scene, "")


def c_equals_casadi(make, scene: str, tag: str) -> None:
    """``make(scene, backend)``'s C run: the same mode and tangent as CasADi's (to 1e-9), no break, and its
    (q, p) the plain library's bit for bit."""
    _, q0, v0, h, t_end, params, _ = SCENES[scene]
    kw = {"t_end": t_end, "params": params, "sensitivities": True, "progress": False}
    a, b = (make(scene, backend).simulate(q0, v0, h, **kw) for backend in ("casadi", "c"))
    assert held_mode(a) == held_mode(b)
    plain = make(scene, "c").simulate(q0, v0, h, t_end=t_end, params=params, progress=False)
    np.testing.assert_array_equal(b.q, plain.q)  # the tangent's hooks leave the C run as it is
    np.testing.assert_array_equal(b.p, plain.p)
    rel = assert_same_tangent(a, b)
    print(f"{scene}{tag}: C against CasADi {rel:.1e}")
    assert b.sensitivity_breaks == []


@pytest.mark.parametrize("backend", BACKENDS)
def test_an_elastic_impact_while_held_is_symplectic(backend: str) -> None:
    """The particle held on the floor hitting the wall elastically: on the free coordinates ``(x, p_x)`` the
    exact step Jacobian ``J = S_k+1 S_k^-1`` (columns ``q0[x]``, ``v0[x]``) of the impact step is symplectic
    to round-off (``vcigen.analysis.jacobian_symplectic_defect``: 0 here, the map is linear), as are the
    held steps around it; with the impact time's tangent ``d tau_s`` dropped (``Tracker._located``) the
    impact step's defect is 1."""
    _, q0, v0, h, t_end, params, _ = SCENES["wall"]
    res = simulator("wall", backend).simulate(q0, v0, h, t_end=t_end, sensitivities=True, progress=False)
    (k,) = [im.step for im in res.impacts]
    block = res.sensitivity[:, [0, 2]][:, :, [0, 2]]  # rows (x, p_x), columns (q0[x], v0[x])
    defects = [jacobian_symplectic_defect(block[j + 1] @ np.linalg.inv(block[j])) for j in range(1, k + 3)]
    print(
        f"wall ({backend}): symplectic defect of the impact step {defects[k - 1]:.1e}, max {max(defects):.1e}"
    )
    assert max(defects) <= 1e-12, defects


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_simultaneous_impact_while_held_breaks(backend: str) -> None:
    """Two rows hit at the same instant while held (the weights of the impulse switch): the tangent stops
    there with its reason (the same step and reason on both backends)."""
    sim = vcigen.build(pair(), backend=backend)
    res = sim.simulate([0.0] * 4, [1.0, 0.0, -1.0, 0.0], 0.01, t_end=0.6, sensitivities=True, progress=False)
    assert [im.step for im in res.impacts] == [45, 45] and res.active[45, :2].all()  # both on the floor
    assert assert_lost(res, "simultaneous impact") == 45


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_rod_against_the_wall_keeps_its_held_steps_symplectic(backend: str) -> None:
    """The bilateral rod swinging into the wall: the Gram matrix ``S_k^T Omega S_k`` of the tangent's
    columns (on the constraint manifold from the first step) is kept to round-off by every held step before
    and after the impact while held. The impact step itself changes it by O(h^2): the impulse law of an
    impact while held (``SustainedSteps._chain_impact``) is Newton's, not a variational jump (1.9e-3, 4.3e-4,
    8.1e-5, 7.8e-6 at h = 0.02, 0.01, 0.005, 0.0025; its tangent agrees with central differences, above)."""
    res = simulator("rod_wall", backend).simulate(
        ROD, [0.0, 0.0], 0.01, t_end=1.5, sensitivities=True, progress=False
    )
    (im,) = res.impacts
    s = res.sensitivity[:, :, :4]
    omega = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])
    gram = np.einsum("kia,ij,kjb->kab", s, omega, s)
    change = np.abs(np.diff(gram[1:], axis=0)).max(axis=(1, 2))  # step j + 1's
    held = np.delete(change, im.step - 1)
    print(f"rod_wall ({backend}): held steps {held.max():.1e}, the impact step {change[im.step - 1]:.1e}")
    assert np.abs(gram[1]).max() > 0.5 and held.max() <= 1e-13
