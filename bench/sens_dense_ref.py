"""The O(n^2)-per-step term of issue 11's C cost target, measured: a dense tangent step in plain C.

    .venv/bin/python -m bench.sens_dense_ref [--steps 20000] [--repeats 7]

Issue 11 item 6 asks for a C run with sensitivities to cost at most ``3x + O(n^2)`` per step of the run
without. Read here: the ``O(n^2)`` term stands for the tangent recurrence's own per-step work, ``S_k+1 = A_k
S_k + B_k`` (``2n x K``, ``K = 2n + P``) computed with a dense ``A_k``, checked finite and stored into the
run's ``N``-row output. This module times that work in its plain form, the naive triple loop, so that the
term's constant is a measured number rather than a guess (a sparse ``A_k``, as many held steps have, needs
less):

* per step, a dense ``2n x 2n`` matrix ``A_k`` times the ``2n x K`` tangent, plus a ``2n x K`` forcing term
  ``B_k`` (all ``K`` columns: a real step's ``Phi_par`` fills only the ``P`` parameter columns, so this is
  the larger choice);
* ``A_k`` and ``B_k`` are read from a ring of ``RING`` precomputed random matrices (in L1), so the compiler
  can neither fold nor hoist them; ``|A_k|_inf <= 0.9`` keeps ``S`` bounded (no overflow, and the forcing
  keeps it away from subnormals);
* the result is checked finite by the same ``0 * s`` sum as ``templates/sens_run.c.j2``'s ``sens_store`` and
  copied into row ``k`` of an ``N``-row buffer (what ``res.sensitivity`` holds), freshly allocated per call
  as a run's is; the two halves of the tangent are swapped (no copy back), as the held glide's map does;
* the loop bounds are compile-time constants (``-DN2=2n -DKC=K``) like the generated code's, compiled with
  the generated code's flags (``vcigen.backends.c.CFLAGS``: ``-std=c99 -O2 ...``); no hand unrolling, no
  blocking, no ``restrict``: the plain product, not a tuned kernel.

``bench/sensitivity_cost_c.py`` times this reference per scene in the same process and run as the scene
itself, and judges ``with <= 3 * without + reference`` next to the strict ``ratio <= 3``. Run alone, this
prints the reference for the bench's sizes.
"""

from __future__ import annotations

import argparse
import ctypes
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from vcigen.backends.c import CFLAGS

RING = 16  # precomputed (A_k, B_k) pairs, cycled (a power of 2: the index is a mask)

SRC = r"""
/* S_k+1 = A_k S_k + B_k, checked finite, stored into row k of S: the plain dense tangent step
 * (N2 = 2n, KC = K) */
long vc_dense(double *S, long steps, const double *A, const double *B, double *s_io)
{
    double buf[2][N2 * KC], *s = buf[0], *s1 = buf[1], *t;
    long k, bad = 0;
    int i, j, l;
    for (i = 0; i < N2 * KC; ++i) {
        s[i] = s_io[i];
    }
    for (k = 0; k < steps; ++k) {
        const double *a = A + (k & (RING - 1)) * N2 * N2, *b = B + (k & (RING - 1)) * N2 * KC;
        double *row = S + k * N2 * KC, zero = 0.0;
        for (i = 0; i < N2; ++i) {
            for (j = 0; j < KC; ++j) {
                double acc = b[i * KC + j];
                for (l = 0; l < N2; ++l) {
                    acc += a[i * N2 + l] * s[l * KC + j];
                }
                s1[i * KC + j] = acc;
            }
        }
        for (i = 0; i < N2 * KC; ++i) {
            row[i] = s1[i];
            zero += 0.0 * s1[i];
        }
        bad += zero != 0.0;
        t = s;
        s = s1;
        s1 = t;
    }
    for (i = 0; i < N2 * KC; ++i) {
        s_io[i] = s[i];
    }
    return bad;
}
"""


def compile_c(src: str, defines: dict[str, int] | None = None) -> ctypes.CDLL:
    """``src`` compiled with the generated code's flags (and ``-D`` ``defines``) into a loaded library."""
    tmp = Path(tempfile.mkdtemp(prefix="vcigen_bench_"))
    try:
        (tmp / "ref.c").write_text(src)
        flags = [f"-D{k}={v}" for k, v in (defines or {}).items()]
        subprocess.run(["cc", *CFLAGS, *flags, str(tmp / "ref.c"), "-o", str(tmp / "ref.so")], check=True)
        return ctypes.CDLL(str(tmp / "ref.so"))  # the loaded library stays mapped after its file is gone
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


class DenseRef:
    """The reference loop for a tangent of ``2n x k`` (``n`` coordinates, ``k`` columns), compiled once."""

    def __init__(self, n: int, k: int, seed: int = 11) -> None:
        self.n2, self.k = 2 * n, k
        self.lib = compile_c(SRC, {"N2": self.n2, "KC": k, "RING": RING})
        self.lib.vc_dense.restype = ctypes.c_long
        self.lib.vc_dense.argtypes = [ctypes.c_void_p, ctypes.c_long] + [ctypes.c_void_p] * 3
        rng = np.random.default_rng(seed)
        self.a = rng.uniform(-0.9, 0.9, (RING, self.n2, self.n2)) / self.n2  # |A|_inf <= 0.9
        self.b = rng.uniform(-1.0, 1.0, (RING, self.n2, k))
        self.s = rng.uniform(-1.0, 1.0, (self.n2, k))

    def seconds(self, steps: int) -> float:
        """One timed run of ``steps`` steps into a fresh ``steps``-row buffer (asserts every row finite)."""
        out = np.empty((steps, self.n2, self.k))
        t = time.perf_counter()
        args = out.ctypes.data, steps, self.a.ctypes.data, self.b.ctypes.data, self.s.ctypes.data
        bad = self.lib.vc_dense(*args)
        t = time.perf_counter() - t
        assert bad == 0 and np.isfinite(self.s).all(), "the reference's tangent left the finite range"
        return t


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    sizes = {"particle": (2, 6), "star": (3, 9), "double_pendulum": (2, 10), "slide": (2, 5),
             "box_face": (3, 6), "bowl": (2, 4), "drag": (2, 7), "dome": (2, 6)}  # fmt: skip
    for scene, (n, k) in sizes.items():
        ref = DenseRef(n, k)
        best = min(ref.seconds(args.steps) for _ in range(args.repeats))
        flops = 2 * (2 * n) ** 2 * k + 2 * n * k
        print(f"{scene:16s} n={n} K={k:2d}: {1e9 * best / args.steps:6.1f} ns/step ({flops} flops, "
              f"{2 * n * k} doubles stored)", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
