"""A frictional scene side by side: a block sliding to a stop on a rough floor (Coulomb friction).

    .venv/bin/python bench/friction.py

A unit block launched at v = 2 along a level floor, mu = 0.4, g = 9.81: the closed form stops it at
t* = v / (mu g) = 0.5097 after d = v^2 / (2 mu g) = 0.5097 and keeps it there. Per method: the error of the
stopping distance (position at t = 1.5 against d), the largest |x(t) - x_exact(t)| on a 0.01 grid, the
energy left at t = 1.5 (0 exactly), and the wall time of one run (best of 3).

* vcigen, C and CasADi (``Model(friction={"floor": (mu, x)})``: the floor held as a constraint, stick and
  slip with the stop located inside the step), h = 0.01 and 0.001.
* MuJoCo (a 0.1 m box on a plane, condim 3, friction 0.4, default soft contact, ``timestep`` 0.001 and
  0.0001), pymunk (a box on a static segment, friction 0.4 each, 1 / dt substeps), PyBullet (a box on a
  plane, lateral friction 0.4 each), each where it installs from PyPI; skipped with a message otherwise.
Writes ``bench/results/friction.csv``.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import sympy as sp
from timing import best_of

import vcigen

V, MU, G, T_END = 2.0, 0.4, 9.81, 1.5
GRID = np.round(np.arange(0.0, T_END + 1e-9, 0.01), 12)
STOP = V / (MU * G)
DIST = V**2 / (2 * MU * G)
EXACT = np.where(GRID < STOP, V * GRID - MU * G * GRID**2 / 2, DIST)
HERE = Path(__file__).resolve().parent


def row(method, setting, xs, vs, wall):
    return {
        "method": method,
        "setting": setting,
        "stop_error": abs(xs[-1] - DIST),
        "max_error": float(np.max(np.abs(xs - EXACT))),
        "energy_left": 0.5 * vs[-1] ** 2,
        "wall": wall,
    }


def vcigen_rows() -> list[dict]:
    x, y, xd, yd = sp.symbols("x y xd yd")
    model = vcigen.Model(
        name="bench_block",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y},
        friction={"floor": (MU, x)},
    )
    out = []
    for backend, rule in (("c", "trapezoid"), ("casadi", "trapezoid"), ("c", "lobatto3")):
        name = f"vcigen {backend}" + ("" if rule == "trapezoid" else f" {rule}")
        try:
            sim = vcigen.build(model, backend=backend, rule=rule)
        except ValueError as exc:  # lobatto3 has no friction (nor sustained contact) yet: said, not silent
            print(f"{name}: skipped ({exc})")
            continue
        for h in (0.01, 0.001):
            res, wall = best_of(sim.simulate, [0.0, 0.0], [V, 0.0], h, T_END)
            on = np.isin(np.round(res.t, 12), GRID)
            out.append(row(name, f"h={h}", res.q[on, 0], res.p[on, 0], wall))
    return out


def mujoco_rows() -> list[dict]:
    try:
        import mujoco
    except ImportError as exc:
        print(f"mujoco: skipped ({exc})")
        return []
    out = []
    for dt in (0.001, 0.0001):
        xml = f"""<mujoco><option timestep="{dt}" gravity="0 0 -{G}"/><worldbody>
<geom type="plane" size="5 5 0.1" friction="{MU} 0 0"/>
<body pos="0 0 0.05"><freejoint/><geom type="box" size="0.05 0.05 0.05" mass="1" friction="{MU} 0 0"/></body>
</worldbody></mujoco>"""
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        every = round(0.01 / dt)

        def run(model, data, every):
            mujoco.mj_resetData(model, data)
            data.qvel[0] = V
            xs, vs = [0.0], [V]
            for _ in range(GRID.size - 1):
                for _ in range(every):
                    mujoco.mj_step(model, data)
                xs.append(data.qpos[0])
                vs.append(data.qvel[0])
            return np.array(xs), np.array(vs)

        (xs, vs), wall = best_of(run, model, data, every)
        out.append(row(f"MuJoCo {mujoco.__version__}", f"dt={dt}", xs, vs, wall))
    return out


def pymunk_rows() -> list[dict]:
    try:
        import pymunk
    except ImportError as exc:
        print(f"pymunk: skipped ({exc})")
        return []
    out = []
    for dt in (0.001, 0.0001):

        def run(dt):
            space = pymunk.Space()
            space.gravity = (0, -G)
            floor = pymunk.Segment(space.static_body, (-10, 0), (10, 0), 0)
            floor.friction = MU
            body = pymunk.Body(1.0, pymunk.moment_for_box(1.0, (0.1, 0.1)))
            body.position = (0, 0.05)
            box = pymunk.Poly.create_box(body, (0.1, 0.1), 0)
            box.friction = 1.0  # pymunk multiplies the two: 0.4 x 1
            space.add(body, box, floor)
            body.velocity = (V, 0)
            xs, vs = [0.0], [V]
            for _ in range(GRID.size - 1):
                for _ in range(round(0.01 / dt)):
                    space.step(dt)
                xs.append(body.position.x)
                vs.append(body.velocity.x)
            return np.array(xs), np.array(vs)

        (xs, vs), wall = best_of(run, dt)
        out.append(row(f"pymunk {pymunk.version}", f"dt={dt}", xs, vs, wall))
    return out


def pybullet_rows() -> list[dict]:
    try:
        import pybullet as pb
    except ImportError as exc:
        print(f"pybullet: skipped ({exc})")
        return []
    out = []
    for dt in (0.001, 0.0001):

        def run(dt):
            cid = pb.connect(pb.DIRECT)
            pb.setGravity(0, 0, -G, physicsClientId=cid)
            pb.setTimeStep(dt, physicsClientId=cid)
            plane = pb.createMultiBody(
                0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid), physicsClientId=cid
            )
            shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.05, 0.05, 0.05], physicsClientId=cid)
            box = pb.createMultiBody(1.0, shape, basePosition=[0, 0, 0.05], physicsClientId=cid)
            for b in (plane, box):
                pb.changeDynamics(b, -1, lateralFriction=math.sqrt(MU), restitution=0.0, physicsClientId=cid)
            pb.resetBaseVelocity(box, [V, 0, 0], physicsClientId=cid)
            xs, vs = [0.0], [V]
            for _ in range(GRID.size - 1):
                for _ in range(round(0.01 / dt)):
                    pb.stepSimulation(physicsClientId=cid)
                xs.append(pb.getBasePositionAndOrientation(box, physicsClientId=cid)[0][0])
                vs.append(pb.getBaseVelocity(box, physicsClientId=cid)[0][0])
            pb.disconnect(cid)
            return np.array(xs), np.array(vs)

        (xs, vs), wall = best_of(run, dt)
        out.append(row("PyBullet", f"dt={dt}", xs, vs, wall))
    return out


def main() -> None:
    rows = vcigen_rows() + mujoco_rows() + pymunk_rows() + pybullet_rows()
    print(
        f"{'method':18s} {'setting':10s} {'|x(end) - d|':>13s} {'max |x - x*|':>13s} "
        f"{'KE left':>10s} {'wall [ms]':>10s}"
    )
    for r in rows:
        print(
            f"{r['method']:18s} {r['setting']:10s} {r['stop_error']:13.2e} {r['max_error']:13.2e} "
            f"{r['energy_left']:10.1e} {1e3 * r['wall']:10.2f}"
        )
    out = HERE / "results" / "friction.csv"
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
