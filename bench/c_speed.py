"""Speed of the generated C against the CasADi backend and a hand-written C loop (issue 3).

    .venv/bin/python bench/c_speed.py [--repeats 5] [--user-only]

For the paper's particle (m = 1, g = 9.81, h = 0.01): ns per smooth step (a run high
above the floor, no impact) and us per impact (1 mm bounces, an impact every ~3 steps,
the steps without an impact subtracted) for

* the generated C, both rules, its whole loop ``<model>_run`` called once through ctypes;
* the CasADi backend (Python stepper over CasADi Functions);
* ``bench/handwritten/particle.c``: Stormer-Verlet plus an analytic impact time, the
  practical limit, called the same way.

Then (``user_main``, alone with ``--user-only``) what a user sees from Python, the C backend called
as a user calls it (``simulate`` / ``simulate_many`` with default options): the particle's 1000
impacts by ``n_impacts=`` and by ``t_end=``, against the same steps without impacts (us per impact
seen from Python); the fixed cost of a ``simulate`` call (double pendulum, 0 and 33 steps); and
``simulate_many`` against a loop of ``simulate`` (per run), with 1 and 2 threads. Writes
``bench/results/c_speed_user.csv``.

Every variant stores the same output (q, p, energy per step) into preallocated
buffers; the best of ``--repeats`` runs counts. Prints a table with ratios and
writes ``bench/results/c_speed.csv``. Targets: generated C within 1.5x of the
hand-written loop per smooth step; C >= 100x faster per step than CasADi.
"""

from __future__ import annotations

import argparse
import csv
import ctypes
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import vcigen
from vcigen.backends.cwrap import IMPACT_CAP, _Err, _ptr, _tol_struct
from vcigen.cli import load_example

HERE = Path(__file__).resolve().parent
Q0, V0, H = [0.0, 1.0], [-2.0, 0.0], 0.01
HIGH = [0.0, 1e9]  # 1e6 steps of free fall stay far above the floor
DENSE = [0.0, 1e-3]  # bounces of 1 mm: an impact every ~3 steps, so impacts dominate the time
N_SMOOTH_C, N_SMOOTH_CASADI = 1_000_000, 5_000
N_IMPACTS_C, N_IMPACTS_CASADI = 20_000, 100


def best_of(repeats: int, fn) -> float:
    """Smallest wall time of ``repeats`` calls of ``fn``."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


class Buffers:
    """Preallocated, touched output buffers shared by the C variants."""

    def __init__(self, steps: int) -> None:
        self.Q, self.P, self.E = np.zeros((steps, 2)), np.zeros((steps, 2)), np.zeros(steps)
        self.rec = np.zeros((IMPACT_CAP, 10))  # t, contact, step, alpha, impulse, E before/after, q (2), kind
        self.A = np.zeros(steps, dtype=np.uint8)  # active contact per step (the one contact)
        self.F, self.FC = np.zeros(steps), np.zeros(steps)  # its mean force, the constraint forces (none)


def generated_runner(rule: str, buf: Buffers):
    """``run(q0, steps, max_impacts) -> (steps, impacts)`` over the generated ``particle_run``."""
    sim = vcigen.build(load_example(HERE.parent / "examples" / "particle.py").model(), backend="c", rule=rule)
    kern = sim.kernels.bind(sim.model.resolve_params(None))
    tol = _tol_struct(sim.tol)
    lift = np.zeros((IMPACT_CAP, 2))

    def run(q0, steps: int, max_impacts: int) -> tuple[int, int]:
        q, v = np.array(q0, dtype=float), np.array(V0)
        p = kern.legendre(q, v)[0].copy()
        err, sd, idone = _Err(), ctypes.c_long(0), ctypes.c_long(0)
        sus = kern.Sustain()  # no contact held at the start (the runs start in free flight)
        sus.liftoffs, sus.liftoff_cap = _ptr(lift), IMPACT_CAP
        done = impacts = 0
        while done < steps and impacts < max_impacts:  # the impact buffer is drained between chunks
            rc = kern.run(
                _ptr(kern.par),
                ctypes.byref(tol),
                H,
                0.0,
                done,
                steps - done,
                max_impacts - impacts,
                _ptr(q),
                _ptr(p),
                _ptr(v),
                _ptr(buf.Q[done:]),
                _ptr(buf.P[done:]),
                _ptr(buf.E[done:]),
                _ptr(buf.rec),
                IMPACT_CAP,
                ctypes.byref(sd),
                ctypes.byref(idone),
                ctypes.byref(err),
                ctypes.byref(sus),
                buf.A[done:].ctypes.data_as(ctypes.c_void_p),
                _ptr(buf.F[done:]),
                _ptr(buf.FC[done:]),
            )
            assert rc == 0, err.reason
            done, impacts = done + sd.value, impacts + idone.value
        return done, impacts

    return run


def handwritten_runner(buf: Buffers):
    """The same interface over ``bench/handwritten/particle.c``."""
    out = Path(tempfile.mkdtemp(prefix="vcigen-hw-")) / "libhw_particle.so"
    subprocess.run(
        [
            "cc",
            "-std=c99",
            "-O2",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-fPIC",
            "-shared",
            "-o",
            str(out),
            str(HERE / "handwritten" / "particle.c"),
            "-lm",
        ],
        check=True,
    )
    lib = ctypes.CDLL(str(out))
    f = lib.hw_particle_run
    f.restype = ctypes.c_long
    f.argtypes = [ctypes.c_void_p] * 2 + [ctypes.c_double] * 3 + [ctypes.c_long] * 2 + [ctypes.c_void_p] * 5
    imp = np.zeros(2 * (N_IMPACTS_C + 1))

    def run(q0, steps: int, max_impacts: int) -> tuple[int, int]:
        n_imp = ctypes.c_long(0)
        q, v = np.array(q0, dtype=float), np.array(V0)
        done = f(
            q.ctypes.data,
            v.ctypes.data,
            H,
            1.0,
            9.81,
            steps,
            max_impacts,
            buf.Q.ctypes.data,
            buf.P.ctypes.data,
            buf.E.ctypes.data,
            imp.ctypes.data,
            ctypes.byref(n_imp),
        )
        return done, n_imp.value

    return run


def casadi_runner(rule: str):
    sim = vcigen.build(
        load_example(HERE.parent / "examples" / "particle.py").model(), backend="casadi", rule=rule
    )

    def run(q0, steps: int, max_impacts: int) -> tuple[int, int]:
        r = sim.simulate(q0, V0, H, t_end=steps * H, n_impacts=max_impacts)
        return r.t.size - 1, len(r.impacts)

    return run


def measure(name: str, run, n_smooth: int, n_impacts: int, repeats: int) -> dict[str, float | str]:
    """ns per smooth step; us per impact from a run of 1 mm bounces (an impact every ~3 steps),
    its smooth steps subtracted: the impacts are most of its time, so the difference is not noise."""
    t_smooth = best_of(repeats, lambda: run(HIGH, n_smooth, 1))
    steps, got = run(HIGH, n_smooth, 1)
    assert got == 0 and steps == n_smooth, (name, steps, got)
    ns_step = t_smooth / n_smooth * 1e9
    steps, got = run(DENSE, 10_000_000, n_impacts)
    assert got == n_impacts, (name, got)
    t_dense = best_of(repeats, lambda: run(DENSE, 10_000_000, n_impacts))
    us_impact = (t_dense - (steps - n_impacts) * ns_step * 1e-9) / n_impacts * 1e6
    return {
        "variant": name,
        "ns_per_step": ns_step,
        "us_per_impact": us_impact,
        "steps": steps,
        "impacts": got,
    }


# ---- what a user sees from Python (issue 13): simulate and simulate_many as a user calls them ----------

N_USER_IMPACTS = 1000  # the paper's particle, h = 0.01
DP_Q0, DP_V0 = [0.3, 0.6], [1.5, 2.0]  # the double pendulum striking its wall (tests/hard_scenes.py)
N_MANY = 1000  # runs of simulate_many


def best_cpu(repeats: int, fn) -> float:
    """Smallest CPU time (``time.process_time``: the time this process ran, so a machine shared with
    other jobs inflates it far less than wall time) of ``repeats`` calls of ``fn``."""
    times = []
    for _ in range(repeats):
        t = time.process_time()
        fn()
        times.append(time.process_time() - t)
    return min(times)


def user_rows(repeats: int) -> list[dict[str, float | str]]:
    """CPU times of ``simulate`` / ``simulate_many`` calls (C backend, default options), best of
    ``repeats`` (wall time for the threads rows): the particle's 1000 impacts (``n_impacts=`` and the
    equivalent ``t_end=``, and the same steps high above the floor, so the difference is the cost of
    the impacts as Python sees them), and the fixed cost of a call on the double pendulum (0 and 33
    steps); ``simulate_many`` against a loop of ``simulate`` (skipped where the simulator has no
    ``simulate_many``)."""
    sys.path.insert(0, str(HERE.parent / "tests"))
    from hard_scenes import double_pendulum

    part = vcigen.build(load_example(HERE.parent / "examples" / "particle.py").model(), backend="c")
    res = part.simulate(Q0, V0, H, n_impacts=N_USER_IMPACTS)
    t_end, steps = float(res.t[-1]), res.t.size - 1
    t_n = best_cpu(repeats, lambda: part.simulate(Q0, V0, H, n_impacts=N_USER_IMPACTS))
    t_t = best_cpu(repeats, lambda: part.simulate(Q0, V0, H, t_end=t_end))
    t_s = best_cpu(repeats, lambda: part.simulate(HIGH, V0, H, t_end=t_end))
    t_read = best_cpu(repeats, lambda: [im.t for im in res.impacts])
    rows: list[dict[str, float | str]] = [
        {"what": f"particle n_impacts={N_USER_IMPACTS} ({steps} steps)", "us": t_n * 1e6},
        {"what": "particle, the same run by t_end", "us": t_t * 1e6},
        {"what": "particle, the same steps without impacts", "us": t_s * 1e6},
        {
            "what": "per impact seen from Python (n_impacts run - no impacts) / 1000",
            "us": (t_n - t_s) / N_USER_IMPACTS * 1e6,
        },
        {"what": "n_impacts run / t_end run (ratio)", "us": t_n / t_t},
        {"what": "reading every res.impacts[i].t, per impact", "us": t_read / N_USER_IMPACTS * 1e6},
    ]
    dp = vcigen.build(double_pendulum(), backend="c")
    reps = max(repeats, 200)  # short calls: many repeats, the best is the call without interference
    for te, label in ((0.0, "0 steps: the fixed cost"), (0.33, "33 steps, 1 impact")):
        rows.append(
            {
                "what": f"double pendulum simulate, {label}",
                "us": best_cpu(reps, lambda te=te: dp.simulate(DP_Q0, DP_V0, 0.01, t_end=te)) * 1e6,
            }
        )
    if not hasattr(dp, "simulate_many"):
        return rows
    rng = np.random.default_rng(1)
    q0s = np.array(DP_Q0) + 0.01 * rng.standard_normal((N_MANY, 2))
    v0s = np.tile(DP_V0, (N_MANY, 1))
    for te, label in ((0.0, "0 steps"), (0.33, "33 steps")):
        loop = best_cpu(repeats, lambda te=te: [dp.simulate(q, v, 0.01, t_end=te) for q, v in zip(q0s, v0s)])
        many = best_cpu(repeats, lambda te=te: dp.simulate_many(q0s, v0s, 0.01, t_end=te))
        rows.append(
            {"what": f"double pendulum, {label}: loop of simulate, per run", "us": loop / N_MANY * 1e6}
        )
        rows.append({"what": f"double pendulum, {label}: simulate_many, per run", "us": many / N_MANY * 1e6})
    for threads in (1, 2):
        many = best_of(repeats, lambda th=threads: dp.simulate_many(q0s, v0s, 0.01, t_end=3.3, threads=th))
        rows.append(
            {
                "what": f"double pendulum, 330 steps: simulate_many threads={threads}, per run",
                "us": many / N_MANY * 1e6,
            }
        )
    return rows


def user_main(repeats: int) -> None:
    """Print :func:`user_rows` and write ``bench/results/c_speed_user.csv``."""
    rows = user_rows(repeats)
    print(f"\n{'simulate as a user calls it (C backend; CPU time, threads rows wall time)':78s} {'us':>10s}")
    for r in rows:
        print(f"{r['what']:78s} {r['us']:10.2f}")
    out = HERE / "results" / "c_speed_user.csv"
    out.parent.mkdir(exist_ok=True)
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["what", "us"])
        w.writeheader()
        w.writerows(rows)
    print(f"written {out}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument(
        "--user-only", action="store_true", help="only simulate / simulate_many as a user calls them"
    )
    args = ap.parse_args(argv)
    if args.user_only:
        user_main(args.repeats)
        return 0
    buf = Buffers(N_SMOOTH_C + 1)
    rows = [
        measure(
            "handwritten C (Verlet + analytic)",
            handwritten_runner(buf),
            N_SMOOTH_C,
            N_IMPACTS_C,
            args.repeats,
        )
    ]
    for rule in ("trapezoid", "midpoint"):
        rows.append(
            measure(
                f"generated C, {rule}", generated_runner(rule, buf), N_SMOOTH_C, N_IMPACTS_C, args.repeats
            )
        )
    for rule in ("trapezoid", "midpoint"):
        rows.append(
            measure(
                f"CasADi, {rule}",
                casadi_runner(rule),
                N_SMOOTH_CASADI,
                N_IMPACTS_CASADI,
                max(1, args.repeats // 2),
            )
        )
    hw = rows[0]
    casadi = {r["variant"].split(", ")[1]: r for r in rows if str(r["variant"]).startswith("CasADi")}
    for r in rows:
        r["step_vs_handwritten"] = r["ns_per_step"] / hw["ns_per_step"]
        r["impact_vs_handwritten"] = r["us_per_impact"] / hw["us_per_impact"]
        rule = str(r["variant"]).split(", ")[-1]
        r["casadi_over_this_step"] = (
            casadi[rule]["ns_per_step"] / r["ns_per_step"] if rule in casadi else float("nan")
        )
    print(
        f"{'variant':36s} {'ns/step':>10s} {'us/impact':>10s} {'x hw step':>10s} {'x hw impact':>12s} "
        f"{'CasADi/this':>12s}"
    )
    for r in rows:
        print(
            f"{r['variant']:36s} {r['ns_per_step']:10.1f} {r['us_per_impact']:10.3f} "
            f"{r['step_vs_handwritten']:10.2f} "
            f"{r['impact_vs_handwritten']:12.1f} {r['casadi_over_this_step']:12.0f}"
        )
    out = HERE / "results" / "c_speed.csv"
    out.parent.mkdir(exist_ok=True)
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"written {out}")
    gen = [r for r in rows if str(r["variant"]).startswith("generated")]
    ok = all(r["step_vs_handwritten"] <= 1.5 for r in gen) and all(
        r["casadi_over_this_step"] >= 100 for r in gen
    )
    print("targets (<= 1.5x hand-written per step, >= 100x CasADi):", "met" if ok else "NOT met")
    user_main(args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
