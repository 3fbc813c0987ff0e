"""Several isotropic cones slipping at once in the impulse law while held (stop 32).

Before, the impulse law at an impact while held let one isotropic cone slip at a time: a puck landing with a
tangential speed while another puck slid on the floor ended in ``SolverError`` "impulse law: 2 isotropic
cones slipping at once" (both backends, step 20). Now the cones slipping at once take Coulomb's sliding
impulse together (``ImpulseLaw._law_slide``, C ``<model>_law_slide``): block Gauss-Seidel over the cones,
each one's 1-D root (``friction.cone_slide``) with the others' tangential impulses fixed, until none moves
(``held_roots.SLIDE_TOL``). Cones the law does not couple (two pucks) settle in one sweep; coupled ones (a
ball struck while it slides on the floor, through the ball) in a few.

Also fixed on the way, both backends: cones near rest are braked together only where something links them
(``vcigen.coupling``; two unrelated pucks slowing in one step broke the tangent), and the check that a
contact's mode changed only by a contact held anew (``SustainedSteps._no_switch``, C ``<model>_no_switch``)
compared a slipping cone's slips as they are, but a cone's direction is aimed anew at every segment's start
(within the mode): C broke the tangent at the landing ("friction switch in a held step") where the new aim
differed in the last bit.
"""

from __future__ import annotations

import math
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS
from scipy.optimize import fsolve

import vcigen
import vcigen.impulse_law

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.puck_drops import drops, model, report  # noqa: E402

G, MU = 9.81, 0.3
RADIUS, MASS, INERTIA, MU_AB = 0.5, 1.0, 0.1, 0.2


def tangent_error(sim, q0, v0, res, cols, **kw) -> float:
    """The largest difference of ``res``'s tangent at its end from central differences of whole runs (eps
    1e-6) over the columns ``cols`` of ``(q0, v0)``."""
    n, worst = len(q0), 0.0
    for j in cols:
        d = np.zeros(2 * n)
        d[j] = 1e-6
        ends = [sim.simulate(q0 + s * d[:n], v0 + s * d[n:], **kw) for s in (1, -1)]
        fd = np.concatenate([ends[0].q[-1] - ends[1].q[-1], ends[0].p[-1] - ends[1].p[-1]]) / 2e-6
        worst = max(worst, float(np.abs(fd - res.sensitivity[-1, :, j]).max()))
    return worst


@cache
def pucks(backend: str) -> vcigen.Simulator:
    return vcigen.build(model(2), backend=backend)  # two pucks, plastic, mu = 0.3


PUCK_Q0 = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.05])
PUCK_V0 = np.array([2.0, 0.5, 0.0, 0.5, 0.2, 0.0])


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_puck_landing_sliding_while_another_slides(backend: str) -> None:
    """The first puck slides on the floor at ``(2, 0.5)``; the second falls from 0.05 with ``(0.5, 0.2)``
    and lands plastically at ``t_l = sqrt(2 z / g)`` while the first slips: both cones slip in the law.
    Closed forms: the lander's normal impulse ``N = g t_l``, its sliding after ``w (1 - mu N / |w|)``,
    then braked at ``mu g`` to rest at ``w+ |w+| / (2 mu g)`` from the landing point; the first slides on
    at ``mu g`` untouched by the impact. State at t = 0.6 to 1e-9 (2e-15 seen), and the tangent against
    central differences of whole runs (eps 1e-6) over ``q0``, ``v0`` but the first puck's ``z`` (it would
    leave the floor) to 1e-7 (1.6e-9 seen), no break."""
    sim = pucks(backend)
    kw = {"h": 0.005, "t_end": 0.6, "progress": False}
    res = sim.simulate(PUCK_Q0, PUCK_V0, sensitivities=True, **kw)
    t_l = math.sqrt(2.0 * 0.05 / G)
    assert [(i.contact, i.kind) for i in res.impacts] == [("f1", "plastic")]  # contacts f0, f1
    assert abs(res.impacts[0].t - t_l) < 1e-12
    w = PUCK_V0[3:5]
    after = w * (1.0 - MU * G * t_l / np.linalg.norm(w))
    rest = PUCK_Q0[3:5] + w * t_l + after * np.linalg.norm(after) / (2.0 * MU * G)
    assert np.abs(res.q[-1, 3:6] - [*rest, 0.0]).max() < 1e-9 and np.abs(res.v[-1, 3:6]).max() < 1e-12
    w1, t = PUCK_V0[:2], 0.6
    s1 = np.linalg.norm(w1)
    assert np.abs(res.q[-1, :2] - w1 / s1 * (s1 * t - MU * G * t * t / 2.0)).max() < 1e-9
    assert np.abs(res.v[-1, :2] - w1 / s1 * (s1 - MU * G * t)).max() < 1e-9
    assert res.sensitivity_breaks == []
    worst = tangent_error(sim, PUCK_Q0, PUCK_V0, res, [j for j in range(12) if j not in (2, 8)], **kw)
    print(f"{backend}: two cones slipping at a landing, tangent vs central differences {worst:.1e}")
    assert worst <= 1e-7


def two_balls() -> vcigen.Model:
    """Ball A on the floor (a rough isotropic cone, ``mu``) and ball B, a weightless striker at A's height
    (``m = 1``, ``I = 0.1``, ``r = 0.5``, small rotation angles as coordinates); the contact of A and B has a
    cone of its own (``mu_ab``, the tangents of a head-on contact along ``x``: the relative velocities of
    the contact points along ``y`` and ``z``). Both contacts plastic. A's floor cone and the A-B cone are
    coupled through A."""
    qa, qb = sp.symbols("xa ya za axa aya aza"), sp.symbols("xb yb zb axb ayb azb")
    qda, qdb = sp.symbols("xad yad zad axad ayad azad"), sp.symbols("xbd ybd zbd axbd aybd azbd")
    xa, ya, za, axa, aya, aza = qa
    xb, yb, zb, _, ayb, azb = qb
    distance = sp.sqrt((xa - xb) ** 2 + (ya - yb) ** 2 + (za - zb) ** 2) - 2 * RADIUS
    kin = sum(MASS / 2 * v**2 for v in (*qda[:3], *qdb[:3]))
    kin += sum(INERTIA / 2 * v**2 for v in (*qda[3:], *qdb[3:]))
    return vcigen.Model(
        name="two_balls",
        q=[*qa, *qb],
        qdot=[*qda, *qdb],
        lagrangian=kin - MASS * G * za,
        contacts={"floor": za - RADIUS, "ab": distance},
        restitution={"floor": 0.0, "ab": 0.0},
        friction={
            "floor": (MU, (xa - RADIUS * aya, ya + RADIUS * axa)),
            "ab": (MU_AB, (ya - RADIUS * aza - yb - RADIUS * azb, za + RADIUS * aya - zb + RADIUS * ayb)),
        },
    )


@cache
def balls(backend: str) -> vcigen.Simulator:
    return vcigen.build(two_balls(), backend=backend)


BALL_Q0 = np.array([2.0, 0.0, RADIUS, 0.0, 0.0, 0.0, 0.5, 0.0, RADIUS, 0.0, 0.0, 0.0])
BALL_V0 = np.array([0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 4.0, 3.0])
BALL_KW = {"h": 0.005, "t_end": 0.4, "progress": False}


def coulomb_reference(q: np.ndarray, vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The impact of B on A (plastic, A held on the floor) solved independently: the six impulses ``(N_f,
    N_ab, m_f, m_ab)`` with both normal velocities after 0 and each cone's tangential impulse ``-mu N w+ /
    |w+|`` against its sliding after (``scipy.optimize.fsolve`` from the frictionless law). The gradients
    and masses by hand. Returns the velocity after and the impulses."""
    r = RADIUS
    n = (q[:3] - q[6:9]) / np.linalg.norm(q[:3] - q[6:9])
    rows = np.zeros((6, 12))
    rows[0, 2] = 1.0  # the floor
    rows[1, :3], rows[1, 6:9] = n, -n  # A-B
    rows[2, [0, 4]] = 1.0, -r  # the floor's tangents: x - r ay, y + r ax
    rows[3, [1, 3]] = 1.0, r
    rows[4, [1, 5, 7, 11]] = 1.0, -r, -1.0, -r  # A-B's: ya - r aza - yb - r azb, za + r aya - zb + r ayb
    rows[5, [2, 4, 8, 10]] = 1.0, r, -1.0, r
    minv = 1.0 / np.array([MASS] * 3 + [INERTIA] * 3 + [MASS] * 3 + [INERTIA] * 3)

    def after(z):
        return vel + minv * (rows.T @ z)

    def law(z):
        v = after(z)
        out = [rows[0] @ v, rows[1] @ v]
        for c, (mu, normal) in enumerate(((MU, z[0]), (MU_AB, z[1]))):
            w = rows[2 + 2 * c : 4 + 2 * c] @ v
            out += list(z[2 + 2 * c : 4 + 2 * c] + mu * normal * w / np.linalg.norm(w))
        return out

    w0 = rows[:2] * minv @ rows[:2].T
    start = np.zeros(6)
    start[:2] = np.linalg.solve(w0, -rows[:2] @ vel)
    z = fsolve(law, start, xtol=1e-13)
    assert np.abs(law(z)).max() < 1e-13
    return after(z), z


def test_a_ball_struck_while_it_slides_coupled_cones_against_an_independent_solution(monkeypatch) -> None:
    """Ball A slides along ``y`` at 3 (not rolling) when B, spinning, strikes it along ``x``: A's floor cone
    (held, slipping) and the A-B cone (landing, sliding) slip at once, coupled through A. The impulse law's
    velocity after (CasADi, captured at the law) against :func:`coulomb_reference` to 1e-10, both normal
    impulses positive; the law did run with two cones slipping (a few Gauss-Seidel sweeps)."""
    seen, laws = [], []
    law, slide = vcigen.impulse_law.ImpulseLaw._impulse_law, vcigen.impulse_law.ImpulseLaw._law_slide

    def impulse_law(self, step, t_k, q, p, guess, hit, targets):
        out = law(self, step, t_k, q, p, guess, hit, targets)
        laws.append((q.copy(), out[2].copy(), out[3].copy()))
        return out

    def law_slide(self, cones, *args):
        out = slide(self, cones, *args)
        seen.append((len(cones), out[0] is not None))
        return out

    monkeypatch.setattr(vcigen.impulse_law.ImpulseLaw, "_impulse_law", impulse_law)
    monkeypatch.setattr(vcigen.impulse_law.ImpulseLaw, "_law_slide", law_slide)
    res = balls("casadi").simulate(BALL_Q0, BALL_V0, **BALL_KW)
    assert [i.contact for i in res.impacts] == ["ab"] and (2, True) in seen
    # the law proper, after one trial with the A-B row's target 0: its normal speed is pulled apart by the
    # curvature of the distance at the incoming velocity, and is read again once stopped (_stopped_pressed)
    assert len(laws) == 2
    q, vel, vel_after = laws[-1]
    ref, z = coulomb_reference(q, vel)
    print(f"two coupled cones: impulses {z}, velocity after vs reference {np.abs(vel_after - ref).max():.1e}")
    assert z[0] > 0.0 and z[1] > 0.0
    assert np.abs(vel_after - ref).max() < 1e-10


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_ball_struck_while_it_slides_carries_the_tangent(backend: str) -> None:
    """The struck ball on both backends: the same run (C against CasADi, every step, to 1e-10), no break,
    and the tangent against central differences of whole runs (eps 1e-6) over A's ``y`` speed and B's
    ``x`` position, speed and spins, to 1e-7 (8e-9 seen)."""
    res = balls(backend).simulate(BALL_Q0, BALL_V0, sensitivities=True, **BALL_KW)
    if backend == "c":
        ref = balls("casadi").simulate(BALL_Q0, BALL_V0, **BALL_KW)
        assert np.abs(res.q - ref.q).max() < 1e-10 and np.abs(res.p - ref.p).max() < 1e-10
    assert res.sensitivity_breaks == []
    worst = tangent_error(balls(backend), BALL_Q0, BALL_V0, res, (6, 13, 18, 22, 23), **BALL_KW)
    print(f"{backend}: struck ball, tangent vs central differences {worst:.1e}")
    assert worst <= 1e-7


@pytest.mark.parametrize("backend", BACKENDS)
def test_random_pucks_on_a_rough_floor(backend: str) -> None:
    """Random drops of three pucks on a rough floor (``bench.puck_drops``: some resting and sliding, some
    landing, ``mu`` in [0.05, 1], ``e`` in [0, 0.9]), 24 in C and 6 on CasADi, to t = 1: none ends in a
    ``SolverError`` (before this stop 169 of 200 C drops did: "2 isotropic cones slipping at once"), the
    energy ``|v|^2/2 + g sum z`` never rises between grid points by more than 1e-9 (round-off; friction and
    plastic landings only take energy), no puck below the floor by more than 1e-9."""
    out = drops(vcigen.build(model(), backend=backend), 24 if backend == "c" else 6, seed=1)
    print(f"{backend}:\n{report(out)}")
    assert not out["errors"], report(out)
    assert out["rise"] <= 1e-9 and out["low"] > -1e-9


def test_coupled_cones_reads_the_pattern_of_the_delassus_matrix() -> None:
    """``coupling.coupled_cones``: two cones on disjoint coordinates are not linked; a rod's constraint row
    (active, after the cones' rows) links them; a third cone linked to neither stays apart."""
    from vcigen.coupling import coupled_cones

    g = np.zeros((6, 6))  # the stick rows of three cones on (x1, y1), (x2, y2), (x3, y3)
    for c in range(3):
        g[2 * c, 2 * c], g[2 * c + 1, 2 * c + 1] = 1.0, 1.0
    assert coupled_cones(g @ g.T, 3) == [False, False, False]
    rod = np.zeros((1, 6))
    rod[0, [0, 2]] = 1.0, -1.0  # x1 - x2: links the first two
    g2 = np.vstack([g, rod])
    assert coupled_cones(g2 @ g2.T, 3) == [True, True, False]


@pytest.mark.parametrize("backend", BACKENDS)
def test_two_unrelated_pucks_coming_to_rest_in_one_step(backend: str) -> None:
    """Two pucks sliding at ``(1, 0.3)`` and ``(1.004, 0.3)`` come to rest within one step of each other
    (t = 0.3548, 0.3561): both near rest in one step. Before, cones near rest were braked together (aimed
    implicitly, ``_cone_brake``) whatever linked them, and the tangent broke (``"held step (sustained
    contact)"``, step 70, both backends): one puck's run depended on whether another, unrelated, was slow at
    the same step. Now only linked cones are braked together (``vcigen.coupling``): the first puck's run is
    the one it has alone (the second at rest) to 1e-15, rests at the closed form ``w |w| / (2 mu g)`` to
    1e-12, no break, the tangent against central differences (eps 1e-6, ``x, y`` of ``q0``, ``v0``) to 1e-7
    (5.6e-9 seen)."""
    sim = pucks(backend)
    kw = {"h": 0.005, "t_end": 0.6, "progress": False}
    q0, v0 = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.0]), np.array([1.0, 0.3, 0.0, 1.004, 0.3, 0.0])
    both = sim.simulate(q0, v0, sensitivities=True, **kw)
    alone = sim.simulate(q0, np.array([1.0, 0.3, 0.0, 0.0, 0.0, 0.0]), **kw)
    assert np.abs(both.q[:, :3] - alone.q[:, :3]).max() <= 1e-15
    w = v0[:2]
    assert np.abs(both.q[-1, :2] - w * np.linalg.norm(w) / (2.0 * MU * G)).max() < 1e-12
    assert both.sensitivity_breaks == []
    worst = tangent_error(sim, q0, v0, both, (0, 1, 3, 4, 6, 7, 9, 10), **kw)
    print(f"{backend}: two pucks at rest within a step, tangent vs central differences {worst:.1e}")
    assert worst <= 1e-7
