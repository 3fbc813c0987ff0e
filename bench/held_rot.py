"""The rotation form of the held step on a circle (``bench.held_floor``'s ``rot``), on vcigen's own models.

    .venv/bin/python -m bench.held_rot [--steps 300]

``bench.held_floor`` writes the rotation form by hand for the unit circle, unit mass and gravity. This is the
same algorithm for any row of ``held.closed_forms`` in the plane (a circle of radius ``R`` about ``c``, an
isotropic mass ``m``) under a constant force ``f`` (the numpy prototype of :mod:`vcigen.held_circle`, which
generates it; that module's routines are tested in ``tests/test_held_circle.py``), run against
vcigen's held step (``Kernels.held_step``: today's closed step, CasADi kernels) from the same start, each for
``--steps`` steps or until its tests refuse a step (the dome's lift-off):

* ``n = (q - c) / R``, ``t = (-n_y, n_x)``; ``omega = t . v0`` with ``v0 = (p + h f / 2) / m`` the free
  velocity; ``a = h omega / R``, ``s = sqrt(arg)``, ``arg = 1 / |n|^2 - a^2`` at the start;
* ``n1 = s n + a t`` (``q1 = c + R n1``: ``z1 = z (s + i a)``), ``t1 = (-n1_y, n1_x)``;
* ``p1 = pi1 t1``, ``pi1 = m omega + (h / 2) f . t1`` (the projection of ``p+ = m v + h f / 2`` onto the
  tangent at ``q1``: ``v . t1 = omega`` exactly on the circle);
* the next ``omega1 = omega + (h / m) f . t1 = o0 + o1 s`` (``f . t1 = s f . t - a f . n``), so the next
  argument ``1 / |n1|^2 - (h omega1 / R)^2`` is ``A + B s`` with ``s^2 = arg`` and
  ``|n1|^2 = |n|^2 (arg + a^2)`` (``1 / |n1|^2`` to first order, ``2 - |n1|^2``);
* the booked impulse ``Lam + Lam'`` from the momentum change ``J = p1 - p0 - h f`` along ``n0 + n1``:
  ``J = Lam g0 + Lam' g1`` with ``g = sigma n`` (``grad psi`` on the row), and ``n0 . (n0 + n1) =
  n1 . (n0 + n1) = 1 + s``; ``E_d`` from the kernels' ``held_segment`` at ``v = (q1 - q0) / h``.

Printed per model and h: the steps each took, and the largest difference of q, p, the impulse and E_d.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen

HERE = Path(__file__).resolve().parent
X, Y, XD, YD = sp.symbols("x y xd yd")
R_, M_ = sp.symbols("R m", positive=True)
G = 9.81


def _planar(name: str, psi: sp.Expr, mass: float | sp.Symbol = 1, params=None, constraint: bool = False):
    rows = {"constraints": {"row": psi}} if constraint else {"contacts": {"row": psi}}
    return vcigen.Model(
        name=name,
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=mass * (XD**2 + YD**2) / 2 - mass * G * Y,
        params=params or {},
        **rows,
    )


# name: model, centre, radius, mass, sigma (grad psi = sigma n on the row), start (q0, v0)
SCENES = {
    "bowl": (_planar("hr_bowl", R_ - sp.sqrt(X**2 + Y**2), params={R_: 1.0}), (0, 0), 1.0, 1.0, -1.0,
             ((0.6, -0.8), (0.0, 0.0))),
    "dome": (_planar("hr_dome", sp.sqrt(X**2 + Y**2) - R_, M_, {R_: 1.0, M_: 2.0}), (0, 0), 1.0, 2.0, 1.0,
             ((0.0, 1.0), (0.3, 0.0))),
    "offset": (_planar("hr_offset", R_ - sp.sqrt((X - 0.3) ** 2 + (Y + 0.2) ** 2), params={R_: 1.5}),
               (0.3, -0.2), 1.5, 1.0, -1.0, ((1.2, -1.4), (0.5, 0.375))),
    "rod": (_planar("hr_rod", X**2 + Y**2 - 1, constraint=True), (0, 0), 1.0, 1.0, 2.0,
            ((0.0, -1.0), (3.0, 0.0))),
}  # fmt: skip


def rot_run(q0, p0, centre, radius, mass, force, sigma, h, steps, kern, kc):
    """The rotation form from (q0, p0): arrays q, p, impulse, E_d of the steps it takes (lift-off: a negative
    normal force on a contact row, as ``held_step``'s test, ends the run)."""
    c, f = np.asarray(centre, float), np.asarray(force, float)
    q, p = np.asarray(q0, float), np.asarray(p0, float)
    n = (q - c) / radius
    t = np.array([-n[1], n[0]])
    om = t @ (p + 0.5 * h * f) / mass
    arg = 1.0 / (n @ n) - (h * om / radius) ** 2
    out = []
    for _ in range(steps):
        s = math.sqrt(arg)
        a = h * om / radius
        n1 = s * n + a * t
        t1 = np.array([-n1[1], n1[0]])
        q1 = c + radius * n1
        pi1 = mass * om + 0.5 * h * (f @ t1)
        p1 = pi1 * t1
        # the normal force of the row on q1 (held_step's lift-off test, sign of sigma): m |u1|^2 / R + f . n1
        # pressed outwards for sigma < 0 (inside), inwards for sigma > 0 (outside)
        normal = -np.sign(sigma) * (pi1 * pi1 / (mass * radius) + f @ n1) if sigma != 2.0 else 0.0
        if normal < 0.0:
            break
        imp = (p1 - p - h * f) @ (n + n1) / (sigma * (1.0 + s))
        _, energy = kern.held_segment(q, (q1 - q) / h, kc)
        out.append((q1, p1, imp, float(np.ravel(energy)[0])))
        o0, o1 = om - h / mass * a * (f @ n), h / mass * (f @ t)
        ho0, ho1 = h * o0 / radius, h * o1 / radius
        arg = (2.0 - (n @ n) * (arg + a * a) - ho1 * ho1 * arg) - ho0 * ho0 - 2.0 * ho0 * ho1 * s
        om = o0 + o1 * s
        q, p, n, t = q1, p1, n1, t1
    return [np.array([o[i] for o in out]) for i in range(4)]


def held_run(kern, sim, q0, p0, h, steps):
    """vcigen's held step (``Kernels.held_step``) from (q0, p0): q, p, impulse, E_d of the steps it takes."""
    q, p, lam = np.asarray(q0, float), np.asarray(p0, float), np.zeros(1)
    act = np.ones(1, dtype=bool)
    out = []
    for _ in range(steps):
        held = kern.held_step(q, p, lam, act, h, sim.tol.residual, sim.tol.phi)
        if held is None:
            break
        out.append((held.q1, held.p1, float(held.lam[0] + held.lam1[0]), held.energy))
        q, p, lam = held.q1, held.p1, held.lam
    return [np.array([o[i] for o in out]) for i in range(4)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    a = ap.parse_args(argv)
    print(f"{'model':<7} {'h':>6} {'steps':>11} {'|dq|':>8} {'|dp|':>8} {'|d imp|':>8} {'|dE_d|':>8}")
    worst = 0.0
    for name, (model, centre, radius, mass, sigma, (q0, v0)) in SCENES.items():
        sim = vcigen.build(model, backend="casadi")
        kern = sim.kernels.bind(sim.model.resolve_params(None))
        force = np.array([0.0, -mass * G])
        for h in (1e-5, 1e-3, 1e-2):
            kc = kern.held_consts(h)
            p0 = mass * np.asarray(v0, float)  # v0 tangent: p0 = m v0
            ref = held_run(kern, sim, q0, p0, h, a.steps)
            got = rot_run(q0, p0, centre, radius, mass, force, sigma, h, a.steps, kern, kc)
            m = min(len(ref[0]), len(got[0]))
            d = [float(np.max(np.abs(x[:m] - y[:m]), initial=0.0)) for x, y in zip(ref, got)]
            worst = max(worst, d[0])
            print(f"{name:<7} {h:>6.0e} {len(got[0]):>5}/{len(ref[0]):<5} {d[0]:>8.1e} {d[1]:>8.1e} "
                  f"{d[2]:>8.1e} {d[3]:>8.1e}")  # fmt: skip
    print(f"largest |dq|: {worst:.1e}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
