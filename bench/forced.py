"""A forced scene side by side: the damped, driven impact oscillator (Lagrange-d'Alembert forces).

    .venv/bin/python bench/forced.py [--long 1000000] [--long-only]

``x'' + 0.3 x' + 4 x = 2 cos(1.7 t)``, a stop at ``x = 0.5`` with restitution 0.8, from rest, to
t = 10 (two impacts); the reference is the exact piecewise flow with impacts located on it by brentq
(``tests/forced_scenes.py``). Per method: the max error over a 0.01 grid of times against it, the
energy behaviour, and the wall time of one run (best of 3).

* vcigen, C and CasADi, trapezoid: ``h`` from 0.02 to 0.00125; C, lobatto3: ``h`` from 0.04 to 0.0025;
  energy: max ``|res.energy_balance()|``.
* scipy ``solve_ivp`` RK45 and DOP853 with event location (terminal event at the stop, restart with
  ``v -> -e v``), ``rtol`` 1e-4 .. 1e-10 (``atol = rtol * 1e-2``), dense output on the grid.
* MuJoCo (where it installs from PyPI; skipped with a message otherwise): a slide joint with
  stiffness 4 and damping 0.3, a motor driven by ``2 cos(1.7 t)``, the stop as a joint limit whose
  soft constraint is tuned to restitution 0.8 (``solreflimit = "0.005 0.071"``: a linear spring-damper
  with damping ratio 0.071 rebounds with e = 0.8), RK4, ``timestep`` 0.004 .. 0.0005.

Then ``--long`` steps of vcigen (C, h = 0.01, and over the same time at h/2) on the driven oscillator
without damping, the stop out of reach (the drive does work both ways), with damping and the stop out of
reach, and with damping and the stop, on the damped, driven pendulum against a wall (V not quadratic)
and on a damped, driven particle in polar coordinates (a mass matrix of q), free and inside a rim r <= 1.2
(e = 0.8), each with the trapezoid and the midpoint rule, and a particle on a rod (a bilateral constraint)
with V not quadratic, and with V linear against a wall: the balance's max, its drift (least-squares
slope times the run's length) and Σ|W|.
``--long-only`` runs only these. Writes ``bench/results/forced.csv``
(``forced_long.csv`` with ``--long-only``).
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np
import sympy as sp

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE))  # timing, also under python -m bench.forced

import forced_scenes as fs  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from timing import best_of  # noqa: E402

import vcigen  # noqa: E402

T_END = 10.0
GRID = np.round(np.arange(0.0, T_END + 1e-9, 0.01), 12)


# (backend, rule, h sweep): the trapezoid rule on both backends, the fourth-order lobatto3 in C (its own,
# coarser sweep: order 4)
VCIGEN_RUNS = (
    ("c", "trapezoid", (0.02, 0.01, 0.005, 0.0025, 0.00125)),
    ("casadi", "trapezoid", (0.02, 0.01, 0.005, 0.0025, 0.00125)),
    ("c", "lobatto3", (0.04, 0.02, 0.01, 0.005, 0.0025)),
)


def vcigen_rows(exact: np.ndarray) -> list[dict]:
    rows = []
    for backend, rule, hs in VCIGEN_RUNS:
        sim = vcigen.build(fs.driven_oscillator(), backend=backend, rule=rule)
        for h in hs:
            res, wall = best_of(sim.simulate, q0=[0.0], v0=[0.0], h=h, t_end=T_END)
            on = np.isin(np.round(res.t, 12), GRID)
            err = float(np.max(np.abs(res.q[on, 0] - exact[np.isin(GRID, np.round(res.t, 12))])))
            rows.append(
                {
                    "method": f"vcigen {backend}" + ("" if rule == "trapezoid" else f" {rule}"),
                    "setting": f"h={h}",
                    "error": err,
                    "wall": wall,
                    "impacts": len(res.impacts),
                    "energy": float(np.max(np.abs(res.energy_balance()))),
                }
            )
    return rows


def scipy_run(method: str, rtol: float):
    c, k, A, W, d, e = fs.DAMPING, fs.STIFFNESS, fs.AMPLITUDE, fs.DRIVE, fs.WALL, fs.REST

    def rhs(t, y):
        return [y[1], -c * y[1] - k * y[0] + A * math.cos(W * t)]

    def hit(t, y):
        return y[0] - d

    hit.terminal, hit.direction = True, 1.0
    t, y, out, hits = 0.0, [0.0, 0.0], np.empty(GRID.size), 0
    while True:
        sol = solve_ivp(
            rhs, (t, T_END), y, method=method, rtol=rtol, atol=rtol * 1e-2, events=hit, dense_output=True
        )
        end = sol.t_events[0][0] if sol.status == 1 else T_END
        sel = (GRID >= t) & (GRID <= end)
        out[sel] = sol.sol(GRID[sel])[0]
        if sol.status != 1:
            return out, hits
        hits += 1
        t, y = end, [d, -e * sol.y_events[0][0][1]]


def scipy_rows(exact: np.ndarray) -> list[dict]:
    rows = []
    for method in ("RK45", "DOP853"):
        for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
            (x, hits), wall = best_of(scipy_run, method, rtol)
            rows.append(
                {
                    "method": f"scipy {method}+events",
                    "setting": f"rtol={rtol:g}",
                    "error": float(np.max(np.abs(x - exact))),
                    "wall": wall,
                    "impacts": hits,
                    "energy": math.nan,
                }
            )
    return rows


MJCF = """<mujoco><option timestep="{h}" gravity="0 0 0" integrator="RK4"/>
<worldbody><body><joint name="x" type="slide" axis="1 0 0" stiffness="{k}" damping="{c}" limited="true"
 range="-100 {d}" solreflimit="0.005 0.071"/><geom type="sphere" size="0.01" mass="1"/></body></worldbody>
<actuator><motor joint="x" gear="1" ctrllimited="false"/></actuator></mujoco>"""


def mujoco_rows(exact: np.ndarray) -> list[dict]:
    try:
        import mujoco
    except ImportError as exc:
        print(f"mujoco: skipped ({exc}; pip install mujoco)")
        return []
    rows = []
    for h in (0.004, 0.002, 0.001, 0.0005):
        xml = MJCF.format(h=h, k=fs.STIFFNESS, c=fs.DAMPING, d=fs.WALL)
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        every = round(0.01 / h)

        def run(model, data, every):
            mujoco.mj_resetData(model, data)
            xs, hits, inside = np.empty(GRID.size), 0, False
            xs[0] = data.qpos[0]
            for i in range(1, GRID.size):
                for _ in range(every):
                    data.ctrl[0] = fs.AMPLITUDE * math.cos(fs.DRIVE * data.time)
                    mujoco.mj_step(model, data)
                    touching = data.qpos[0] > fs.WALL - 1e-9 or data.nefc > 0
                    hits += touching and not inside
                    inside = touching
                xs[i] = data.qpos[0]
            return xs, hits

        (x, hits), wall = best_of(run, model, data, every)
        rows.append(
            {
                "method": f"MuJoCo {mujoco.__version__} RK4",
                "setting": f"dt={h}",
                "error": float(np.max(np.abs(x - exact))),
                "wall": wall,
                "impacts": hits,
                "energy": math.nan,
            }
        )
    return rows


def _drive(t: float, x: float, v: float) -> float:
    """The oscillator's force: spring, damping and drive (what an engine applies each step)."""
    return -fs.STIFFNESS * x - fs.DAMPING * v + fs.AMPLITUDE * math.cos(fs.DRIVE * t)


def pymunk_rows(exact: np.ndarray) -> list[dict]:
    """pymunk: a point mass (radius 1e-3, no rotation) against a static segment at the stop, restitution
    0.8 (elasticities 0.8 and 1 multiply), the force applied before each step."""
    try:
        import pymunk
    except ImportError as exc:
        print(f"pymunk: skipped ({exc}; pip install pymunk)")
        return []
    rows = []
    radius = 1e-3
    for dt in (0.001, 0.0001):

        def run(dt):
            space = pymunk.Space()
            body = pymunk.Body(1.0, float("inf"))
            ball = pymunk.Circle(body, radius)
            ball.elasticity = fs.REST
            wall = pymunk.Segment(space.static_body, (fs.WALL + radius, -1), (fs.WALL + radius, 1), 0)
            wall.elasticity = 1.0
            space.add(body, ball, wall)
            xs, hits, inside, t = np.empty(GRID.size), 0, False, 0.0
            xs[0] = 0.0
            for i in range(1, GRID.size):
                for _ in range(round(0.01 / dt)):
                    body.force = (_drive(t, body.position.x, body.velocity.x), 0.0)
                    space.step(dt)
                    t += dt
                    touching = body.position.x >= fs.WALL - 1e-6
                    hits += touching and not inside
                    inside = touching
                xs[i] = body.position.x
            return xs, hits

        (x, hits), wall_time = best_of(run, dt)
        rows.append(
            {
                "method": f"pymunk {pymunk.version}",
                "setting": f"dt={dt}",
                "error": float(np.max(np.abs(x - exact))),
                "wall": wall_time,
                "impacts": hits,
                "energy": math.nan,
            }
        )
    return rows


def pybullet_rows(exact: np.ndarray) -> list[dict]:
    """PyBullet: a sphere (radius 0.01) against a static box face at the stop, restitution 0.8 (the
    product of the two bodies'), the force applied before each step."""
    try:
        import pybullet as pb
    except ImportError as exc:
        print(f"pybullet: skipped ({exc}; pip install pybullet)")
        return []
    rows = []
    radius = 0.01
    for dt in (0.001, 0.0001):

        def run(dt):
            cid = pb.connect(pb.DIRECT)
            pb.setGravity(0, 0, 0, physicsClientId=cid)
            pb.setTimeStep(dt, physicsClientId=cid)
            wall_shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.5, 1, 1], physicsClientId=cid)
            wall = pb.createMultiBody(
                0, wall_shape, basePosition=[fs.WALL + radius + 0.5, 0, 0], physicsClientId=cid
            )
            shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=radius, physicsClientId=cid)
            ball = pb.createMultiBody(1.0, shape, basePosition=[0, 0, 0], physicsClientId=cid)
            pb.changeDynamics(wall, -1, restitution=1.0, physicsClientId=cid)
            pb.changeDynamics(
                ball, -1, restitution=fs.REST, linearDamping=0, angularDamping=0, physicsClientId=cid
            )
            xs, hits, inside, t = np.empty(GRID.size), 0, False, 0.0
            xs[0] = 0.0
            for i in range(1, GRID.size):
                for _ in range(round(0.01 / dt)):
                    (x, _, _), _ = pb.getBasePositionAndOrientation(ball, physicsClientId=cid)
                    v = pb.getBaseVelocity(ball, physicsClientId=cid)[0][0]
                    pb.applyExternalForce(
                        ball, -1, [_drive(t, x, v), 0, 0], [x, 0, 0], pb.WORLD_FRAME, physicsClientId=cid
                    )
                    pb.stepSimulation(physicsClientId=cid)
                    t += dt
                    touching = x >= fs.WALL - 1e-4
                    hits += touching and not inside
                    inside = touching
                xs[i] = pb.getBasePositionAndOrientation(ball, physicsClientId=cid)[0][0]
            pb.disconnect(cid)
            return xs, hits

        (x, hits), wall_time = best_of(run, dt)
        rows.append(
            {
                "method": "PyBullet",
                "setting": f"dt={dt}",
                "error": float(np.max(np.abs(x - exact))),
                "wall": wall_time,
                "impacts": hits,
                "energy": math.nan,
            }
        )
    return rows


def _drift(bal: np.ndarray, t: np.ndarray) -> float:
    """Least-squares slope of the balance times the run's length."""
    return float(np.polyfit(t - t[0], bal, 1)[0] * (t[-1] - t[0]))


def long_rows(steps: int) -> list[dict]:
    oscillator = vcigen.build(fs.driven_oscillator(), backend="c")
    pendulum = {r: vcigen.build(fs.pendulum_wall(), backend="c", rule=r) for r in ("trapezoid", "midpoint")}
    polar = {r: vcigen.build(fs.polar_particle(), backend="c", rule=r) for r in ("trapezoid", "midpoint")}
    rules = ("trapezoid", "midpoint")
    rim = {r: vcigen.build(fs.polar_particle(rim=1.2), backend="c", rule=r) for r in rules}
    x, y = sp.symbols("x y")
    rod = vcigen.build(fs.rod_pendulum(potential=4 * y + 2 * x**2 * y + x**3), backend="c")
    rod_wall = vcigen.build(fs.rod_pendulum(wall=0.6), backend="c")
    rows = []
    for label, sim, params in (
        ("undamped drive, stop out of reach", oscillator, {"c": 0.0, "d": 100.0}),
        ("damped drive, stop out of reach", oscillator, {"d": 100.0}),
        ("damped drive, stop e = 0.8", oscillator, {}),
        ("pendulum, wall e = 0.8, trapezoid", pendulum["trapezoid"], {}),
        ("pendulum, wall e = 0.8, midpoint", pendulum["midpoint"], {}),
        ("polar particle M(q), trapezoid", polar["trapezoid"], {}),
        ("polar particle M(q), midpoint", polar["midpoint"], {}),
        ("polar M(q), rim e = 0.8, trapezoid", rim["trapezoid"], {}),
        ("polar M(q), rim e = 0.8, midpoint", rim["midpoint"], {}),
        ("rod (bilateral), V = 4y + 2x^2y + x^3", rod, {}),
        ("rod (bilateral), wall e = 0.8", rod_wall, {}),
    ):
        for h in (0.01, 0.005):  # the same span of time: steps at h, twice as many at h/2
            start = time.perf_counter()
            start0 = ([1.0, 0.0], [0.2, 0.9]) if sim.model.n == 2 else ([0.0], [0.0])
            if sim.model.constraint:
                start0 = ([0.0, -1.0], [0.5, 0.0])
            res = sim.simulate(q0=start0[0], v0=start0[1], h=h, t_end=steps * 0.01, params=params)
            wall = time.perf_counter() - start
            bal = res.energy_balance()
            rows.append(
                {
                    "method": f"vcigen c, {bal.size} steps",
                    "setting": f"{label}, h={h}",
                    "impacts": len(res.impacts),
                    "wall": wall,
                    "error": math.nan,
                    "energy": float(np.max(np.abs(bal))),
                    "drift": _drift(bal, res.t[1:]),
                    "work": float(np.sum(np.abs(res.work))),
                }
            )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--long", type=int, default=1_000_000, help="steps of the long balance runs")
    ap.add_argument("--long-only", action="store_true", help="only the long balance runs")
    a = ap.parse_args()
    rows = []
    if not a.long_only:
        exact = fs.driven_exact_grid(0.0, 0.0, GRID)
        rows = vcigen_rows(exact) + scipy_rows(exact) + mujoco_rows(exact) + pymunk_rows(exact)
        rows += pybullet_rows(exact)
    rows += long_rows(a.long)
    print(
        f"{'method':34s} {'setting':34s} {'impacts':>7s} {'max error':>10s} {'wall [ms]':>10s} {'energy':>9s}"
    )
    for r in rows:
        extra = f"  drift {r['drift']:.1e}, sum|W| {r['work']:.4g}" if "drift" in r else ""
        print(
            f"{r['method']:34s} {r['setting']:34s} {r['impacts']:7d} {r['error']:10.2e} "
            f"{1e3 * r['wall']:10.3f}"
            f" {r['energy']:9.1e}{extra}"
        )
    out = HERE / "results" / ("forced_long.csv" if a.long_only else "forced.csv")
    out.parent.mkdir(exist_ok=True)
    keys = ["method", "setting", "impacts", "error", "wall", "energy", "drift", "work"]
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in keys})
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
