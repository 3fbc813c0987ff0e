"""Cost of a held step on a curved row that moves, at several steps h, against a free step (C, CPU time).

    .venv/bin/python -m bench.held_curved [--repeats 7] [--scenes bowl dome sphere spring ellipse]

Scenes (best of ``--repeats`` of each run, held and free interleaved; CPU time of the C loop as in
``bench.sustained_cost``, whose helpers it uses):

* ``bowl``: the bowl of ``bench.sustained_cost`` (a particle sliding inside a circle ``r - |q|``, released at
  rest at ``(0.6, -0.8)``), 2e5 steps at h = 1e-3 and 1e-2; free: ``r = 1e9``, ``q0 = 0``, ``v0 = (1, 0)``.
* ``dome``: ``examples/contact/slide_off_dome.py``'s model (``|q| - 1 >= 0``) from its top with
  ``v0 = (0.1, 0)``, 5e4 steps at h = 1e-5 (held throughout: it lifts off at t = 1.27); free: from
  ``(0, 10)``, the same ``v0``.

Both rows are circles in the plane under gravity: every held step is the rotation of :mod:`vcigen.held_circle`
(``<model>_held_circle_loop``: ``(omega, arg)`` carried, one multiply-add between two ``sqrt`` on the state's
chain); before it, the closed step of ``held.closed_forms`` (stop 21: 5.7-5.9x) and, before that, the held
Newton with its line start.

Other curved rows, 1e5 steps at h = 1e-3 (free: far from the row, ``r = 1e9``):

* ``sphere``: the bowl in three coordinates (``r - |q|``, released at ``(0.6, 0, -0.8)`` with ``v0 = (0, 0.5,
  0)``): the closed step (``held.closed_forms``; the generated rotation is the plane's); and
  ``bench/handwritten/sphere_rot.c`` (stop 45), its held step written by hand as a rotation in three
  coordinates (``q1 = s q + h w``, ``w`` and ``|w|^2`` carried as polynomials in the root, one multiply-add
  from one ``sqrt`` to the next), checked against the generated run (q, p and the impulse to 1e-9): at the
  shipped flags it is as slow as the generated closed step (~350 instructions a step: without FMA and
  three-operand forms the three coordinates' arithmetic, not the chain, bounds it), so it is not generated;
* ``spring``: the bowl under a spring to its centre besides gravity (stiffness 3): a rotation (the force is
  affine in ``q``; stop 23, before it the closed step: 3.0-3.3x);
* ``ellipse``: ``r - sqrt(x^2 / 4 + y^2)`` from ``(1.2, -0.8)`` at rest: a quadric's closed step
  (``held.closed_forms``, not ``fixed``: ``A`` and the projection's ``W`` vary on the row, ``Hess F``
  definite), ``<model>_held_closed_loop``; before stop 24 the held Newton (9-10x);
* ``ellipse``, hand-written (``HANDS``): ``bench/handwritten/ellipse.c``, the same held step written for
  this row alone (the fewest operations we could write, the next line's start one multiply-add after the
  root), timed in the same loop and checked against the generated run (q, p to 1e-9): the practical limit of
  the generated loop; and ``bench/handwritten/ellipse_poly.c`` (stop 34), the same with the next step's
  quadratic formed as polynomials in the root (a shorter chain to the next ``sqrt``), alike; and
  ``bench/handwritten/ellipse_chain.c`` (stop 39), that form's state's chain alone (no projection, force,
  ``E_d`` or tests; its ``Q`` checked, its ``P`` is ``p+``): a floor for any held step with that chain;
* ``valley``: a particle in the parabola ``y >= x^2 / 2``, from ``(0.8, 0.32)`` at rest, through its vertex:
  a quadric's closed step whose ``Hess F`` is not definite (its root divides by ``B + sqrt(D)``); free: from
  ``(0, 1e6)``.
"""

from __future__ import annotations

import argparse
import ctypes
import math
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen
from bench.sustained_cost import G, bowl, cpu_clock, keep_heap

HERE = Path(__file__).resolve().parent


def _planar_bowl(name: str, row, potential) -> vcigen.Model:
    """A particle inside the closed curve ``row(x, y) = r`` under gravity and ``potential(x, y)``."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    r = sp.Symbol("r", positive=True)
    return vcigen.Model(
        name=name,
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y - potential(x, y),
        contacts={"bowl": r - row(x, y)},
        params={r: 1.0},
    )


def spring() -> vcigen.Model:
    return _planar_bowl("hcv_spring", lambda x, y: sp.sqrt(x**2 + y**2), lambda x, y: 3 * (x**2 + y**2) / 2)


def ellipse() -> vcigen.Model:
    return _planar_bowl("hcv_ellipse", lambda x, y: sp.sqrt(x**2 / 4 + y**2), lambda x, y: 0)


def valley() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    return vcigen.Model(
        name="hcv_valley",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"valley": y - x**2 / 2},
    )


def sphere() -> vcigen.Model:
    x, y, z, xd, yd, zd = sp.symbols("x y z xd yd zd")
    r = sp.Symbol("r", positive=True)
    return vcigen.Model(
        name="hcv_sphere",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 - G * z,
        contacts={"bowl": r - sp.sqrt(x**2 + y**2 + z**2)},
        params={r: 1.0},
    )


def dome() -> vcigen.Model:
    sys.path.insert(0, str(HERE.parent / "examples" / "contact"))
    import slide_off_dome

    return slide_off_dome.model()


BOWL_HELD = ([0.6, -0.8], [0.0, 0.0], {"r": 1.0})
BOWL_FREE = ([0.0, 0.0], [1.0, 0.0], {"r": 1e9})
RUNS = [  # name, model, h, steps, held (q0, v0, params), free (q0, v0, params)
    ("bowl", bowl, 1e-3, 200_000, BOWL_HELD, BOWL_FREE),
    ("bowl", bowl, 1e-2, 200_000, BOWL_HELD, BOWL_FREE),
    ("dome", dome, 1e-5, 50_000, ([0.0, 1.0], [0.1, 0.0], None), ([0.0, 10.0], [0.1, 0.0], None)),
    (
        "sphere",
        sphere,
        1e-3,
        100_000,
        ([0.6, 0.0, -0.8], [0.0, 0.5, 0.0], {"r": 1.0}),
        ([0.0] * 3, [1.0, 0, 0], {"r": 1e9}),
    ),
    ("spring", spring, 1e-3, 100_000, BOWL_HELD, BOWL_FREE),
    ("ellipse", ellipse, 1e-3, 100_000, ([1.2, -0.8], [0.0, 0.0], {"r": 1.0}), BOWL_FREE),
    ("valley", valley, 1e-3, 100_000, ([0.8, 0.32], [0.0, 0.0], None), ([0.0, 1e6], [1.0, 0.0], None)),
]


def handwritten(source: str = "ellipse.c"):
    """``run(q0, p0, h, steps) -> (seconds of CPU time, Q, P, F)`` over ``bench/handwritten/<source>`` (r = 1,
    the row of its scene: ``ellipse*.c`` the ``ellipse``'s, ``sphere*.c`` the ``sphere``'s), compiled with the
    shipped flags."""
    stem = Path(source).stem.split("_")[0]
    dim = 3 if stem == "sphere" else 2
    out = Path(tempfile.mkdtemp(prefix="vcigen-hw-")) / f"libhw_{Path(source).stem}.so"
    flags = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared"]
    subprocess.run(["cc", *flags, "-o", str(out), str(HERE / "handwritten" / source), "-lm"], check=True)
    f = getattr(ctypes.CDLL(str(out)), f"hw_{stem}_run")
    f.restype = ctypes.c_long
    f.argtypes = [ctypes.c_void_p] * 2 + [ctypes.c_double] * 3 + [ctypes.c_long] + [ctypes.c_void_p] * 4

    def run(q0, p0, h: float, steps: int):
        q0, p0 = np.array(q0, float), np.array(p0, float)
        Q, P, E, F = np.empty((steps, dim)), np.empty((steps, dim)), np.empty(steps), np.empty(steps)
        t = time.thread_time()
        done = f(q0.ctypes.data, p0.ctypes.data, h, 1.0, G, steps, *(a.ctypes.data for a in (Q, P, E, F)))
        spent = time.thread_time() - t
        assert done == steps, (f"hand-written {source} stopped at", done)
        return spent, Q, P, F

    return run


def apart(scene: str, label: str, res: vcigen.Result, Q, P, F) -> float:
    """How far a hand-written run (``Q``, ``P``, ``F`` of ``handwritten``) is from the generated run ``res``:
    the largest difference of q, of p (not the chain alone's: its ``P`` is ``p+``) and of the sphere's impulse
    over h (``res.contact_force``; the ellipse's is on ``grad F / 2``)."""
    out = [np.abs(Q - res.q[1:]).max()]
    out += [np.abs(P - res.p[1:]).max()] if label != "chain" else []
    out += [np.abs(F - res.contact_force[:, 0]).max()] if scene == "sphere" else []
    return float(max(out))


# per scene, the hand-written steps timed beside it: label -> source (bench/handwritten/)
HANDS = {
    "ellipse": {"hand": "ellipse.c", "poly": "ellipse_poly.c", "chain": "ellipse_chain.c"},
    "sphere": {"rot": "sphere_rot.c"},
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    names = list(dict.fromkeys(name for name, *_ in RUNS))
    ap.add_argument("--scenes", nargs="+", choices=names, default=names)
    a = ap.parse_args(argv)
    runs = [run for run in RUNS if run[0] in a.scenes]
    warnings.simplefilter("ignore", RuntimeWarning)
    keep_heap()
    sims = {name: vcigen.build(model(), backend="c") for name, model, *_ in runs}
    clocks = {name: cpu_clock(sim) for name, sim in sims.items()}
    hands = {
        name: {key: handwritten(src) for key, src in HANDS[name].items()} for name in HANDS if name in sims
    }
    best = {}
    for _ in range(a.repeats):
        for name, _, h, steps, held, free in runs:
            for kind, (q0, v0, params) in (("held", held), ("free", free)):
                t0 = clocks[name][0]
                res = sims[name].simulate(q0, v0, h, t_end=steps * h, params=params)
                spent = clocks[name][0] - t0
                ok = res.active.all() if kind == "held" else not res.active.any()
                assert ok and res.t.size == steps + 1, (name, h, kind)
                best[name, h, kind] = min(best.get((name, h, kind), math.inf), spent / steps * 1e9)
                for key, hand in hands.get(name, {}).items() if kind == "held" else ():
                    spent, Q, P, F = hand(q0, v0, h, steps)  # the hand-written steps, alike
                    assert apart(name, key, res, Q, P, F) < 1e-9, (name, key)
                    best[name, h, key] = min(best.get((name, h, key), math.inf), spent / steps * 1e9)
    print(f"{'scene':<7} {'h':>7} {'held ns':>8} {'free ns':>8} {'ratio':>6}   (CPU time of the C loop)")
    for name, _, h, *_ in runs:
        held_ns, free_ns = best[name, h, "held"], best[name, h, "free"]
        print(f"{name:<7} {h:>7.0e} {held_ns:>8.1f} {free_ns:>8.1f} {held_ns / free_ns:>6.2f}")
        for key, source in HANDS.get(name, {}).items():
            if (name, h, key) in best:
                hand_ns = best[name, h, key]
                print(
                    f"{'  ' + key:<7} {h:>7.0e} {hand_ns:>8.1f} {free_ns:>8.1f} {hand_ns / free_ns:>6.2f}"
                    f"   (bench/handwritten/{source}; generated / hand-written {held_ns / hand_ns:.2f})"
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
