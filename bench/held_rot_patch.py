"""The rotation form (``bench.held_rot``) inside the bowl's generated C loop: an experiment, not generated.

    .venv/bin/python -m bench.held_rot_patch [--rounds 2] [--repeats 7]

Builds ``bench.sustained_cost``'s bowl (C backend) into a private cache (``VCIGEN_CACHE`` in a temporary
directory; the shared cache is not touched), copies it, and in the copy replaces the held loop's body for
the one active row (``sc_bowl_held_loop``, ``na == 1``) by the rotation form written by hand (``ROT`` below:
the same stores, logs, tests and exit state as the generated loop), then recompiles it with the generated
code's flags. Then, each in its own process, alternated ``--rounds`` times:

* the agreement of the two libraries on whole runs (from rest at (0.6, -0.8), 2e5 steps at h = 1e-3 and
  1e-2; from the bottom at speed 5, 3 s at h = 1e-3: a lift-off and impacts): max differences of q, p,
  E_d, the contact force, and whether the active sets, impacts and lift-offs are the same;
* ``bench.held_curved``'s bowl rows (CPU time of the C loop, best of ``--repeats``): held step, free step,
  ratio.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ANCHOR = """    long s;
    sc_bowl_held_rows(q, kh, psi, grad, hess);
"""
# kh: sc_bowl_held_consts (k0 = -g h / 2, R, -k0, -R^2, ..., 1/(2R), -1/(2R)) at indices 0, 1, 2, 3, 11, 12
ROT = """    long s;
    if (na == 1) { /* bench.held_rot_patch: the rotation form of the held step on the circle |q| = R */
        const double R = kh[1], iR = 1.0 / R, k0 = kh[0], ih = 1.0 / h, hR = h * iR, tk = 2.0 * k0;
        const double ymax = -R * R / (h * k0); /* the root holds: B > 0 */
        double x = q[0], y = q[1], px = p[0], py = p[1], nx = x * iR, ny = y * iR, om, arg, sq;
        double x0 = x, y0 = y, px0 = px, py0 = py;
        om = (px * -ny + py * nx) + k0 * nx;
        arg = 1.0 / (nx * nx + ny * ny) - (hR * om) * (hR * om);
        for (s = 0; s < n; ++s) {
            double vv[2], pp[2], q0a[2], tot;
            const double aa = hR * om;
            sq = sqrt(arg);
            {
                const double n1x = sq * nx - aa * ny, n1y = sq * ny + aa * nx;
                const double x1 = R * n1x, y1 = R * n1y, pi1 = om + k0 * n1x;
                const double p1x = -pi1 * n1y, p1y = pi1 * n1x;
                const double ho0 = hR * (om - tk * aa * ny), ho1 = hR * tk * nx;
                const double an = (2.0 - (nx * nx + ny * ny) * (arg + aa * aa) - ho1 * ho1 * arg) - ho0 * ho0;
                const double bn = (-2.0 * ho1) * ho0;
                const double f = kh[11] * (-19.62 * y1 + 2.0 * (pi1 * pi1));
                const double rs = kh[12] * (kh[3] + x1 * x1 + y1 * y1);
                vv[0] = (x1 - x) * ih;
                vv[1] = (y1 - y) * ih;
                q0a[0] = x;
                q0a[1] = y;
                sc_bowl_held_segment(q0a, vv, kh, pp, &e);
                tot = e + f + x1 + y1 + p1x + p1y;
                if (!(y < ymax) | !(arg >= 0.0) | !(fabs(rs) <= residual)
                    | (f < -SC_BOWL_EPS_LAM * (1.0 + fabs(f))) | !isfinite(tot)) {
                    break;
                }
                /* Lam + Lam' from the momentum change along n0 + n1 (grad psi = -n) */
                imp = -((p1x - px) * (nx + n1x) + (p1y - py - 2.0 * k0) * (ny + n1y)) / (1.0 + sq);
                x0 = x;
                y0 = y;
                px0 = px;
                py0 = py;
                arg = an + bn * sq;
                om = pi1 + k0 * n1x;
                x = x1;
                y = y1;
                px = p1x;
                py = p1y;
                nx = n1x;
                ny = n1y;
            }
            Q[s * 2] = x;
            Q[s * 2 + 1] = y;
            P[s * 2] = px;
            P[s * 2 + 1] = py;
            E[s] = e;
            sum += e;
            F[s] = imp / h;
            A[s] = held[0];
        }
        if (s > 0) { /* the last step's Lam = (v - v0) . grad psi(q0) (the general chain's start) */
            lam[0] = -(((x - x0) * ih - px0) * x0 * iR + ((y - y0) * ih - py0 - k0) * y0 * iR);
        }
        q[0] = x;
        q[1] = y;
        p[0] = px;
        p[1] = py;
        v[0] = (x - x0) * ih;
        v[1] = (y - y0) * ih;
        *sum_e += sum;
        (void)c; (void)act; (void)fm; (void)fk; (void)i; (void)j; (void)r; (void)FC; (void)g1; (void)g0;
        (void)psi; (void)grad; (void)hess; (void)q1; (void)p1; (void)lam1; (void)a; (void)phi_tol;
        return s;
    }
    sc_bowl_held_rows(q, kh, psi, grad, hess);
"""
RUNS = ((1e-3, 200_000), (1e-2, 200_000))


def prepare(tmp: Path) -> tuple[Path, Path]:
    """Two private caches with the bowl's library: as generated, and with the rotation form."""
    from vcigen.backends.c import CFLAGS

    orig, rot = tmp / "orig", tmp / "rot"
    subprocess.run([sys.executable, "-m", "bench.held_rot_patch", "--worker", "build"], check=True,
                   env={**os.environ, "VCIGEN_CACHE": str(orig)})  # fmt: skip
    shutil.copytree(orig, rot)
    (where,) = [d for d in rot.iterdir() if (d / "sc_bowl.c").is_file()]
    src = (where / "sc_bowl.c").read_text()
    assert src.count(ANCHOR) == 1, "the generated held loop changed: update ANCHOR"
    (where / "sc_bowl.c").write_text(src.replace(ANCHOR, ROT))
    cmd = ["cc", *CFLAGS, "-o", str(where / "libsc_bowl.so"), str(where / "sc_bowl.c"), "-lm"]
    subprocess.run(cmd, check=True)
    return orig, rot


def worker(kind: str, out: str | None, repeats: int) -> None:
    import warnings

    import vcigen
    from bench.held_curved import BOWL_FREE, BOWL_HELD
    from bench.sustained_cost import bowl, cpu_clock, keep_heap

    warnings.simplefilter("ignore", RuntimeWarning)
    keep_heap()
    sim = vcigen.build(bowl(), backend="c")
    if kind == "build":
        return
    if kind == "runs":
        res = {}
        for h, steps in RUNS:
            r = sim.simulate([0.6, -0.8], [0.0, 0.0], h, t_end=steps * h, params={"r": 1.0})
            res |= {
                f"{k}{h}": v for k, v in (("q", r.q), ("p", r.p), ("E", r.energy), ("F", r.contact_force))
            }
            res[f"a{h}"] = r.active
        r = sim.simulate([0.0, -1.0], [5.0, 0.0], 1e-3, t_end=3.0, params={"r": 1.0})
        res |= {"qL": r.q, "pL": r.p, "EL": r.energy, "FL": r.contact_force, "aL": r.active}
        res["events"] = np.array([len(r.impacts), len(r.liftoffs)])
        np.savez(out, **res)
        return
    clock = cpu_clock(sim)
    best = {}
    for _ in range(repeats):
        for h, steps in RUNS:
            for name, (q0, v0, params) in (("held", BOWL_HELD), ("free", BOWL_FREE)):
                t0 = clock[0]
                sim.simulate(q0, v0, h, t_end=steps * h, params=params)
                best[h, name] = min(best.get((h, name), np.inf), (clock[0] - t0) / steps * 1e9)
    for h, _ in RUNS:
        held, free = best[h, "held"], best[h, "free"]
        print(f"{h:>7.0e} {held:>8.1f} {free:>8.1f} {held / free:>6.2f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--worker", choices=("build", "runs", "time"))
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    if a.worker:
        worker(a.worker, a.out, a.repeats)
        return 0
    tmp = Path(tempfile.mkdtemp(prefix="vcigen_held_rot_"))
    caches = dict(zip(("generated", "rotation"), prepare(tmp)))

    def run(kind: str, cache: Path, *extra: str) -> str:
        env = {**os.environ, "VCIGEN_CACHE": str(cache)}
        cmd = [
            sys.executable,
            "-m",
            "bench.held_rot_patch",
            "--worker",
            kind,
            "--repeats",
            str(a.repeats),
            *extra,
        ]
        return subprocess.run(cmd, check=True, env=env, capture_output=True, text=True).stdout

    outs = {}
    for name, cache in caches.items():
        outs[name] = tmp / f"{name}.npz"
        run("runs", cache, "--out", str(outs[name]))
    ref, got = np.load(outs["generated"]), np.load(outs["rotation"])
    print("agreement, rotation form against the generated loop (whole runs):")
    for key in ref.files:
        x, y = ref[key], got[key]
        if x.dtype == bool or key == "events":
            print(f"  {key:<7} {'same' if x.shape == y.shape and (x == y).all() else 'DIFFERENT'}")
        else:
            d = float(np.max(np.abs(x - y))) if x.shape == y.shape else float("nan")
            print(f"  {key:<7} max |difference| {d:.1e}")
    print(f"\n{'loop':<10} {'h':>7} {'held ns':>8} {'free ns':>8} {'ratio':>6}   (CPU time of the C loop)")
    for _ in range(a.rounds):
        for name, cache in caches.items():
            for line in run("time", cache).splitlines():
                print(f"{name:<10} {line}")
    shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
