"""The latency floor of a held step on a curved row: one sqrt and the projection against a free step.

    .venv/bin/python -m bench.held_floor [--steps 200000] [--repeats 9]

A held step on a circle feeds the next one through ``p_k -> a -> sqrt -> q_k+1 -> projection -> p_k+1``: the
steps cannot overlap as the free step's do (its chain is ``p + const``, ``q + h v``). This times, in small C
loops compiled here with the generated code's flags (``-O2``, no ``-march``), on the bowl of
``bench.sustained_cost`` (unit mass, ``r = 1``, g = 9.81, h = 1e-3, from rest at ``(0.6, -0.8)``):

* ``free``: the explicit free grid step as ``<model>_glide`` has it (v, q, p, E_d, phi with its ``sqrt``,
  the slope with its division, the pre-test, the stores);
* ``sqrt``: a chain of ``x = sqrt(x x + c)`` alone, one a step (the sqrt's latency and one multiply-add);
* ``chain``: the closed held step's loop-carried chain alone (``held.closed_routines``: ``a``, ``B/2``,
  ``D``, ``sqrt``, ``q1``, ``v``, ``p+``, the projection onto ``grad F(q1)``), nothing stored, no test;
* ``step``: that chain with what a held step does besides (E_d, the force, the residual, the tests, the
  stores of q, p, E, F).

Each is the best of ``--repeats``, in ns per step, with its ratio to ``free`` (CPU time of the loop, on a
machine loaded by other sessions the figure to read).
"""

from __future__ import annotations

import argparse
import ctypes
import subprocess
import tempfile
import time
from pathlib import Path

SRC = r"""
#include <math.h>
#define G 9.81
static double Q[2 * %(steps)d], P[2 * %(steps)d], E[%(steps)d], F[%(steps)d];
#define STORE Q[2 * s] = x; Q[2 * s + 1] = y; P[2 * s] = px; P[2 * s + 1] = py; E[s] = e; sum += e;

long vc_free(double h, long n)
{
    double k0 = -0.5 * G * h, k1 = -G * h, x = 0.0, y = 0.0, px = 1.0, py = 0.0, d = 0.0, sum = 0.0;
    long s;
    for (s = 0; s < n; ++s) {
        const double vy = py + k0, nx = x + h * px, ny = y + h * vy, npy = py + k1;
        const double e = 0.5 * px * px + 0.5 * vy * vy + G * y - k0 * vy;
        const double t = sqrt(nx * nx + ny * ny), phi = 1e9 - t, d1 = -h * (px * nx + npy * ny) / t;
        if ((phi < -1e-9) | ((d < 0) & (d1 > 0))) {
            break;
        }
        x = nx;
        y = ny;
        py = npy;
        d = d1;
        STORE
    }
    return s + (sum != sum);
}

double vc_sqrt(long n)
{
    double x = 0.3;
    long s;
    for (s = 0; s < n; ++s) {
        x = sqrt(x * x + 0.5);
    }
    return x;
}

/* held.closed_routines on the circle |q| = 1, unit mass: nu = sqrt((B/2)^2 - A C) - B/2, A = 4 h^2 */
#define STEP_CHAIN \
    const double vx = px, vy = py + k0, ax = x + h * vx, ay = y + h * vy; \
    const double beta = (2.0 * h * x) * ax + (2.0 * h * y) * ay, cc = ax * ax + ay * ay - 1.0; \
    const double dd = beta * beta - a0 * cc, nu = sqrt(dd) - beta; \
    const double nx = ax + (2.0 * h * x / a0) * nu, ny = ay + (2.0 * h * y / a0) * nu; \
    const double wx = vx + (2.0 * x / a0) * nu, wy = vy + (2.0 * y / a0) * nu; \
    const double ppx = wx, ppy = wy + k0, l1 = (ppx * nx + ppy * ny) * (-0.5); \
    const double npx = ppx + (2.0 * nx) * l1, npy = ppy + (2.0 * ny) * l1;

double vc_chain(double h, long n)
{
    double k0 = -0.5 * G * h, a0 = 4.0 * h * h, x = 0.6, y = -0.8, px = 0.0, py = 0.0;
    long s;
    for (s = 0; s < n; ++s) {
        STEP_CHAIN
        x = nx;
        y = ny;
        px = npx;
        py = npy;
    }
    return x + y + px + py;
}

long vc_step(double h, long n)
{
    double k0 = -0.5 * G * h, a0 = 4.0 * h * h, x = 0.6, y = -0.8, px = 0.0, py = 0.0, sum = 0.0;
    long s;
    for (s = 0; s < n; ++s) {
        STEP_CHAIN
        const double e = 0.5 * wx * wx + 0.5 * wy * wy + G * y - k0 * wy;
        const double f = 2.0 * ((2.0 * ny) * (-G) + 2.0 * (npx * npx + npy * npy)) * 0.25;
        const double res = (nx * nx + ny * ny - 1.0) * (-0.5), tot = e + f + nx + ny + npx + npy;
        if (!(beta > 0.0) | !(dd >= 0.0) | !(fabs(res) <= 1e-10) | (f < -1e-12 * (1.0 + fabs(f)))
            | !isfinite(tot)) {
            break;
        }
        x = nx;
        y = ny;
        px = npx;
        py = npy;
        STORE
        F[s] = (-2.0 * nu / a0 - 2.0 * l1) / h;
    }
    return s + (sum != sum);
}
"""


def _lib(steps: int) -> ctypes.CDLL:
    tmp = Path(tempfile.mkdtemp(prefix="vcigen_held_floor_"))
    (tmp / "floor.c").write_text(SRC % {"steps": steps})
    subprocess.run(["cc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared",
                    str(tmp / "floor.c"), "-o", str(tmp / "floor.so"), "-lm"], check=True)  # fmt: skip
    lib = ctypes.CDLL(str(tmp / "floor.so"))
    for name, res, args in (
        ("vc_free", ctypes.c_long, [ctypes.c_double, ctypes.c_long]),
        ("vc_sqrt", ctypes.c_double, [ctypes.c_long]),
        ("vc_chain", ctypes.c_double, [ctypes.c_double, ctypes.c_long]),
        ("vc_step", ctypes.c_long, [ctypes.c_double, ctypes.c_long]),
    ):
        getattr(lib, name).restype = res
        getattr(lib, name).argtypes = args
    return lib


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=9)
    a = ap.parse_args(argv)
    lib = _lib(a.steps)
    h, n = 1e-3, a.steps
    runs = {
        "free": lambda: lib.vc_free(h, n),
        "sqrt": lambda: lib.vc_sqrt(n),
        "chain": lambda: lib.vc_chain(h, n),
        "step": lambda: lib.vc_step(h, n),
    }
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(a.repeats):
        for name, run in runs.items():
            t = time.thread_time()
            out = run()
            spent = time.thread_time() - t
            if name in ("free", "step"):
                assert out == n, (name, out)  # every step taken
            best[name] = min(best[name], spent / n * 1e9)
    print(f"{'loop':<6} {'ns/step':>8} {'/ free':>7}   (CPU time, best of {a.repeats}, h = {h:g})")
    for name, ns in best.items():
        print(f"{name:<6} {ns:>8.2f} {ns / best['free']:>7.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
