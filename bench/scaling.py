"""Growth with system size (issue 13): build time and cost per step and per impact against N.

    .venv/bin/python bench/scaling.py [--fast] [--repeats 3] [--out bench/results]

Two scenes, C backend, cold cache (``VCIGEN_CACHE`` set to a fresh temporary directory):

* ``chain``: N unit point masses on a line, x_i = i + 1 at the start, walls at 0 and N + 1;
  contacts ``wall_left``, ``gap0`` ... ``gap{N-2}`` (neighbours), ``wall_right``: N + 1 contacts.
* ``box``: N disks of radius 0.2 in a square box of side ceil(sqrt(N)) + 1 (unit spacing), 4 walls per
  disk and one contact per pair: 4 N + N (N - 1) / 2 contacts.

For each N: the build split into *derive* (:func:`vcigen.derive.derive`), *generate* (render
context with CSE, templates) and *compile* (``cc``); the cost per smooth step (a quiet run, the
bodies drifting at 1e-4 so that nothing is hit) and per impact (a dense run at speeds of order 1,
the quiet per-step cost of its steps subtracted), each the best of ``--repeats`` runs after an untimed
one, as seen by a user calling ``simulate`` (so a step includes storing its row of the result). Every
time is CPU time (this process's, and the compiler's for compile): the machine these figures come from
is shared, and wall times there are several times the CPU times. Every run is checked admissible
(phi_j(q_k) >= -1e-9 at every grid point).
Prints a table and the fitted exponents (slope of log cost against log N, and against log m, the
number of contacts) and writes ``scaling.csv`` and ``scaling.png`` into ``--out``. ``--fast`` takes
small N only (``tests/test_scaling.py`` runs it).
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy as sp

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:  # run as a script from anywhere: this checkout's vcigen
    sys.path.insert(0, str(HERE.parent))

import vcigen  # noqa: E402
from vcigen.backends.c import LIBRARY_TEMPLATES, build_library, render  # noqa: E402
from vcigen.backends.ccontext import render_context  # noqa: E402
from vcigen.backends.cwrap import CKernels, CSimulator  # noqa: E402
from vcigen.derive import derive  # noqa: E402
from vcigen.stepper import Tolerances  # noqa: E402

H = 0.01
RADIUS = 0.2
ADMISSIBLE = 1e-9
FULL = {"chain": (4, 8, 16, 32, 64), "box": (2, 4, 8, 12, 16)}
# --fast (tests/test_scaling.py runs it): a fit needs two sizes of a scene, the growing source three chains.
# Box N = 4 (22 contacts) took 37 s of the test's 110 s of CPU (27 s its CSE) and checked what box 2 and 3 do.
FAST = {"chain": (2, 4, 8), "box": (2, 3)}
COLUMNS = (
    "scene",
    "N",
    "n",
    "m",
    "derive_s",
    "generate_s",
    "compile_s",
    "build_s",
    "build_wall_s",
    "kbytes",
    "us_per_step",
    "us_per_impact",
    "impacts",
    "min_phi",
)


def chain(n: int) -> vcigen.Model:
    """N unit masses on a line between walls at 0 and N + 1, neighbour contacts."""
    xs, vs = sp.symbols(f"x0:{n}", real=True), sp.symbols(f"xd0:{n}", real=True)
    m = sp.Symbol("m", positive=True)
    contacts = {"wall_left": xs[0]}
    contacts |= {f"gap{i}": xs[i + 1] - xs[i] for i in range(n - 1)}
    contacts["wall_right"] = n + 1 - xs[-1]
    return vcigen.Model(
        name=f"chain{n}",
        q=list(xs),
        qdot=list(vs),
        lagrangian=sum(m / 2 * v**2 for v in vs),
        contacts=contacts,
        params={m: 1.0},
    )


def _side(n: int) -> int:
    return math.ceil(math.sqrt(n))


def box(n: int) -> vcigen.Model:
    """N disks of radius 0.2 in a square box, 4 walls each and one contact per pair."""
    xs, ys = sp.symbols(f"x0:{n}", real=True), sp.symbols(f"y0:{n}", real=True)
    xd, yd = sp.symbols(f"xd0:{n}", real=True), sp.symbols(f"yd0:{n}", real=True)
    m = sp.Symbol("m", positive=True)
    w = _side(n) + 1
    contacts = {}
    for i in range(n):
        contacts |= {
            f"l{i}": xs[i] - RADIUS,
            f"r{i}": w - RADIUS - xs[i],
            f"b{i}": ys[i] - RADIUS,
            f"t{i}": w - RADIUS - ys[i],
        }
    for i in range(n):
        for k in range(i + 1, n):
            contacts[f"d{i}_{k}"] = sp.sqrt((xs[i] - xs[k]) ** 2 + (ys[i] - ys[k]) ** 2) - 2 * RADIUS
    q = [c for i in range(n) for c in (xs[i], ys[i])]
    qd = [c for i in range(n) for c in (xd[i], yd[i])]
    return vcigen.Model(
        name=f"box{n}",
        q=q,
        qdot=qd,
        lagrangian=sum(m / 2 * v**2 for v in qd),
        contacts=contacts,
        params={m: 1.0},
    )


SCENES = {"chain": chain, "box": box}


def start(scene: str, n: int, speed: float, seed: int = 1) -> tuple[list[float], list[float]]:
    """Bodies on the unit grid with random velocities of size ``speed``."""
    rng = np.random.default_rng(seed + n)
    if scene == "chain":
        return [float(i + 1) for i in range(n)], list(speed * rng.uniform(-1, 1, n))
    side = _side(n)
    q = [float(c) for i in range(n) for c in (i % side + 1, i // side + 1)]
    return q, list(speed * rng.uniform(-1, 1, 2 * n))


def _children_cpu() -> float:
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def timed_build(model: vcigen.Model) -> tuple[vcigen.Simulator, dict[str, float]]:
    """The C backend's build (:func:`vcigen.backends.c.build_c`) step by step, cold cache.

    Each step in CPU seconds (this process for derive and generate, the compiler's for compile), so
    that other work on a shared machine does not count; ``build_wall_s`` is the wall time of all three.
    """
    tol = Tolerances()
    wall, t0 = time.perf_counter(), time.process_time()
    system = derive(model, "trapezoid")
    t1 = time.process_time()
    ctx = render_context(system, None, tol)
    files = render(ctx, LIBRARY_TEMPLATES)
    t2 = time.process_time()
    with tempfile.TemporaryDirectory() as cache:
        c0 = _children_cpu()
        lib = build_library(files, ctx["model"], cache=cache)
        compile_s = _children_cpu() - c0
        wall = time.perf_counter() - wall
        sim = CSimulator(system, CKernels(system, lib, ctx), tol)  # the library stays loaded
    size = sum(len(v) for v in files.values()) / 1e3
    return sim, {
        "derive_s": t1 - t0,
        "generate_s": t2 - t1,
        "compile_s": compile_s,
        "build_s": t2 - t0 + compile_s,
        "build_wall_s": wall,
        "kbytes": size,
    }


def min_phi(model: vcigen.Model, q: np.ndarray) -> float:
    """The smallest phi_j(q_k) over every grid point and contact."""
    f = sp.lambdify([list(model.coordinates)], [e.subs(model.defaults) for e in model.phi.values()], "numpy")
    vals = f(q.T)
    return float(min(np.min(np.broadcast_to(v, q.shape[:1])) for v in vals))


def best(repeats: int, fn):
    """``(result, least CPU time in s)`` of ``repeats`` calls after one untimed call (single-threaded).

    The untimed call pays the page faults of result arrays the allocator has not reused yet: a first
    run of 2e5 chain steps took 180-270 ms of CPU, the next ones 7-10 ms. Without it, best of 2 kept
    that first-touch cost, and the chain's per-step fit came out falling with N (CI at 5b46b3c).
    """
    fn()
    out, wall = None, math.inf
    for _ in range(repeats):
        t = time.process_time()
        out = fn()
        wall = min(wall, time.process_time() - t)
    return out, wall


def run_costs(sim: vcigen.Simulator, scene: str, n: int, steps: int, t_dense: float, repeats: int) -> dict:
    """Cost per smooth step and per impact, the fixed cost of a ``simulate`` call taken out.

    Per step: the difference of a quiet run of ``steps`` steps and one of ``steps // 10`` (nothing is
    hit), over the difference in steps. Per impact: a dense run (speeds of order 1, up to ``t_dense``)
    less a quiet run of as many steps, over its impacts. Also the runs' smallest phi.
    """
    q0, v0 = start(scene, n, 1e-4)

    def quiet(k: int):
        res, wall = best(repeats, lambda: sim.simulate(q0=q0, v0=v0, h=H, t_end=k * H))
        if res.n_impacts:
            raise RuntimeError(f"{scene} N={n}: the quiet run has {res.n_impacts} impacts")
        return res, wall

    long, wall_long = quiet(steps)
    _, wall_short = quiet(steps // 10)
    per_step = max(wall_long - wall_short, 0.0) / (steps - steps // 10)
    q1, v1 = start(scene, n, 1.0)
    dense, wall = best(repeats, lambda: sim.simulate(q0=q1, v0=v1, h=H, t_end=t_dense))
    _, wall_same = quiet(len(dense.t) - 1)
    per_impact = max(wall - wall_same, 0.0) / max(dense.n_impacts, 1)
    low = min(min_phi(sim.model, long.q), min_phi(sim.model, dense.q))
    return {
        "us_per_step": per_step * 1e6,
        "us_per_impact": per_impact * 1e6,
        "impacts": dense.n_impacts,
        "min_phi": low,
    }


def measure(scene: str, n: int, fast: bool, repeats: int) -> dict:
    model = SCENES[scene](n)
    sim, times = timed_build(model)
    steps, t_dense = (20_000, 10.0) if fast else (200_000, 40.0)
    row = {"scene": scene, "N": n, "n": model.n, "m": len(model.phi), **times}
    row |= run_costs(sim, scene, n, steps, t_dense, repeats)
    return row


def exponent(xs, ys) -> float:
    """Least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(np.asarray(xs, float)), np.log(np.asarray(ys, float)), 1)[0])


FITTED = ("derive_s", "generate_s", "compile_s", "build_s", "us_per_step", "us_per_impact")


def fits(rows: list[dict]) -> dict[str, dict[str, float]]:
    """Per scene, the exponent of each cost in N and (``/m``) in the number of contacts."""
    out = {}
    for scene in dict.fromkeys(r["scene"] for r in rows):
        sel = [r for r in rows if r["scene"] == scene]
        if len(sel) < 2:
            continue
        out[scene] = {}
        for key in FITTED:
            ys = [max(r[key], 1e-9) for r in sel]
            out[scene][key] = exponent([r["N"] for r in sel], ys)
            out[scene][key + "/m"] = exponent([r["m"] for r in sel], ys)
    return out


def read_row(r: dict[str, str]) -> dict:
    """A row of a written CSV with its numbers back."""
    ints = ("N", "n", "m", "impacts")
    return {k: (v if k == "scene" else int(v) if k in ints else float(v)) for k, v in r.items()}


def write_csv(rows: list[dict], path: Path) -> None:
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.6g}" if isinstance(r[k], float) else r[k]) for k in COLUMNS})


def plot(rows: list[dict], exps: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    styles = {"chain": "-", "box": "--"}
    for scene, ls in styles.items():
        sel = [r for r in rows if r["scene"] == scene]
        if not sel:
            continue
        ns = [r["N"] for r in sel]
        for key, mk in (("derive_s", "s"), ("generate_s", "^"), ("compile_s", "v"), ("build_s", "o")):
            label = f"{scene} {key[:-2]} (N^{exps.get(scene, {}).get(key, float('nan')):.2f})"
            axes[0].loglog(ns, [max(r[key], 1e-4) for r in sel], ls, marker=mk, label=label)
        for key, mk in (("us_per_step", "o"), ("us_per_impact", "s")):
            label = (
                f"{scene} {key[3:].replace('_', ' ')} (N^{exps.get(scene, {}).get(key, float('nan')):.2f})"
            )
            axes[1].loglog(ns, [max(r[key], 1e-4) for r in sel], ls, marker=mk, label=label)
    axes[0].set(xlabel="N bodies", ylabel="build time [s] (cold cache)", title="build")
    axes[1].set(xlabel="N bodies", ylabel="cost [us]", title="run (C backend, from Python)")
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    for ax in axes:
        ax.set_xticks(sorted({r["N"] for r in rows}))
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(rows: list[dict], exps: dict) -> str:
    """The markdown table and the exponents, as the README shows them."""
    lines = [
        "| scene | N | n | m | derive s | generate s | compile s | build s | (wall s) | C kB | us/step "
        "| us/impact"
        " | impacts |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['N']} | {r['n']} | {r['m']} | {r['derive_s']:.2f} | "
            f"{r['generate_s']:.2f} | "
            f"{r['compile_s']:.2f} | {r['build_s']:.2f} | {r['build_wall_s']:.1f} | {r['kbytes']:.0f} | "
            f"{r['us_per_step']:.3f} | "
            f"{r['us_per_impact']:.2f} | {r['impacts']} |"
        )
    lines.append("")
    for scene, e in exps.items():
        parts = ", ".join(f"{k[:-2] if k.endswith('_s') else k[3:]} N^{e[k]:.2f}" for k in FITTED)
        per_m = ", ".join(f"{k[:-2] if k.endswith('_s') else k[3:]} m^{e[k + '/m']:.2f}" for k in FITTED)
        lines.append(f"- {scene}: {parts}; against the number of contacts m: {per_m}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fast", action="store_true", help="small N only (the test runs this)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=str(HERE / "results"))
    ap.add_argument("--scenes", default="chain,box")
    ap.add_argument("--sizes", default="", help="comma-separated N, overriding the defaults")
    ap.add_argument("--from-csv", nargs="*", default=[], help="no runs: table, fits and plot of these CSVs")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sizes = FAST if args.fast else FULL
    rows = [read_row(r) for path in args.from_csv for r in csv.DictReader(Path(path).open())]
    name = "scaling_fast" if args.fast else "scaling"
    for scene in args.scenes.split(",") if not args.from_csv else ():
        for n in [int(s) for s in args.sizes.split(",")] if args.sizes else sizes[scene]:
            row = measure(scene, n, args.fast, args.repeats)
            rows.append(row)
            print(
                f"{scene} N={n}: build {row['build_s']:.2f} s (derive {row['derive_s']:.2f}, generate "
                f"{row['generate_s']:.2f}, compile {row['compile_s']:.2f}), "
                f"{row['us_per_step']:.3f} us/step, "
                f"{row['us_per_impact']:.2f} us/impact ({row['impacts']} impacts)",
                flush=True,
            )
            if row["min_phi"] < -ADMISSIBLE:
                raise RuntimeError(f"{scene} N={n}: inadmissible run, min phi = {row['min_phi']:.3e}")
            write_csv(rows, out / f"{name}.csv")  # as it goes: a long run keeps what it measured
    exps = fits(rows)
    write_csv(rows, out / f"{name}.csv")
    plot(rows, exps, out / f"{name}.png")
    print(table(rows, exps))
    return {"rows": rows, "exponents": exps, "csv": out / f"{name}.csv", "png": out / f"{name}.png"}


if __name__ == "__main__":
    os.environ.setdefault("VCIGEN_CACHE", tempfile.mkdtemp(prefix="vcigen-scaling-"))
    main()
