"""The memory floor of a C run's tangent output: the cost per grid step of only storing its row of doubles.

    .venv/bin/python -m bench.sens_store_floor [--steps 20000] [--repeats 7]

A C run with sensitivities writes ``S_k+1`` (``2n x K`` doubles) per grid step into the run's buffer, where
the plain run writes ``q, p`` and ``t`` (``2n + 1``); ``templates/sens_run.c.j2``'s ``sens_row`` also sums
``0 * S`` for the finiteness check. This times those stores alone, in a small C loop compiled here with the
generated code's flags (``-O2``), into a freshly allocated buffer (first touch included, as a run's) and
into an already touched one: ``store`` = the copy only, ``store+check`` = the copy and ``sens_row``'s check.
Its first entry changes every step (so the stores are not hoisted; the tangent's own update is
not timed; ``bench.sens_dense_ref`` times it with the stores).
Sizes: the particle (n = 2, K = 6: 24 vs 5), the star (n = 3, K = 9: 54 vs 7), the double pendulum
(n = 2, K = 10: 40 vs 5).
"""

from __future__ import annotations

import argparse
import ctypes
import time

import numpy as np

from bench.sens_dense_ref import compile_c

SRC = r"""
#include <stdlib.h>
long vc_store(double *S, long steps, int m, double *s, int check)
{
    long k, bad = 0;
    int i;
    for (k = 0; k < steps; ++k) {
        double *row = S + k * m, zero = 0.0;
        s[0] += 1e-3;
        if (check) {
            for (i = 0; i < m; ++i) {
                row[i] = s[i];
                zero += 0.0 * s[i];
            }
            bad += zero != 0.0;
        } else {
            for (i = 0; i < m; ++i) {
                row[i] = s[i];
            }
        }
    }
    return bad;
}
"""

SIZES = {"particle": (2, 6), "star": (3, 9), "double_pendulum": (2, 10)}


def _lib() -> ctypes.CDLL:
    lib = compile_c(SRC)
    lib.vc_store.restype = ctypes.c_long
    lib.vc_store.argtypes = [ctypes.c_void_p, ctypes.c_long, ctypes.c_int, ctypes.c_void_p, ctypes.c_int]
    return lib


def ns_per_step(lib: ctypes.CDLL, m: int, steps: int, repeats: int, check: int, fresh: bool) -> float:
    best = float("inf")
    s = np.ones(m)
    S = np.empty((steps, m))
    for _ in range(repeats):
        if fresh:
            S = np.empty((steps, m))
        t = time.perf_counter()
        lib.vc_store(S.ctypes.data, steps, m, s.ctypes.data, check)
        best = min(best, time.perf_counter() - t)
    return 1e9 * best / steps


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    lib = _lib()
    for scene, (n, k) in SIZES.items():
        out = []
        for m in (2 * n * k, 2 * n + 1):
            for fresh in (True, False):
                for check in (0, 1):
                    out.append(ns_per_step(lib, m, args.steps, args.repeats, check, fresh))
        print(
            f"{scene:16s} S row {2 * n * k:2d} doubles: store {out[0]:5.1f} ns/step, "
            f"store+check {out[1]:5.1f} "
            f"(fresh buffer), {out[2]:5.1f} / {out[3]:5.1f} (touched); plain row {2 * n + 1} doubles: "
            f"store {out[4]:5.1f} (fresh), {out[6]:5.1f} (touched)",
            flush=True,
        )


if __name__ == "__main__":
    main()
