"""The latency floor of a held step on a curved row, and exact variants of it, against a free step.

    .venv/bin/python -m bench.held_floor [--steps 200000] [--repeats 9] [--check]

A held step on a circle feeds the next one through ``p_k -> a -> sqrt -> q_k+1 -> projection -> p_k+1``: the
steps cannot overlap as the free step's do (its chain is ``p + const``, ``q + h v``). This times, in small C
loops compiled here with the generated code's flags (``-O2``, no ``-march``), on the bowl of
``bench.sustained_cost`` (unit mass, ``r = 1``, g = 9.81, h = 1e-3, from rest at ``(0.6, -0.8)``):

* ``free``: the explicit free grid step as ``<model>_glide`` has it (v, q, p, E_d, phi with its ``sqrt``,
  the slope with its division, the pre-test, the stores of q, p, E_d);
* ``sqrt``: a chain of ``x = sqrt(x x + c)`` alone, one a step (the sqrt's latency and one multiply-add);
* ``chain``: the closed held step's loop-carried chain alone (``held.closed_routines``: ``a``, ``B/2``,
  ``D``, ``sqrt``, ``q1``, ``v``, ``p+``, the projection onto ``grad F(q1)``), nothing stored, no test;
* ``step``: that chain with what a held step does besides (E_d, the force, the impulse, the residual, the
  tests, the stores of q, p, E_d and the impulse): today's generated step, written by hand;
* ``pipe_chain``, ``pipe``: the same algebra reduced modulo the circle ``|q| = 1``, the tangency ``q . p = 0``
  and ``s^2 = 1 - X`` (a Groebner basis): ``D = 4 h^2 s^2``, ``s^2 = 1 - h^2 |w|^2`` with ``w`` the
  tangential part of ``v0``, ``q1 = h w + s q``; the next step's ``sqrt`` argument is carried as
  ``a0(y, p) + a1(y, p) s``, so that the chain from one ``sqrt`` to the next is a multiply-add. ``pipe``
  takes the predicted ``|q1|^2 - 1 = e0 + e1 s`` (exact: ``s^2`` is the argument) off that argument: without
  it the modulus random-walks (``pipe_raw`` in ``--check``);
* ``rot_chain``, ``rot``: the circle's step as a rotation: ``p = pi (-y, x)`` (tangent by construction),
  ``omega = pi + k0 x`` the tangential speed of ``v0``, ``z1 = z (s + i h omega)`` with
  ``s = sqrt(1 - h^2 omega^2)``, ``pi1 = omega + k0 x1`` (the projection of ``p+`` onto the tangent at
  ``q1``: ``v . t1 = omega`` exactly on the circle); ``omega1 = omega + 2 k0 x1`` is linear in ``s``, so the
  next argument ``1/|z1|^2 - h^2 omega1^2`` is ``A + B s`` with ``A``, ``B`` from the step's start (the
  modulus ``|z1|^2 = |z|^2 (s^2 + h^2 omega^2)`` taken off it).

Each is the best of ``--repeats``, in ns per step, with its ratio to ``free`` (CPU time of the loop, on a
machine loaded by other sessions the figure to read). ``--check`` compares each exact variant with ``step``
(today's algebra): over 1000 steps from the bowl's start and from the bottom at speed 3 (h = 1e-3, 1e-2,
3e-2), and on a dome (outside the circle, from the top at speed 0.1 until the lift-off test refuses a step),
the largest difference of q, p, E_d and the impulse and the step where each stops; then 10^6 steps on the
bowl at each h: max ``||q|^2 - 1|``, max ``|q . p|`` and the end state's distance to ``step``'s.
"""

from __future__ import annotations

import argparse
import ctypes
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

SRC = r"""
#include <math.h>
#define G 9.81
#define INLINE static inline __attribute__((always_inline))
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

/* the tests of held.closed_step and the impulse (Lam + Lam') / h; side = 1 inside the circle (the bowl,
 * psi = 1 - |q|), -1 outside (a dome, psi = |q| - 1: its force and impulse change sign) */
#define TESTS(SLOPE, DISC) \
        const double f = side * 2.0 * ((2.0 * ny) * (-G) + 2.0 * (npx * npx + npy * npy)) * 0.25; \
        const double res = (nx * nx + ny * ny - 1.0) * (-0.5), tot = e + f + nx + ny + npx + npy; \
        if (!(SLOPE > 0.0) | !(DISC >= 0.0) | !(fabs(res) <= 1e-10) | (f < -1e-12 * (1.0 + fabs(f))) \
            | !isfinite(tot)) { \
            break; \
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

INLINE long step(double h, long n, double x, double y, double px, double py, double side)
{
    double k0 = -0.5 * G * h, a0 = 4.0 * h * h, sum = 0.0;
    long s;
    for (s = 0; s < n; ++s) {
        STEP_CHAIN
        const double e = 0.5 * wx * wx + 0.5 * wy * wy + G * y - k0 * wy;
        TESTS(beta, dd)
        x = nx;
        y = ny;
        px = npx;
        py = npy;
        STORE
        F[s] = side * (-2.0 * nu / a0 - 2.0 * l1) / h;
    }
    return s + (sum != sum);
}

/* pipe: the algebra above reduced modulo |q| = 1, q . p = 0 and s^2 = 1 - X; the argument of the next sqrt
 * carried as a0 + a1 s (a Groebner reduction, bench.held_floor's docstring) */
#define PIPE_CONSTS \
    const double k0 = -0.5 * G * h, ih = 1.0 / h, h2 = h * h, h3 = h2 * h, h4 = h3 * h; \
    const double cxx0 = -h2 - 4 * h4 * k0 * k0, cxx1 = 4 * h3 * k0, cyy0 = -h2 + 4 * h4 * k0 * k0; \
    const double cy0 = -2 * h2 * k0 + 8 * h4 * k0 * k0 * k0, cy1 = 8 * h3 * k0 * k0; \
    const double cy2 = -16 * h4 * k0 * k0 * k0; \
    const double c00 = 1.0 - 5 * h2 * k0 * k0 + 4 * h4 * k0 * k0 * k0 * k0, c01 = 4 * h3 * k0 * k0 * k0; \
    const double c02 = 5 * h2 * k0 * k0 - 12 * h4 * k0 * k0 * k0 * k0, c03 = -4 * h3 * k0 * k0 * k0; \
    const double c04 = 8 * h4 * k0 * k0 * k0 * k0, b0 = -4 * h2 * k0, b1 = 2 * h * k0, i2h2 = 0.5 / h2; \
    double argn; \
    { \
        const double c = k0 * y, tx = px - c * x, ty = py + k0 - c * y; \
        argn = 1.0 - h2 * (tx * tx + ty * ty); \
    }

#define PIPE_STEP \
        const double a0 = c00 + y * (c01 + y * (c02 + y * (c03 + y * c04))) + px * px * (cxx0 + cxx1 * y) \
            + py * py * (cyy0 + cxx1 * y) + py * (cy0 + y * (cy1 + y * cy2)); \
        const double a1 = b0 * (b1 * y - 1.0) * (k0 * y * y - k0 - py); \
        const double c = k0 * y, tx = px - c * x, ty = py + k0 - c * y, arg = argn, sq = sqrt(arg); \
        const double nx = h * tx + sq * x, ny = h * ty + sq * y, dm = (sq - 1.0) * ih; \
        const double wx = tx + dm * x, wy = ty + dm * y; \
        const double ppx = wx, ppy = wy + k0, l1 = ppx * nx + ppy * ny; \
        const double npx = ppx - nx * l1, npy = ppy - ny * l1;

#define PIPE_NEXT(CORRECT) \
        if (CORRECT) { /* |q1|^2 - 1 = e0 + e1 sq exactly (sq^2 = arg): taken off the next argument */ \
            const double e0 = h2 * (tx * tx + ty * ty) + arg * (x * x + y * y) - 1.0; \
            const double e1 = 2.0 * h * (x * tx + y * ty); \
            argn = (a0 - e0) + (a1 - e1) * sq; \
        } else { \
            argn = a0 + a1 * sq; \
        }

double vc_pipe_chain(double h, long n)
{
    double x = 0.6, y = -0.8, px = 0.0, py = 0.0;
    long s;
    PIPE_CONSTS
    (void)i2h2;
    for (s = 0; s < n; ++s) {
        PIPE_STEP
        PIPE_NEXT(0)
        x = nx;
        y = ny;
        px = npx;
        py = npy;
    }
    return x + y + px + py;
}

INLINE long pipe(double h, long n, double x, double y, double px, double py, double side, int correct)
{
    double sum = 0.0;
    long s;
    PIPE_CONSTS
    for (s = 0; s < n; ++s) {
        PIPE_STEP
        const double e = 0.5 * wx * wx + 0.5 * wy * wy + G * y - k0 * wy;
        TESTS(1.0 + h * c, arg)
        PIPE_NEXT(correct)
        x = nx;
        y = ny;
        px = npx;
        py = npy;
        STORE
        F[s] = side * (-2.0 * h * (sq - 1.0 - h * c) * i2h2 + l1) * ih;
    }
    return s + (sum != sum);
}


/* rot: z1 = z (s + i h omega); omega1 = omega + 2 k0 x1 = o0 + o1 s, so the next argument
 * 1/|z1|^2 - h^2 omega1^2 is A + B s (1/|z1|^2 to first order: 2 - |z|^2 (s^2 + h^2 omega^2)) */
#define ROT_CONSTS \
    const double k0 = -0.5 * G * h, ih = 1.0 / h, c2kh2 = 2.0 * k0 * h * h, tkh = 2.0 * k0 * h; \
    double om = (px * -y + py * x) + k0 * x, arg = 1.0 - h * h * om * om;

/* h omega1 = ho0 + ho1 s: ho0 = omega (h - 2 k0 h^2 y) (the factor of y first, off omega's chain),
 * ho1 = 2 k0 h x */
#define ROT_STEP \
        const double sq = sqrt(arg), hw = h * om; \
        const double nx = sq * x - hw * y, ny = sq * y + hw * x; \
        const double npi = om + k0 * nx; \
        const double ho0 = om * (h - c2kh2 * y), ho1 = tkh * x; \
        const double an = (2.0 - (x * x + y * y) * (arg + hw * hw) - ho1 * ho1 * arg) - ho0 * ho0; \
        const double bn = (-2.0 * ho1) * ho0;

double vc_rot_chain(double h, long n)
{
    double x = 0.6, y = -0.8, px = 0.0, py = 0.0;
    long s;
    ROT_CONSTS
    (void)ih;
    for (s = 0; s < n; ++s) {
        ROT_STEP
        arg = an + bn * sq;
        om = npi + k0 * nx;
        x = nx;
        y = ny;
    }
    return x + y + om;
}

INLINE long rot(double h, long n, double x, double y, double px, double py, double side)
{
    double sum = 0.0;
    long s;
    ROT_CONSTS
    const double ymax = -1.0 / (h * k0); /* the root holds (B > 0): 1 + h k0 y > 0 */
    for (s = 0; s < n; ++s) {
        ROT_STEP
        const double npx = -npi * ny, npy = npi * nx;
        const double vx = (nx - x) * ih, vy = (ny - y) * ih;
        const double e = 0.5 * vx * vx + 0.5 * vy * vy + G * y - k0 * vy;
        /* |p1|^2 = npi^2 |q1|^2: npi^2 to round-off */
        const double f = side * 2.0 * ((2.0 * ny) * (-G) + 2.0 * (npi * npi)) * 0.25;
        const double res = (nx * nx + ny * ny - 1.0) * (-0.5), tot = e + f + nx + ny + npx + npy;
        if (!(y < ymax) | !(arg >= 0.0) | !(fabs(res) <= 1e-10) | (f < -1e-12 * (1.0 + fabs(f)))
            | !isfinite(tot)) {
            break;
        }
        /* (Lam + Lam') / h from the momentum change J = p1 - p0 - (h/2)(f0 + f1) along n0 + n1 */
        F[s] = -side * ((npx - px) * (x + nx) + (npy - py + h * G) * (y + ny)) / ((1.0 + sq) * h);
        arg = an + bn * sq;
        om = npi + k0 * nx;
        x = nx;
        y = ny;
        px = npx;
        py = npy;
        STORE
    }
    return s + (sum != sum);
}

/* each stepper with its side a constant (as the generated code's signs are): the bowl's, and the dome's */
#define SIDES(NAME, CALL) \
    long vc_##NAME(double h, long n, double x, double y, double px, double py) { return CALL(1.0); } \
    long vc_##NAME##_dome(double h, long n, double x, double y, double px, double py) { return CALL(-1.0); }
#define STEP(SIDE) step(h, n, x, y, px, py, SIDE)
#define PIPE(SIDE) pipe(h, n, x, y, px, py, SIDE, 1)
#define PIPE_RAW(SIDE) pipe(h, n, x, y, px, py, SIDE, 0)
#define ROT(SIDE) rot(h, n, x, y, px, py, SIDE)
SIDES(step, STEP)
SIDES(pipe, PIPE)
SIDES(pipe_raw, PIPE_RAW)
SIDES(rot, ROT)

double *vc_out(int which)
{
    return which == 0 ? Q : which == 1 ? P : which == 2 ? E : F;
}
"""

H = 1e-3
STEPPERS = ("step", "pipe_raw", "pipe", "rot")


def _lib(steps: int) -> ctypes.CDLL:
    tmp = Path(tempfile.mkdtemp(prefix="vcigen_held_floor_"))
    (tmp / "floor.c").write_text(SRC % {"steps": steps})
    subprocess.run(["cc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared",
                    str(tmp / "floor.c"), "-o", str(tmp / "floor.so"), "-lm"], check=True)  # fmt: skip
    lib = ctypes.CDLL(str(tmp / "floor.so"))
    d, lg = ctypes.c_double, ctypes.c_long
    lib.vc_free.restype, lib.vc_free.argtypes = lg, [d, lg]
    lib.vc_sqrt.restype, lib.vc_sqrt.argtypes = d, [lg]
    for name in ("vc_chain", "vc_pipe_chain", "vc_rot_chain"):
        getattr(lib, name).restype, getattr(lib, name).argtypes = d, [d, lg]
    for name in STEPPERS:
        for fn in (getattr(lib, f"vc_{name}"), getattr(lib, f"vc_{name}_dome")):
            fn.restype, fn.argtypes = lg, [d, lg, d, d, d, d]
    lib.vc_out.restype, lib.vc_out.argtypes = ctypes.POINTER(d), [ctypes.c_int]
    return lib


def _run(lib: ctypes.CDLL, name: str, h: float, n: int, start, side: float = 1.0):
    """``n`` steps of stepper ``name`` from ``start = (x, y, px, py)``: (steps taken, Q, P, E, F) copies."""
    m = getattr(lib, f"vc_{name}" if side > 0 else f"vc_{name}_dome")(h, n, *start)
    out = [np.ctypeslib.as_array(lib.vc_out(i), shape=(2 * n if i < 2 else n,)).copy() for i in range(4)]
    return m, out[0].reshape(n, 2)[:m], out[1].reshape(n, 2)[:m], out[2][:m], out[3][:m]


def check(lib: ctypes.CDLL, long_steps: int) -> None:
    """The exact variants against ``step`` (today's algebra): short runs, then the modulus over long ones."""
    starts = {  # name: (x, y, px, py), side
        "bowl, from rest at (0.6, -0.8)": ((0.6, -0.8, 0.0, 0.0), 1.0),
        "bowl, from the bottom at speed 3": ((0.0, -1.0, 3.0, 0.0), 1.0),
        "dome, from the top at speed 0.1": ((0.0, 1.0, 0.1, 0.0), -1.0),
    }
    print("\nagreement with `step` over the first 1000 steps (max |dq|, |dp|, |dE_d|, |d impulse|; steps)")
    for h in (1e-3, 1e-2, 3e-2):
        for label, (start, side) in starts.items():
            ref = _run(lib, "step", h, 1000, start, side)
            for name in STEPPERS[1:]:
                got = _run(lib, name, h, 1000, start, side)
                m = min(ref[0], got[0])
                d = [float(np.max(np.abs(a[:m] - b[:m]), initial=0.0)) for a, b in zip(ref[1:], got[1:])]
                print(f"  h={h:<6g} {label:<34} {name:<9} q {d[0]:.1e}  p {d[1]:.1e}  E {d[2]:.1e}  "
                      f"F {d[3]:.1e}  steps {got[0]} (step: {ref[0]})")  # fmt: skip
    print(
        f"\n{long_steps} steps, bowl from rest at (0.6, -0.8): max ||q|^2 - 1|, max |q . p|, end q - step's"
    )
    for h in (1e-3, 1e-2, 3e-2):
        ref = _run(lib, "step", h, long_steps, (0.6, -0.8, 0.0, 0.0))
        for name in STEPPERS:
            m, q, p, e, _ = ref if name == "step" else _run(lib, name, h, long_steps, (0.6, -0.8, 0.0, 0.0))
            mod = float(np.max(np.abs(np.sum(q * q, axis=1) - 1.0)))
            tan = float(np.max(np.abs(np.sum(q * p, axis=1))))
            end = float(np.max(np.abs(q[-1] - ref[1][-1])))
            print(f"  h={h:<6g} {name:<9} steps {m}  ||q|^2-1| {mod:.1e}  |q.p| {tan:.1e}  end q {end:.1e}  "
                  f"end E_d - step's {e[-1] - ref[3][-1]:.1e}")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--check", action="store_true", help="agreement with today's step, and the drift of |q|")
    ap.add_argument("--long-steps", type=int, default=1_000_000)
    a = ap.parse_args(argv)
    lib = _lib(max(a.steps, a.long_steps if a.check else 0, 1000))
    h, n = H, a.steps
    bowl = (0.6, -0.8, 0.0, 0.0)
    runs = {
        "free": lambda: lib.vc_free(h, n),
        "sqrt": lambda: lib.vc_sqrt(n),
        "chain": lambda: lib.vc_chain(h, n),
        "step": lambda: lib.vc_step(h, n, *bowl),
        "pipe_chain": lambda: lib.vc_pipe_chain(h, n),
        "pipe": lambda: lib.vc_pipe(h, n, *bowl),
        "rot_chain": lambda: lib.vc_rot_chain(h, n),
        "rot": lambda: lib.vc_rot(h, n, *bowl),
    }
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(a.repeats):
        for name, run in runs.items():
            t = time.thread_time()
            out = run()
            spent = time.thread_time() - t
            if name in ("free", "step", "pipe", "rot"):
                assert out == n, (name, out)  # every step taken
            best[name] = min(best[name], spent / n * 1e9)
    print(f"{'loop':<10} {'ns/step':>8} {'/ free':>7}   (CPU time, best of {a.repeats}, h = {h:g})")
    for name, ns in best.items():
        print(f"{name:<10} {ns:>8.2f} {ns / best['free']:>7.2f}")
    if a.check:
        check(lib, a.long_steps)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
