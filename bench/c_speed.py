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
``simulate_many`` against a loop of ``simulate`` (per run), with 1 and 2 threads, and its CPU time per
run beyond the generated C loop (``<model>_run_many``'s own time subtracted). Writes
``bench/results/c_speed_user.csv``. From a worktree other than the installed one, run it with
``PYTHONPATH=.`` (the script's folder, not the cwd, is first on ``sys.path``).

Every variant stores the same output (q, p, energy per step) into preallocated
buffers; the best of ``--repeats`` runs counts. Prints a table with ratios and
writes ``bench/results/c_speed.csv``. Targets: generated C within 1.5x of the
hand-written loop per smooth step; C >= 100x faster per step than CasADi.

Models without explicit structure (issue 14; ``--only chain`` for this table alone, written to
``bench/results/c_speed_chain.csv``): the double and triple pendulum (``chain_model``), h = 1e-3,
both rules, ns per smooth step of ``bench/handwritten/chain.c`` (Newton with the hand-derived
Jacobian), the generated C, the CasADi backend, a plain ``casadi.rootfinder`` loop and the CasADi
kernel alone, the variants timed in turn; and us per impact of the generated C on the double
pendulum against the wall (``pendulum_wall``). Target: generated C within 1.5x of the hand loop.
"""

from __future__ import annotations

import argparse
import csv
import ctypes
import math
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


def write_rows(out: Path, rows: list[dict]) -> None:
    """``rows`` (dicts with the same keys) as a CSV at ``out``."""
    out.parent.mkdir(exist_ok=True)
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"written {out}")


def best_of(repeats: int, fn) -> float:
    """Smallest wall time of ``repeats`` calls of ``fn``."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


class Buffers:
    """Preallocated, touched output buffers shared by the C variants (``n`` coordinates)."""

    def __init__(self, steps: int, n: int = 2) -> None:
        self.Q, self.P, self.E = np.zeros((steps, n)), np.zeros((steps, n)), np.zeros(steps)
        self.rec = np.zeros((IMPACT_CAP, 10))  # t, contact, step, alpha, impulse, E before/after, q (2), kind
        self.A = np.zeros(steps, dtype=np.uint8)  # active contact per step (the one contact)
        self.F, self.FC = np.zeros(steps), np.zeros(steps)  # its mean force, the constraint forces (none)


def generated_runner(rule: str, buf: Buffers, model=None, h: float = H, v0=V0):
    """``run(q0, steps, max_impacts) -> (steps, impacts)`` over the generated ``<model>_run`` (the
    particle's unless ``model`` is given, started with velocity ``v0``, step ``h``)."""
    if model is None:
        model = load_example(HERE.parent / "examples" / "particle.py").model()
    sim = vcigen.build(model, backend="c", rule=rule)
    kern = sim.kernels.bind(sim.model.resolve_params(None))
    tol = _tol_struct(sim.tol)
    lift = np.zeros((IMPACT_CAP, 2))

    def run(q0, steps: int, max_impacts: int, calls: list | None = None) -> tuple[int, int]:
        """``calls``: one step per call of ``<model>_run``, each call's (wall time, impacts) appended."""
        q, v = np.array(q0, dtype=float), np.array(v0, dtype=float)
        p = kern.legendre(q, v)[0].copy()
        err, sd, idone = _Err(), ctypes.c_long(0), ctypes.c_long(0)
        sus = kern.Sustain()  # no contact held at the start (the runs start in free flight)
        sus.liftoffs, sus.liftoff_cap = _ptr(lift), IMPACT_CAP
        done = impacts = 0
        while done < steps and impacts < max_impacts:  # the impact buffer is drained between chunks
            t = time.perf_counter()
            rc = kern.run(
                _ptr(kern.par),
                ctypes.byref(tol),
                h,
                0.0,
                done,
                steps - done if calls is None else 1,
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
            if calls is not None:
                calls.append((time.perf_counter() - t, idone.value))
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


# ------------------------------------------------------ models without explicit structure (issue 14)

CHAIN_H, CHAIN_G = 1e-3, 9.81
CHAIN_FAR = 10.0  # a wall the chain cannot reach: smooth steps only
CHAIN_START = {2: ([0.4, -0.3], [1.0, -0.5]), 3: ([0.4, -0.3, 0.2], [1.0, -0.5, 0.8])}
N_CHAIN_C, N_CHAIN_CASADI, N_AGREE = 200_000, 2_000, 5_000
PW_Q0, PW_V0, PW_H = [0.0, 0.0], [6.0, 8.0], 0.005  # the scene bench.scenes.pendulum_wall
N_STEPWISE = 60_000  # single-step calls for the cost per impact


def chain_model(n: int, wall: float):
    """``n`` unit point masses on unit rods, angles from the downward vertical, the wall ``x = wall``
    (n = 2 is ``tests/hard_scenes.double_pendulum``): ``M_ij = l_i l_j sum_{k >= max(i, j)} m_k
    cos(q_i - q_j)``."""
    import sympy as sp

    q = sp.symbols(f"theta1:{n + 1}")
    w = sp.symbols(f"omega1:{n + 1}")
    x = sum(sp.sin(q[i]) for i in range(n))
    kinetic = sum(
        sp.Rational(n - max(i, j), 2) * w[i] * w[j] * sp.cos(q[i] - q[j]) for i in range(n) for j in range(n)
    )
    potential = -CHAIN_G * sum((n - i) * sp.cos(q[i]) for i in range(n))
    return vcigen.Model(
        name=f"chain{n}", q=list(q), qdot=list(w), lagrangian=kinetic - potential, contacts={"wall": wall - x}
    )


def handwritten_chain_runner(n: int, rule: str, buf: Buffers):
    """``run(q0, steps, max_impacts)`` over ``bench/handwritten/chain.c`` (``CHAIN_N = n``): Newton on v with
    the hand-derived Jacobian, the far wall checked at each step end."""
    out = Path(tempfile.mkdtemp(prefix="vcigen-hw-")) / f"libhw_chain{n}.so"
    flags = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared", f"-DCHAIN_N={n}"]
    subprocess.run(["cc", *flags, "-o", str(out), str(HERE / "handwritten" / "chain.c"), "-lm"], check=True)
    f = getattr(ctypes.CDLL(str(out)), f"hw_chain_{rule}")
    f.restype = ctypes.c_long
    f.argtypes = [ctypes.c_void_p] * 2 + [ctypes.c_double] * 2 + [ctypes.c_void_p] * 2 + [ctypes.c_double]
    f.argtypes += [ctypes.c_long] + [ctypes.c_void_p] * 3
    ones = np.ones(n)
    v0 = np.array(CHAIN_START[n][1])

    def run(q0, steps: int, max_impacts: int) -> tuple[int, int]:
        q = np.array(q0, dtype=float)
        args = (
            ones.ctypes.data,
            ones.ctypes.data,
            CHAIN_G,
            CHAIN_FAR,
            q.ctypes.data,
            v0.ctypes.data,
            CHAIN_H,
        )
        done = f(*args, steps, buf.Q.ctypes.data, buf.P.ctypes.data, buf.E.ctypes.data)
        return done, 0

    return run


def casadi_chain_runner(n: int, rule: str):
    sim = vcigen.build(chain_model(n, CHAIN_FAR), backend="casadi", rule=rule)
    v0 = CHAIN_START[n][1]

    def run(q0, steps: int, max_impacts: int) -> tuple[int, int]:
        r = sim.simulate(q0, v0, CHAIN_H, t_end=steps * CHAIN_H, n_impacts=max_impacts)
        return r.t.size - 1, len(r.impacts)

    return run


def interleaved(runs: dict[str, object], q0, steps: int, max_impacts: int, repeats: int) -> dict[str, float]:
    """Smallest wall time of each of ``runs`` over ``repeats`` rounds, the variants taken in turn in each
    round (on a loaded machine the load drifts; a ratio of two variants timed apart would carry it)."""
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(repeats):
        for name, run in runs.items():
            t = time.perf_counter()
            run(q0, steps, max_impacts)
            best[name] = min(best[name], time.perf_counter() - t)
    return best


def casadi_limit_runner(n: int, rule: str):
    """The CasADi backend's limit: a plain Python loop over ``casadi.rootfinder`` ('newton', the backend's
    options) on the same smooth residual (46), then ``p+`` and ``E_d`` (segment) and ``phi`` at the step end,
    each a CasADi call on numpy arrays; no detection beyond ``phi >= 0``, no checks, stored as the others."""
    import casadi as ca

    from vcigen.backends.casadi import NEWTON_OPTIONS, routine_to_function

    system = vcigen.derive(chain_model(n, CHAIN_FAR), rule)
    smooth = routine_to_function(system.routines["smooth"])
    segment = routine_to_function(system.routines["segment"])
    contacts = routine_to_function(system.routines["contacts"])
    x, q0, p0, par = (
        ca.MX.sym("x", n),
        ca.MX.sym("q0", n),
        ca.MX.sym("p0", n),
        ca.MX.sym("par", len(system.params)),
    )
    h = ca.MX.sym("h")
    g = ca.Function("g", [x, ca.vertcat(q0, p0, h, par)], [smooth(x, q0, p0, h, par)[0]])
    rf = ca.rootfinder("smooth_newton", "newton", g, NEWTON_OPTIONS)
    pars = np.array(vcigen.Model.resolve_params(chain_model(n, CHAIN_FAR), None), dtype=float)
    v0 = np.array(CHAIN_START[n][1])

    def run(q_start, steps: int, max_impacts: int) -> tuple[int, int]:
        q, v = np.array(q_start, dtype=float), v0.copy()
        p = np.array(routine_to_function(system.routines["legendre"])(q, v, pars)[0]).ravel()
        Q, P, E = np.empty((steps, n)), np.empty((steps, n)), np.empty(steps)
        for k in range(steps):
            v = np.array(rf(v, np.concatenate([q, p, [CHAIN_H], pars]))).ravel()
            _, p1, e = segment(q, v, CHAIN_H, pars)
            q = q + CHAIN_H * v
            p = np.array(p1).ravel()
            Q[k], P[k], E[k] = q, p, float(e)
            if float(contacts(q, pars)[0][0]) < 0:
                return k + 1, 1
        return steps, 0

    return run


def casadi_kernel_runner(n: int, rule: str):
    """The CasADi backend's kernel alone: ``Kernels.smooth_step`` (one Function call per step) in a bare
    Python loop, stored as the others; against the backend's ``simulate``, the Python stepper's share."""
    sim = vcigen.build(chain_model(n, CHAIN_FAR), backend="casadi", rule=rule)
    kern = sim.kernels.bind(sim.model.resolve_params(None))
    v0 = np.array(CHAIN_START[n][1])

    def run(q_start, steps: int, max_impacts: int) -> tuple[int, int]:
        q, v = np.array(q_start, dtype=float), v0.copy()
        p = kern.legendre(q, v)[0]
        Q, P, E = np.empty((steps, n)), np.empty((steps, n)), np.empty(steps)
        for k in range(steps):
            v, _, p, e, _, phi1, _, _ = kern.smooth_step(q, p, CHAIN_H, v)
            q = q + CHAIN_H * v
            Q[k], P[k], E[k] = q, p, e
            if phi1.min() < 0:
                return k + 1, 1
        return steps, 0

    return run


def smooth_ns(runs: dict[str, object], q0, steps: int, repeats: int) -> dict[str, float]:
    """ns per smooth step of each of ``runs`` from ``q0``; asserts no impact and no early stop."""
    for name, run in runs.items():
        done, got = run(q0, steps, 1)
        assert got == 0 and done == steps, (name, done, got)
    return {name: t / steps * 1e9 for name, t in interleaved(runs, q0, steps, 1, repeats).items()}


def chain_rows(repeats: int) -> list[dict[str, float | str]]:
    """Per model (double and triple pendulum) and rule: ns per smooth step of the hand-written loop, the
    generated C and the CasADi backend, and the largest |q| difference of the generated C from the hand
    loop over the first ``N_AGREE`` steps (same trajectory to solver tolerance)."""
    rows: list[dict[str, float | str]] = []
    for n in (2, 3):
        q0 = CHAIN_START[n][0]
        buf, ref = Buffers(N_CHAIN_C + 1, n), Buffers(N_AGREE, n)
        model = chain_model(n, CHAIN_FAR)
        for rule in ("trapezoid", "midpoint"):
            hw = handwritten_chain_runner(n, rule, buf)
            gen = generated_runner(rule, buf, model=model, h=CHAIN_H, v0=CHAIN_START[n][1])
            ns = smooth_ns({"hand": hw, "generated": gen}, q0, N_CHAIN_C, repeats)
            hand_ns, gen_ns = ns["hand"], ns["generated"]
            casadi = {
                "casadi": casadi_chain_runner(n, rule),
                "limit": casadi_limit_runner(n, rule),
                "kernel": casadi_kernel_runner(n, rule),
            }
            cas = smooth_ns(casadi, q0, N_CHAIN_CASADI, max(1, repeats // 2))
            casadi_ns = cas["casadi"]
            handwritten_chain_runner(n, rule, ref)(q0, N_AGREE, 1)
            gen(q0, N_AGREE, 1)
            dq = float(np.max(np.abs(buf.Q[:N_AGREE] - ref.Q)))
            rows.append(
                {
                    "model": f"chain{n}",
                    "rule": rule,
                    "hand_ns": hand_ns,
                    "generated_ns": gen_ns,
                    "generated_vs_hand": gen_ns / hand_ns,
                    "casadi_ns": casadi_ns,
                    "casadi_limit_ns": cas["limit"],
                    "casadi_vs_limit": casadi_ns / cas["limit"],
                    "casadi_vs_kernel": casadi_ns / cas["kernel"],
                    "casadi_vs_generated": casadi_ns / gen_ns,
                    "max_dq": dq,
                }
            )
    return rows


def per_impact_us(run, q0, steps: int) -> tuple[float, int]:
    """us per impact from ``steps`` single-step calls of ``<model>_run``: the median call with an impact
    less the median call without (the same call overhead and the same trajectory in both, so neither
    the call nor a different smooth trajectory enters the figure); and the number of impacts."""
    calls: list[tuple[float, int]] = []
    run(q0, steps, 10**9, calls)
    t = np.array([c[0] for c in calls])
    hit = np.array([c[1] > 0 for c in calls])
    assert hit.sum() > 20, hit.sum()
    return float(np.median(t[hit]) - np.median(t[~hit])) * 1e6, int(hit.sum())


def pendulum_impact_rows() -> list[dict[str, float | str]]:
    """us per impact of the generated C on the double pendulum against the wall x = 1.2 (the scene
    ``pendulum_wall``, h = 0.005, an impact every ~200 steps), both rules, by :func:`per_impact_us`. (The
    particle's, in its own table, subtracts its smooth steps from a run of 1 mm bounces instead: its
    impact, 0.2 us, is below the resolution of one call.)"""
    rows: list[dict[str, float | str]] = []
    for rule in ("trapezoid", "midpoint"):
        run = generated_runner(rule, Buffers(N_STEPWISE + 1, 2), model=chain_model(2, 1.2), h=PW_H, v0=PW_V0)
        us, got = per_impact_us(run, PW_Q0, N_STEPWISE)
        rows.append({"model": "double pendulum", "rule": rule, "us_per_impact": us, "impacts": got})
    return rows


def print_chain(rows, impacts) -> None:
    print(
        f"\n{'model':8s} {'rule':10s} {'hand ns':>9s} {'gen ns':>9s} {'gen/hand':>9s} {'CasADi ns':>10s} "
        f"{'CasADi/gen':>10s} {'limit ns':>10s} {'CasADi/lim':>10s} {'CasADi/krn':>10s} {'max |dq|':>9s}"
    )
    for r in rows:
        print(
            f"{r['model']:8s} {r['rule']:10s} {r['hand_ns']:9.1f} {r['generated_ns']:9.1f} "
            f"{r['generated_vs_hand']:9.2f} {r['casadi_ns']:10.0f} {r['casadi_vs_generated']:10.0f} "
            f"{r['casadi_limit_ns']:10.0f} {r['casadi_vs_limit']:10.2f} {r['casadi_vs_kernel']:10.2f} "
            f"{r['max_dq']:9.1e}"
        )
    for r in impacts:
        print(
            f"generated C, {r['model']}, {r['rule']}: {r['us_per_impact']:.2f} us per impact "
            f"(median of {r['impacts']} impact steps less the median smooth step, one step per call)"
        )
    write_rows(HERE / "results" / "c_speed_chain.csv", rows)


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


def cpu_beyond_c(repeats: int, fn, kern) -> tuple[float, float]:
    """``(total, total - C)`` of the call of ``fn`` with the smallest CPU time among ``repeats``, where C
    is the CPU time spent inside ``kern.run_many`` (the generated C loop: the steps themselves)."""
    raw, inside = kern.run_many, [0.0]

    def timed(*args):
        t = time.process_time()
        raw(*args)
        inside[0] += time.process_time() - t

    kern.run_many = timed
    try:
        best = (math.inf, math.inf)
        for _ in range(repeats):
            inside[0] = 0.0
            t = time.process_time()
            fn()
            total = time.process_time() - t
            best = min(best, (total, total - inside[0]))
    finally:
        kern.run_many = raw
    return best


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
    _, beyond = cpu_beyond_c(repeats, lambda: dp.simulate_many(q0s, v0s, 0.01, t_end=0.33), dp.kernels)
    rows.append(
        {
            "what": "double pendulum, 33 steps: simulate_many, per run beyond the C loop (run_many)",
            "us": beyond / N_MANY * 1e6,
        }
    )
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
    write_rows(HERE / "results" / "c_speed_user.csv", rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--only", choices=("particle", "chain"), help="one table only")
    ap.add_argument(
        "--user-only", action="store_true", help="only simulate / simulate_many as a user calls them"
    )
    args = ap.parse_args(argv)
    if args.user_only:
        user_main(args.repeats)
        return 0
    if args.only != "particle":
        chain = chain_rows(args.repeats)
        print_chain(chain, pendulum_impact_rows())
        chain_ok = all(r["generated_vs_hand"] <= 1.5 for r in chain)
        print(
            "chain target (generated <= 1.5x hand-written per smooth step):", "met" if chain_ok else "NOT met"
        )
    if args.only == "chain":
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
    write_rows(HERE / "results" / "c_speed.csv", rows)
    gen = [r for r in rows if str(r["variant"]).startswith("generated")]
    ok = all(r["step_vs_handwritten"] <= 1.5 for r in gen) and all(
        r["casadi_over_this_step"] >= 100 for r in gen
    )
    print("targets (<= 1.5x hand-written per step, >= 100x CasADi):", "met" if ok else "NOT met")
    user_main(args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
