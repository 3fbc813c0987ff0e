"""Two-tangent friction (the isotropic cone of a 3-D contact): the figures of the README's *Friction* section.

    .venv/bin/python bench/friction_3d.py

The scenes and closed forms are those of ``tests/test_friction_3d.py``, on both backends:

* a puck launched at (1.2, -0.9) on a level floor, mu = 0.4: largest error of the path against the straight
  stop after v^2/(2 mu g), and of friction's work against -v^2/2;
* a puck launched across an incline at (1.5, 0.5) (tan a = mu/2: it curves and stops) and at (1, 0) on a
  steep one (tan a = 1.5 mu: it turns downhill): largest error against scipy's Coulomb ODE (DOP853, rtol
  1e-13, the stop as an event) at h = 0.02, 0.01, 0.005, and the order between successive h;
* the same curved stop with the slip direction frozen at each segment's start instead of aimed at its
  midpoint (Python stepper only): why the aim;
* a ball dropped spinning on a rough floor: velocity and spin after the impact against Coulomb's law (roll and
  slip) at h = 0.01, 0.005;
* C against CasADi on the ball bouncing to rolling and the curved stop.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_friction_3d import INERTIA, MASS, MU, G, coulomb_ball, incline_reference, sim  # noqa: E402

from vcigen import held_roots, sustained  # noqa: E402


def straight(backend: str) -> str:
    vx, vy = 1.2, -0.9
    v = math.hypot(vx, vy)
    ts, dist = v / (MU * G), v * v / (2 * MU * G)
    out = []
    for h in (0.01, 0.003):
        res = sim("puck", backend).simulate(q0=[0.0, 0.0, 0.0], v0=[vx, vy, 0.0], h=h, t_end=1.0)
        s = np.where(res.t < ts, v * res.t - MU * G * res.t**2 / 2, dist)
        err = np.max(np.abs(res.q[:, :2] - np.stack([s * vx / v, s * vy / v], 1)))
        out.append(f"h = {h}: path {err:.1e}, work {abs(res.work.sum() + v * v / 2):.1e}")
    return "; ".join(out)


def incline(backend: str, angle: float, v0, stops: bool) -> list[float]:
    if stops:
        sol, ts, q_stop = incline_reference(angle, *v0)
    else:
        from scipy.integrate import solve_ivp

        ca, sa = math.cos(angle), math.sin(angle)

        def rhs(t, s):
            speed = math.hypot(s[2], s[3])
            return [s[2], s[3], -MU * G * ca * s[2] / speed, -G * sa - MU * G * ca * s[3] / speed]

        sol = solve_ivp(
            rhs, (0.0, 1.0), [0.0, 0.0, *v0], method="DOP853", rtol=1e-13, atol=1e-15, dense_output=True
        ).sol
        ts, q_stop = math.inf, None
    errs = []
    for h in (0.02, 0.01, 0.005):
        res = sim("puck", backend).simulate(
            q0=[0.0, 0.0, 0.0], v0=[*v0, 0.0], h=h, t_end=1.0, params={"a": angle}
        )
        exact = np.array([sol(t)[:2] if t < ts else q_stop for t in res.t])
        errs.append(float(np.max(np.abs(res.q[:, :2] - exact))))
    return errs


def fmt(errs: list[float]) -> str:
    orders = [math.log2(a / b) for a, b in zip(errs, errs[1:])]
    return ", ".join(f"{e:.2e}" for e in errs) + "  (orders " + ", ".join(f"{o:.2f}" for o in orders) + ")"


def frozen_aim(self, cones, q, u, tau):
    """``_cone_aim`` without the midpoint prediction: the direction of the sliding at the segment's start."""
    _, grad, _ = self.k.rows(q, u)
    for f, p in cones:
        w = self._sliding(f, p, grad, u)
        if math.hypot(*w) > held_roots.SLIDE_EPS * (1.0 + float(np.max(np.abs(u)))):
            self._slip[[f, p]] = -self._mu_f[f] * w / math.hypot(*w)
    self._set_friction()


def ball(backend: str) -> str:
    out = []
    for spin in ((1.0, 4.0), (3.0, -20.0)):
        v0, w0 = np.array([2.0, -1.0, -math.sqrt(2 * G)]), np.array(spin)
        v1, w1, rolls = coulomb_ball(v0, w0)
        errs = []
        for h in (0.01, 0.005):
            res = sim("ball", backend).simulate(
                q0=[0.0, 0.0, 2.0, 0.0, 0.0], v0=[2.0, -1.0, 0.0, *spin], h=h, t_end=0.9
            )
            k = res.impacts[0].step + 2
            got = np.concatenate([res.p[k, :2] / MASS - v1[:2], res.p[k, 3:] / INERTIA - w1])
            errs.append(float(np.max(np.abs(got))))
        out.append(f"{'roll' if rolls else 'slip'} {errs[0]:.1e}, {errs[1]:.1e}")
    return "; ".join(out)


def agreement() -> str:
    scenes = [
        ("ball", dict(q0=[0.0, 0.0, 2.0, 0.0, 0.0], v0=[2.0, -1.0, 0.0, 3.0, -20.0], h=0.01, t_end=3.0)),
        (
            "puck",
            dict(q0=[0.0, 0.0, 0.0], v0=[1.5, 0.5, 0.0], h=0.01, t_end=1.0, params={"a": math.atan(MU / 2)}),
        ),
    ]
    out = []
    for name, run in scenes:
        a, b = (sim(name, bk).simulate(**run) for bk in ("casadi", "c"))
        out.append(
            f"{name}: {len(a.impacts)} impacts, max |q| diff {np.max(np.abs(a.q - b.q)):.1e}, "
            f"|p| {np.max(np.abs(a.p - b.p)):.1e}"
        )
    return "; ".join(out)


if __name__ == "__main__":
    for backend in ("c", "casadi"):
        print(f"[{backend}] straight stop: {straight(backend)}")
        curved = incline(backend, math.atan(MU / 2), (1.5, 0.5), True)
        print(f"[{backend}] curved stop on the incline: {fmt(curved)}")
        downhill = incline(backend, math.atan(1.5 * MU), (1.0, 0.0), False)
        print(f"[{backend}] turning downhill: {fmt(downhill)}")
        print(f"[{backend}] ball after its impact (h = 0.01, 0.005): {ball(backend)}")
    aim = sustained.SustainedSteps._cone_aim
    sustained.SustainedSteps._cone_aim = frozen_aim
    try:
        print(
            f"[casadi] curved stop, direction frozen at the segment start: "
            f"{fmt(incline('casadi', math.atan(MU / 2), (1.5, 0.5), True))}"
        )
    finally:
        sustained.SustainedSteps._cone_aim = aim
    print(f"C = CasADi: {agreement()}")
