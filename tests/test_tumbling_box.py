"""A rigid box tumbling onto a rough floor: four vertex contacts with restitution and Coulomb friction.

A planar box (``m = 1``, half sides ``a = 0.5``, ``b = 0.25``, ``q = (x, y, theta)``), each vertex a contact
``phi = Y_v >= 0`` with one tangent ``X_v`` (Coulomb, ``mu``) and restitution ``e``, thrown from ``y = 1``
with a random tilt and spin: it bounces, lands on a vertex, rocks, slides and comes to rest on a face. The
drop below is one of 200 random ones (``python -m bench.tumbling``: ``rng = np.random.default_rng(7)``,
``theta0`` in ``(-pi, pi)``, ``v0`` in ``(-2, 2) x (-1, 1) x (-5, 5)``, ``e, mu`` in ``(0, 1)``; drop 61) on
which the C run stopped with "more than 64 impacts and lift-offs in one step":

* ``slide_turns``: held on one vertex and slipping, the slip stops; sticking there its stick force leaves
  the cone and its normal force pulls at once. The release came first: the vertex, freed with no normal
  speed, landed again at the same instant (plastic), stuck again, and so on. Now the friction switch comes
  first at a segment's start (``SustainedSteps._chain``, C ``<model>_chain``): it slides back, pressing.

No closed form; the test asserts what holds for every drop: the run ends without an error on both backends,
never below the floor, its energy at the end below its start, resting on a face, the two backends on the
same impacts and states. (Two other drops of the 200 still end in a C ``SolverError``: bursts of lift-offs and
landings, each landing's friction impulse missing; README, *Known limits*.)
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, c_backend_problem

import vcigen

A, B, MASS = 0.5, 0.25, 1.0
VERTS = {f"v{i}": (sx * A, sy * B) for i, (sx, sy) in enumerate([(-1, -1), (1, -1), (1, 1), (-1, 1)])}
H = 0.005
T_END = 3.0
# case -> (theta0, v0, e, mu)
CASES = {
    "slide_turns": (
        -0.655938739174577,
        [1.1632551950821166, 0.7468748982913689, -3.2062873631179367],
        0.13630872481803047,
        0.11319164078204269,
    ),
}


def tumble() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    e, mu = sp.symbols("e mu")
    inertia = MASS * (4 * A * A + 4 * B * B) / 12
    contacts, friction = {}, {}
    for name, (px, py) in VERTS.items():
        contacts[name] = y + px * sp.sin(th) + py * sp.cos(th)
        friction[name] = (mu, x + px * sp.cos(th) - py * sp.sin(th))
    return vcigen.Model(
        name="tumble",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=MASS * (xd**2 + yd**2) / 2 + inertia * thd**2 / 2 - 9.81 * MASS * y,
        contacts=contacts,
        params={e: 0.3, mu: 0.5},
        restitution=dict.fromkeys(contacts, e),
        friction=friction,
    )


# Drop 138 of ``bench.tumbling`` (seed 7), which parted the backends by 8.4e-5 at t = 3: at t = 2.9648 a
# restitution impact on v2 beside v1 held and sticking leaves v1 moving out at 0.043, below the resolution, so
# it stays held; v2 sinks again at once (again: plastic). C located that crossing 1.8e-13 h in, and the
# sub-step's hold stopped v1 (v2's impulse 0.0128); CasADi's was within the least sub-step (1e-13 h), with no
# sub-step, v1 moving on (v2's impulse 0). Both now take that start as the sub-step's limit (rattle_project:
# HeldImpacts._held_limit, C held_limit). Drops 178 and 238 logged such an impulse apart the same way.
KEPT = {
    "kept_moving": (
        -1.3954412147301123,
        [-0.7843000353935374, 0.5213818356968012, -1.2581841375487244],
        0.3231888628795335,
        0.6363015699459732,
    ),
}


@cache
def simulator(backend: str) -> vcigen.Simulator:
    return vcigen.build(tumble(), backend=backend)


@cache
def run(case: str, backend: str) -> vcigen.Result:
    th0, v0, e, mu = (CASES | KEPT)[case]
    sim = simulator(backend)
    return sim.simulate([0.0, 1.0, th0], v0, H, t_end=T_END, params={"e": e, "mu": mu}, progress=False)


def lowest_vertex(q: np.ndarray) -> np.ndarray:
    """The lowest vertex's height at each grid point."""
    heights = [q[:, 1] + px * np.sin(q[:, 2]) + py * np.cos(q[:, 2]) for px, py in VERTS.values()]
    return np.min(heights, axis=0)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", sorted(CASES))
def test_the_box_comes_down_without_an_error(case: str, backend: str) -> None:
    """To ``t = 3``: no ``SolverError``, never below the floor, energy at the end below the start, and
    lying on a face at rest (two vertices held, kinetic energy ~0) where it stops."""
    res = run(case, backend)
    assert res.t[-1] == pytest.approx(T_END)
    assert lowest_vertex(res.q).min() >= -1e-9
    assert res.energy[-1] < res.energy[0]
    held = res.active[-1]
    assert held.sum() == 2  # on a face
    kinetic = 0.5 * MASS * (res.v[-1, 0] ** 2 + res.v[-1, 1] ** 2)
    kinetic += 0.5 * MASS * (4 * A * A + 4 * B * B) / 12 * res.v[-1, 2] ** 2
    assert kinetic <= 1e-20
    if case == "slide_turns":  # the slip turned at t = 0.884: slid on, no lift-off and landing there
        assert not any(abs(t - 0.884146) < 1e-5 for t, _ in res.liftoffs)
        assert not any(abs(im.t - 0.884146) < 1e-5 for im in res.impacts)
    print(f"{case} ({backend}): {len(res.impacts)} impacts, {len(res.liftoffs)} lift-offs, rests on {held}")


@pytest.mark.skipif(c_backend_problem() is not None, reason=str(c_backend_problem()))
@pytest.mark.parametrize("case", sorted(CASES | KEPT))
def test_c_equals_casadi(case: str) -> None:
    """The C run is the CasADi one: the same impacts (step, contact, kind) and lift-offs, states to 1e-9."""
    a, b = run(case, "casadi"), run(case, "c")

    def log(res):
        return [(i.step, i.contact, i.kind) for i in res.impacts]

    assert log(a) == log(b)
    assert [c for _, c in a.liftoffs] == [c for _, c in b.liftoffs]
    assert np.abs(a.q - b.q).max() <= 1e-9 and math.isfinite(float(np.abs(a.q - b.q).max()))
