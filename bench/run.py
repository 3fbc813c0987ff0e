"""Speed against error, side by side (issue 5): ``make bench`` / ``vcigen bench``.

Sweeps the step size ``h`` (the step methods) and ``rtol`` (the event-driven
``solve_ivp`` methods) on four scenes and measures, per run: wall time of the
integration, position error at a fixed time after the first collision and after
a few impacts (against a reference), maximum energy deviation, energy drift,
impacts missed or spurious, and the largest constraint violation. Then long
runs (energy against time over >= 1e5 steps, drift after 1e6 steps with the C
backend). Writes ``bench/results/``: ``<scene>.csv``, ``longrun.csv``,
``wp_<scene>.png``, ``energy_<scene>.png``, ``summary.md``.

Every run starts at one of several *start phases* ``tau_j`` in ``[0, 0.02)``
(the reference state at ``tau_j``) and is evaluated at ``tau_j + T``, so the
first impact falls at different places inside a step; errors are RMS over the
phases, wall times the median. Under linear gravity free flight is exact for
every method here, so ``particle`` and ``star`` measure only impact handling;
``star_nonlinear`` and ``pendulum_wall`` measure accuracy.

Usage: ``python bench/run.py [--scenes a,b] [--methods m,n] [--hs 0.01,0.005]
[--rtols 1e-6,1e-10] [--phases 8] [--no-long] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import importlib.util
import math
import platform
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from bench import baselines, reference  # noqa: E402
from bench import scenes as bench_scenes  # noqa: E402
from bench.scenes import Scene  # noqa: E402

Array = np.ndarray
GOLDEN = 0.6180339887498949
TAU_SPAN = 0.02  # start phases tau_j = TAU_SPAN * frac(j * golden ratio)
SCIPY_GRID = 0.01  # the event-driven runs are sampled on tau + k * SCIPY_GRID
MATCH_TOL = 0.05  # an impact matches a reference impact within this many seconds
DEFAULT_OUT = ROOT / "bench" / "results"
CSV_COLUMNS = [
    "scene",
    "method",
    "h_or_tol",
    "phases",
    "wall_s",
    "steps",
    "err_first",
    "err_few",
    "energy_dev",
    "drift",
    "missed",
    "spurious",
    "max_violation",
    "impacts",
    "note",
]


@dataclass(frozen=True)
class Setup:
    """Per scene: evaluation times after the first collision and after a few impacts."""

    t_first: float
    t_few: float
    hs: tuple[float, ...]
    long_h: float | None = None  # step of the long runs (None: no long run)


SETUPS: dict[str, Setup] = {
    # particle impacts at 0.45, 1.35, 2.26, 3.16
    "particle": Setup(0.8, 2.5, (0.02, 0.01, 0.005, 0.0025, 0.00125), long_h=0.01),
    # star (linear gravity) impacts at 0.756, 2.263, 3.029, 4.405
    "star": Setup(1.5, 3.5, (0.02, 0.01, 0.005, 0.0025, 0.00125), long_h=0.005),
    # star, V = -m g R^2/(R+y): a pair at 1.239 / 1.248 (second vertex), then 2.758, 3.159
    "star_nonlinear": Setup(2.0, 3.5, (0.02, 0.01, 0.005, 0.0025, 0.00125, 0.000625)),
    # double pendulum against a wall: impacts at 0.094, 0.822, 1.611, 2.481
    "pendulum_wall": Setup(0.5, 2.0, (0.02, 0.01, 0.005, 0.0025, 0.00125)),
}
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)


# ------------------------------------------------------------------ methods


@dataclass(frozen=True)
class Method:
    name: str
    kind: str  # "h" (step size) or "rtol"
    label: str
    style: str = "o-"


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("vcigen_c_trapezoid", "h", "vcigen C, trapezoid", "o-"),
        Method("vcigen_c_midpoint", "h", "vcigen C, midpoint", "s-"),
        Method("vcigen_casadi_trapezoid", "h", "vcigen CasADi, trapezoid", "D--"),
        Method("dop853_events", "rtol", "DOP853 + events", "^-"),
        Method("dop853_events_ms", "rtol", "DOP853 + events, max_step 0.01", "<-"),
        Method("rk45_events", "rtol", "RK45 + events", "v-"),
        Method("verlet_full_flip", "h", "naive Verlet, full-step flip", "x-"),
        Method("verlet_half_flip", "h", "naive Verlet, half-step flip", "+-"),
        Method("siconos_mj", "h", "Siconos Moreau-Jean", "*-"),
    )
}


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


class VcigenSims:
    """Builds (once) and caches ``vcigen`` simulators; remembers why a backend cannot run."""

    def __init__(self) -> None:
        self.cache: dict[tuple[str, str, str], object] = {}
        self.build_time: dict[tuple[str, str, str], float] = {}

    @staticmethod
    def backend_missing(backend: str) -> str | None:
        if backend == "c" and importlib.util.find_spec("vcigen.backends.c") is None:
            return "vcigen C backend not available (module vcigen.backends.c does not exist yet)"
        return None

    def get(self, scene: Scene, backend: str, rule: str):
        """The simulator, or a string saying why it cannot be built."""
        key = (scene.name, backend, rule)
        if key not in self.cache:
            reason = self.backend_missing(backend)
            if reason is None:
                import vcigen

                start = time.perf_counter()
                try:
                    self.cache[key] = vcigen.build(scene.vcigen_model(), backend=backend, rule=rule)
                except Exception as exc:  # noqa: BLE001 - any failure becomes a skip message
                    self.cache[key] = f"vcigen {backend}/{rule} build failed: {type(exc).__name__}: {exc}"
                self.build_time[key] = time.perf_counter() - start
            else:
                self.cache[key] = reason
        return self.cache[key]


def _vcigen_runs(sims: VcigenSims, method: str, scene: Scene, h: float, starts, t_rel: float) -> list[dict]:
    _, backend, rule = method.split("_", 2)
    sim = sims.get(scene, backend, rule)
    if isinstance(sim, str):
        return [{"skip": sim}] * len(starts)
    out = []
    for tau, q0, v0 in starts:
        try:
            res = sim.simulate(q0, v0, h, t_end=tau + t_rel, t0=tau)
        except Exception as exc:  # noqa: BLE001 - a SolverError is a result too
            out.append({"fail": f"{type(exc).__name__}: {str(exc)[:200]}"})
            continue
        out.append(
            {
                "t": res.t,
                "q": res.q,
                "energy": res.energy,
                "impacts": [i.t for i in res.impacts],
                "wall": float(res.stats["wall_time"]),
                "steps": res.t.size - 1,
            }
        )
    return out


def _baseline_runs(method: str, scene: Scene, x: float, starts, t_rel: float) -> list[dict]:
    if method == "siconos_mj":
        jobs = [(x, q0, v0, t_rel) for _, q0, v0 in starts]
        raw = baselines.run_siconos_batch(scene, jobs)
    else:
        raw = []
        for _, q0, v0 in starts:
            sc = dataclasses.replace(scene, q0=np.asarray(q0, float), v0=np.asarray(v0, float))
            kw = {"grid_h": SCIPY_GRID} if METHODS[method].kind == "rtol" else {}
            try:
                raw.append(baselines.METHODS[method](sc, x, t_end=t_rel, **kw))
            except Exception as exc:  # noqa: BLE001
                raw.append({"fail": f"{type(exc).__name__}: {str(exc)[:200]}"})
    out = []
    for (tau, _, _), r in zip(starts, raw):
        if "skip" in r or "fail" in r:
            out.append(r)
            continue
        steps = r["t"].size - 1 if METHODS[method].kind == "h" else r.get("nfev", 0)
        out.append(
            {
                "t": r["t"] + tau,
                "q": r["q"],
                "energy": r["energy"],
                "impacts": [tau + ti for ti in r["impacts"]],
                "wall": float(r["wall"]),
                "steps": steps,
                "fell_through": bool(r.get("fell_through", False)),
                "stalled": r.get("stalled"),
            }
        )
    return out


def run_method(sims: VcigenSims, method: str, scene: Scene, x: float, starts, t_rel: float) -> list[dict]:
    """One result dict per start ``(tau, q0, v0)``: ``t`` (absolute), ``q``, ``energy``,
    ``impacts`` (absolute times), ``wall``; or ``{"skip": why}`` / ``{"fail": why}``."""
    if method.startswith("vcigen_"):
        return _vcigen_runs(sims, method, scene, x, starts, t_rel)
    return _baseline_runs(method, scene, x, starts, t_rel)


# ------------------------------------------------------------------ reference


def phases(n: int) -> list[float]:
    """Start times ``tau_j = TAU_SPAN * frac(j * golden)``: spread for every dyadic ``h``."""
    return [TAU_SPAN * ((j * GOLDEN) % 1.0) for j in range(n)]


def reference_states(scene: Scene, times: Array, n_impacts_cap: int = 50) -> reference.Trajectory:
    """The scene's reference at sorted ``times`` (closed form / exact flight / DOP853 1e-13)."""
    if scene.name == "particle":
        return reference.particle_closed_form(times, q0=tuple(scene.q0), v0=tuple(scene.v0))
    if scene.name == "star":
        return reference.star_exact(times)
    return reference.event_driven(scene, times, rtol=1e-13, atol=1e-13)


def min_phi(scene: Scene, q: Array) -> float:
    """Smallest contact value over the rows of ``q``."""
    if q.size == 0:
        return 0.0
    return float(min(np.min(np.asarray(c.phi(q.T), float)) for c in scene.contacts))


def match_impacts(ref: Sequence[float], got: Sequence[float], tol: float = MATCH_TOL) -> tuple[int, int]:
    """``(missed, spurious)``: greedy in-order matching of impact times within ``tol``."""
    used = [False] * len(got)
    missed = 0
    for tr in ref:
        best = None
        for i, tg in enumerate(got):
            if not used[i] and abs(tg - tr) <= tol and (best is None or abs(tg - tr) < abs(got[best] - tr)):
                best = i
        if best is None:
            missed += 1
        else:
            used[best] = True
    return missed, used.count(False)


def relative_drift(t: Array, energy: Array) -> float:
    """Least-squares slope of ``(E - E0)/|E0|`` per unit time."""
    if energy.size < 3:
        return float("nan")
    e0 = energy[0] if energy[0] != 0 else 1.0
    return float(np.polyfit(t[: energy.size] - t[0], (energy - energy[0]) / abs(e0), 1)[0])


# ------------------------------------------------------------------ sweep


@dataclass
class Row:
    scene: str
    method: str
    x: float
    phases: int
    wall: float = float("nan")
    steps: float = float("nan")
    err_first: float = float("nan")
    err_few: float = float("nan")
    energy_dev: float = float("nan")
    drift: float = float("nan")
    missed: float = float("nan")
    spurious: float = float("nan")
    max_violation: float = float("nan")
    impacts: float = float("nan")
    note: str = ""

    def csv(self) -> list[str]:
        vals = [
            self.scene,
            self.method,
            f"{self.x:.6g}",
            str(self.phases),
            *(
                f"{v:.6g}"
                for v in (
                    self.wall,
                    self.steps,
                    self.err_first,
                    self.err_few,
                    self.energy_dev,
                    self.drift,
                    self.missed,
                    self.spurious,
                    self.max_violation,
                    self.impacts,
                )
            ),
            self.note,
        ]
        return vals


def _state_at(run: dict, t_abs: float) -> Array | None:
    k = int(np.argmin(np.abs(run["t"] - t_abs)))
    if abs(run["t"][k] - t_abs) > 1e-7:
        return None
    return run["q"][k]


def evaluate(scene: Scene, setup: Setup, method: str, x: float, runs: list[dict], ref: dict) -> Row:
    """Aggregate the runs of one (method, h or rtol) over the start phases."""
    row = Row(scene.name, method, x, len(runs))
    skips = [r for r in runs if "skip" in r]
    if skips:
        row.note = "skip: " + skips[0]["skip"]
        return row
    fails = [r for r in runs if "fail" in r]
    ok = [r for r in runs if "fail" not in r]
    notes = [f"{len(fails)}/{len(runs)} runs failed: {fails[0]['fail']}"] if fails else []
    if not ok:
        row.note = "; ".join(notes)
        return row
    e1, e3, dev, drift, miss, spur, viol, nimp = [], [], [], [], [], [], [], []
    for r, (tau, _, _) in zip(runs, ref["starts"]):
        if "fail" in r:
            continue
        for target, bucket in ((setup.t_first, e1), (setup.t_few, e3)):
            qa = _state_at(r, tau + target)
            bucket.append(np.inf if qa is None else float(np.linalg.norm(qa - ref["q"][tau + target])))
        en = np.asarray(r["energy"], float)
        e0 = en[0] if en[0] != 0 else 1.0
        dev.append(float(np.max(np.abs(en - en[0])) / abs(e0)))
        drift.append(relative_drift(r["t"], en))
        window = [ti for ti in r["impacts"] if ti <= tau + setup.t_few + 1e-12]
        m, s = match_impacts(ref["impacts"][tau], window)
        miss.append(m)
        spur.append(s)
        viol.append(max(0.0, -min_phi(scene, r["q"])))
        nimp.append(len(window))
    if any(r.get("fell_through") for r in ok):
        notes.append(f"fell through the contact in {sum(bool(r.get('fell_through')) for r in ok)} run(s)")
    stalled = [r["stalled"] + tau for r, (tau, _, _) in zip(runs, ref["starts"]) if r.get("stalled")]
    if stalled:
        notes.append(
            f"stuck re-impacting at one instant (kink chatter) in {len(stalled)} run(s), t = {stalled[0]:.4g}"
        )
    e1a, e3a = np.array(e1), np.array(e3)
    row.err_first = float(np.sqrt(np.mean(e1a**2))) if not fails else float("nan")
    row.err_few = float(np.sqrt(np.mean(e3a**2))) if not fails else float("nan")
    if np.isinf(row.err_first):
        row.err_first = float("nan")
    if np.isinf(row.err_few):
        row.err_few = float("nan")
    row.wall = float(np.median([r["wall"] for r in ok]))
    row.steps = float(np.median([r["steps"] for r in ok]))
    row.energy_dev = max(dev)
    row.drift = float(np.median(drift))
    row.missed, row.spurious = float(max(miss)), float(max(spur))
    row.max_violation = max(viol)
    row.impacts = float(np.mean(nimp))
    row.note = "; ".join(notes)
    return row


def scene_reference(scene: Scene, setup: Setup, n_phases: int) -> dict:
    """Reference states at every start and evaluation time; impacts inside each run's window."""
    taus = phases(n_phases)
    times = sorted({*taus, *(t + setup.t_first for t in taus), *(t + setup.t_few for t in taus)})
    traj = reference_states(scene, np.array(times))
    if traj.t.size != len(times):
        raise RuntimeError(f"{scene.name}: reference stopped at t={traj.t[-1] if traj.t.size else 0}")
    q_at = {t: traj.q[i] for i, t in enumerate(times)}
    v_at = {t: traj.v[i] for i, t in enumerate(times)}
    imp = traj.impact_times
    return {
        "starts": [(tau, q_at[tau], v_at[tau]) for tau in taus],
        "q": q_at,
        "impacts": {tau: [float(t) for t in imp if tau < t <= tau + setup.t_few] for tau in taus},
    }


def sweep_scene(
    sims: VcigenSims, scene: Scene, setup: Setup, methods: Sequence[str], rtols, n_phases: int, counter
) -> list[Row]:
    start = time.perf_counter()
    ref = scene_reference(scene, setup, n_phases)
    log(f"[bench] {scene.name}: reference in {time.perf_counter() - start:.1f}s, {n_phases} start phases")
    rows: list[Row] = []
    for method in methods:
        xs = setup.hs if METHODS[method].kind == "h" else rtols
        for x in xs:
            counter[0] += 1
            t0 = time.perf_counter()
            runs = run_method(sims, method, scene, x, ref["starts"], setup.t_few)
            row = evaluate(scene, setup, method, x, runs, ref)
            rows.append(row)
            log(
                f"[bench {counter[0]:3d}/{counter[1]}] {scene.name:15s} {method:24s} {x:<9.3g} "
                f"err1 {row.err_first:9.2e} err3 {row.err_few:9.2e} wall {row.wall:9.2e}s "
                f"dE {row.energy_dev:8.1e} miss {row.missed:g} viol {row.max_violation:7.1e} "
                f"({time.perf_counter() - t0:.1f}s) {row.note[:90]}"
            )
            if row.note.startswith("skip"):
                counter[0] += len(xs) - 1 - xs.index(x)
                break
    return rows


def write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[object]]) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


# ------------------------------------------------------------------ long runs


@dataclass
class LongRun:
    scene: str
    method: str
    h: float
    steps: int
    wall: float = float("nan")
    impacts: int = 0
    energy_dev: float = float("nan")
    drift: float = float("nan")  # fitted relative change of E over the whole run
    min_phi: float = float("nan")
    note: str = ""
    t: Array = field(default_factory=lambda: np.empty(0), repr=False)
    rel_e: Array = field(default_factory=lambda: np.empty(0), repr=False)


LONG_COLUMNS = [
    "scene",
    "method",
    "h",
    "steps",
    "wall_s",
    "impacts",
    "energy_dev",
    "drift",
    "min_phi",
    "note",
]


def long_run(sims: VcigenSims, scene: Scene, method: str, h: float, steps: int) -> LongRun:
    """One run of ``steps * h`` seconds from the scene's start; energy kept for the plot."""
    lr = LongRun(scene.name, method, h, steps)
    t_end = steps * h
    if method.startswith("vcigen_"):
        runs = _vcigen_runs(sims, method, scene, h, [(0.0, scene.q0, scene.v0)], t_end)
    else:
        sc = scene
        kw = {"grid_h": h} if METHODS[method].kind == "rtol" else {}
        x = 1e-10 if METHODS[method].kind == "rtol" else h
        try:
            r = baselines.METHODS[method](sc, x, t_end=t_end, **kw)
        except Exception as exc:  # noqa: BLE001
            r = {"fail": f"{type(exc).__name__}: {exc}"}
        runs = [r if ("skip" in r or "fail" in r) else {**r, "steps": r["t"].size - 1}]
    r = runs[0]
    if "skip" in r or "fail" in r:
        lr.note = r.get("skip") or r.get("fail")
        return lr
    en = np.asarray(r["energy"], float)
    t = np.asarray(r["t"], float)[: en.size]
    e0 = en[0] if en[0] != 0 else 1.0
    lr.wall = float(r["wall"])
    lr.impacts = len(r["impacts"])
    lr.rel_e = (en - en[0]) / abs(e0)
    lr.t = t
    lr.energy_dev = float(np.max(np.abs(lr.rel_e)))
    lr.drift = relative_drift(t, en) * (t[-1] - t[0])
    lr.min_phi = min_phi(scene, np.asarray(r["q"]))
    if r.get("fell_through"):
        lr.note = f"fell through the contact at t = {t[-1]:.3g} after {lr.impacts} impacts (a missed impact)"
    elif r.get("stalled"):
        lr.note = f"stuck re-impacting at one instant (kink chatter) at t = {r['stalled']:.4g}"
    elif t[-1] < t_end - 2 * h:
        lr.note = f"stopped at t = {t[-1]:.4g}"
    lr.steps = int(t.size - 1) if method.startswith(("vcigen", "verlet")) else steps
    return lr


def long_csv_row(r: LongRun) -> list[object]:
    vals = (r.wall, r.impacts, r.energy_dev, r.drift, r.min_phi)
    return [r.scene, r.method, f"{r.h:g}", r.steps, *(f"{v:.6g}" for v in vals), r.note]


# ------------------------------------------------------------------ plots


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_work_precision(path: Path, scene: str, rows: Sequence[Row], setup: Setup) -> None:
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), dpi=110)
    for ax, attr, what in (
        (axes[0], "err_first", f"t = {setup.t_first} (after the first collision)"),
        (axes[1], "err_few", f"t = {setup.t_few} (after a few impacts)"),
    ):
        for name, m in METHODS.items():
            pts = [(r.wall, getattr(r, attr)) for r in rows if r.method == name]
            pts = [(w, e) for w, e in pts if np.isfinite(w) and np.isfinite(e) and w > 0 and e > 0]
            if pts:
                w, e = zip(*pts)
                ax.loglog(w, e, m.style, label=m.label, ms=5, lw=1)
        ax.set_xlabel("wall time per run [s]")
        ax.set_ylabel("position error (RMS over start phases)")
        ax.set_title(f"{scene}: {what}", fontsize=10)
        ax.grid(True, which="both", lw=0.3)
    axes[0].legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_energy(path: Path, scene: str, runs: Sequence[LongRun]) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(10, 4.5), dpi=110)
    for lr in runs:
        if lr.t.size == 0:
            continue
        # at most ~4000 points: per bin, the largest |dE|
        n = lr.t.size
        bins = max(1, n // 4000)
        m = (n // bins) * bins
        dev = np.abs(lr.rel_e[:m]).reshape(-1, bins).max(axis=1)
        tt = lr.t[:m].reshape(-1, bins)[:, 0]
        label = f"{METHODS[lr.method].label} (h={lr.h:g})" + (" - fell through" if "fell" in lr.note else "")
        ax.semilogy(tt, np.maximum(dev, 1e-17), lw=0.7, label=label)
    ax.set_xlabel("t")
    ax.set_ylabel("|E - E0| / |E0|")
    ax.set_title(f"{scene}: energy over a long run")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# ------------------------------------------------------------------ summary


def machine_line() -> str:
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        nproc = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
    except OSError:
        nproc = "?"
    import scipy

    return (
        f"nproc {nproc}, {cpu}, Python {platform.python_version()}, numpy {np.__version__}, "
        f"scipy {scipy.__version__}, {platform.system()} {platform.release()}"
    )


def wall_at(rows: Sequence[Row], target: float, attr: str = "err_first") -> tuple[float, str]:
    """Wall time to reach ``target`` error: interpolated on the log-log curve, or
    extrapolated from the two most accurate points (flagged ``~``)."""
    pts = sorted(
        ((r.wall, getattr(r, attr)) for r in rows if np.isfinite(getattr(r, attr)) and r.wall > 0),
        key=lambda p: -p[1],
    )
    pts = [(w, max(e, 1e-16)) for w, e in pts]
    if not pts:
        return float("nan"), "no data"
    reached = [w for w, e in pts if e <= target]
    for (w0, e0), (w1, e1) in zip(pts, pts[1:]):
        if e0 > target >= e1 and e1 < e0:
            s = math.log(target / e0) / math.log(e1 / e0)
            return math.exp(math.log(w0) + s * math.log(w1 / w0)), ""
    if reached:  # already below the target at the cheapest point
        return min(reached), "<="
    if len(pts) >= 2:
        (w0, e0), (w1, e1) = pts[-2], pts[-1]
        if e1 < e0 and w1 > w0:
            slope = math.log(w1 / w0) / math.log(e0 / e1)
            return w1 * (e1 / target) ** slope, "~"
    return float("nan"), "not reached"


def order_of(rows: Sequence[Row], attr: str = "err_first") -> float:
    pts = [
        (r.x, getattr(r, attr)) for r in rows if np.isfinite(getattr(r, attr)) and getattr(r, attr) > 1e-13
    ]
    if len(pts) < 2:
        return float("nan")
    h, e = np.array(pts).T
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


def _fmt(v: float, spec: str = ".2e") -> str:
    return "—" if not np.isfinite(v) else format(v, spec)


def write_summary(
    path: Path,
    all_rows: dict[str, list[Row]],
    longs: Sequence[LongRun],
    drift_runs: Sequence[LongRun],
    target: float,
    skips: dict[str, str],
    total: float,
    args: argparse.Namespace,
) -> None:
    lines = ["# Speed against error (`make bench`)", ""]
    lines += [f"Machine: {machine_line()}.", ""]
    lines += [
        f"Sweep: {args.phases} start phases per run (the start time shifted by tau_j in [0, {TAU_SPAN}) "
        "so the first impact falls at different places inside a step); errors are the RMS over the "
        "phases of |q - q_ref| at a fixed time, wall times the median over the phases (integration "
        "loop only, no build/compile). References: closed form (particle), exact flight + "
        "branch-and-bound impact times (star), DOP853 rtol = atol = 1e-13 with every contact "
        "checked inside every step (star_nonlinear, pendulum_wall).",
        "",
        "**Under linear gravity free flight is integrated exactly by every method here**, so "
        "`particle` and `star` measure only how impacts are handled; `star_nonlinear` "
        "(V = -m g R^2/(R+y), R = 5, the paper's Fig. 5 set-up) and `pendulum_wall` "
        "(configuration-dependent mass matrix, nonlinear contact) measure accuracy.",
        "",
        "Costs are per language: vcigen CasADi, naive Verlet, solve_ivp and the Siconos driver "
        "loop are Python; vcigen C runs compiled C. Compare like with like.",
        "",
    ]
    for scene, rows in all_rows.items():
        setup = SETUPS[scene]
        lines += [
            f"## {scene}",
            "",
            f"Errors at t = {setup.t_first} (after the first collision) and t = {setup.t_few} "
            f"(after a few impacts). `wall @ {target:g}`: wall time per run to reach error "
            f"{target:g} at t = {setup.t_first} (interpolated; `~` extrapolated from the two most "
            "accurate points; `<=` the cheapest run already does better). Impacts missed / "
            f"spurious: reference impacts in (tau, tau + {setup.t_few}] with no impact of the method "
            f"within {MATCH_TOL} s, and the reverse; at coarse h the trajectory error alone can move "
            "an impact after the first few out of that window.",
            "",
            f"| method | wall @ {target:g} | best error (t={setup.t_first}) | its wall [s] | order in h "
            "| max dE/E0 | impacts missed / spurious (worst run) | max violation |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for name, m in METHODS.items():
            mr = [r for r in rows if r.method == name]
            if not mr:
                continue
            if all(r.note.startswith("skip") for r in mr):
                lines.append(f"| {m.label} | skipped: {mr[0].note[6:]} | | | | | | |")
                continue
            w, flag = wall_at(mr, target)
            good = [r for r in mr if np.isfinite(r.err_first)]
            best = min(good, key=lambda r: r.err_first) if good else None
            order = _fmt(order_of(mr), ".2f") if m.kind == "h" else "(rtol sweep)"
            miss = max((r.missed for r in mr if np.isfinite(r.missed)), default=float("nan"))
            spur = max((r.spurious for r in mr if np.isfinite(r.spurious)), default=float("nan"))
            if best is None:
                lines.append(f"| {m.label} | {_wall_cell(w, flag)} | — | — | {order} | — | — | — |")
                continue
            dev = max((r.energy_dev for r in mr if np.isfinite(r.energy_dev)), default=np.nan)
            viol = max((r.max_violation for r in mr if np.isfinite(r.max_violation)), default=np.nan)
            lines.append(
                f"| {m.label} | {_wall_cell(w, flag)} | {_fmt(best.err_first)} "
                f"({'h' if m.kind == 'h' else 'rtol'}={best.x:g}) | {_fmt(best.wall)} | {order} | "
                f"{_fmt(dev)} | {_fmt(miss, 'g')} / {_fmt(spur, 'g')} | {_fmt(viol)} |"
            )
        notes = sorted(
            {f"{r.method} {r.x:g}: {r.note}" for r in rows if r.note and not r.note.startswith("skip")}
        )
        if notes:
            lines += ["", "Notes:", *(f"- {n}" for n in notes)]
        ratios = _ratios(rows, target)
        if ratios:
            others = ", ".join(f"{lab} x{r:.3g}" for lab, r in ratios[1:]) or "no other method reaches it"
            lines += [
                "",
                f"Wall time at matched accuracy ({target:g} at t = {setup.t_first}), relative to "
                f"{ratios[0][0]}: {others}.",
            ]
        lines += ["", f"![work-precision {scene}](wp_{scene}.png)", ""]
    if longs:
        lines += [
            "## Long runs: energy",
            "",
            "`drift`: least-squares slope of (E - E0)/|E0| times the run length; `max dE/E0` the "
            "largest deviation; `min phi` the deepest penetration seen on the grid. "
            "E is the discrete energy E_d for vcigen, the continuous energy otherwise.",
            "",
            "| scene | method | h | steps | wall [s] | impacts | max dE/E0 | drift over the run "
            "| min phi | note |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for lr in [*longs, *drift_runs]:
            lines.append(
                f"| {lr.scene} | {METHODS[lr.method].label} | {lr.h:g} | {lr.steps} | "
                f"{_fmt(lr.wall, '.3g')} | {lr.impacts} | {_fmt(lr.energy_dev)} | {_fmt(lr.drift)} | "
                f"{_fmt(lr.min_phi, '.2e')} | {lr.note} |"
            )
        for scene in dict.fromkeys(lr.scene for lr in longs):
            lines += ["", f"![energy {scene}](energy_{scene}.png)"]
        lines.append("")
    if skips:
        lines += ["## Could not run", "", *(f"- {k}: {v}" for k, v in skips.items()), ""]
    lines += [f"`make bench` took {total:.0f} s.", ""]
    path.write_text("\n".join(lines))


def _wall_cell(w: float, flag: str) -> str:
    return f"{flag}{_fmt(w)}" if np.isfinite(w) else (flag or "—")


def _ratios(rows: Sequence[Row], target: float) -> list[tuple[str, float]]:
    walls = {}
    for name, m in METHODS.items():
        mr = [r for r in rows if r.method == name and not r.note.startswith("skip")]
        if mr:
            w, flag = wall_at(mr, target)
            if np.isfinite(w):
                suffix = {"~": " (extrapolated)", "<=": " (at most: its cheapest run is already better)"}
                walls[m.label + suffix.get(flag, "")] = w
    if not walls:
        return []
    base = next(iter(walls))
    return [(base, 1.0)] + [(k, v / walls[base]) for k, v in walls.items() if k != base]


# ------------------------------------------------------------------ main


def parse(argv: Sequence[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="bench/run.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=",".join(SETUPS), help="comma list (default: all four)")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma list (default: all)")
    ap.add_argument("--hs", default=None, help="override the h sweep of every scene, comma list")
    ap.add_argument("--rtols", default=",".join(f"{r:g}" for r in RTOLS))
    ap.add_argument("--phases", type=int, default=8, help="start phases per (method, h)")
    ap.add_argument("--target", type=float, default=1e-4, help="accuracy for 'wall time to reach'")
    ap.add_argument("--long-steps", type=int, default=100_000, help="steps of the energy long runs")
    ap.add_argument("--drift-steps", type=int, default=1_000_000, help="steps of the C drift runs")
    ap.add_argument("--no-long", action="store_true", help="skip the long runs")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    return ap.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(argv)
    total0 = time.perf_counter()
    scenes = [s for s in args.scenes.split(",") if s]
    methods = [m for m in args.methods.split(",") if m]
    for s in scenes:
        if s not in SETUPS:
            raise SystemExit(f"unknown scene {s!r}; known: {', '.join(SETUPS)}")
    for m in methods:
        if m not in METHODS:
            raise SystemExit(f"unknown method {m!r}; known: {', '.join(METHODS)}")
    rtols = tuple(float(r) for r in args.rtols.split(","))
    setups = dict(SETUPS)
    if args.hs:
        hs = tuple(float(h) for h in args.hs.split(","))
        setups = {k: dataclasses.replace(v, hs=hs) for k, v in setups.items()}
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    sims = VcigenSims()
    skips: dict[str, str] = {}
    for backend in ("c",):
        reason = sims.backend_missing(backend)
        if reason and any(m.startswith(f"vcigen_{backend}_") for m in methods):
            log(f"[bench] SKIP vcigen C (both rules): {reason}")
            skips["vcigen C"] = reason
    n_runs = sum(len(setups[s].hs) if METHODS[m].kind == "h" else len(rtols) for s in scenes for m in methods)
    counter = [0, n_runs]
    all_rows: dict[str, list[Row]] = {}
    for s in scenes:
        scene = bench_scenes.get(s)
        rows = sweep_scene(sims, scene, setups[s], methods, rtols, args.phases, counter)
        all_rows[s] = rows
        write_csv(out / f"{s}.csv", CSV_COLUMNS, [r.csv() for r in rows])
        for r in rows:
            if r.note.startswith("skip") and f"{r.method} on {s}" not in skips:
                skips[f"{r.method} on {s}"] = r.note[6:]
        try:
            plot_work_precision(out / f"wp_{s}.png", s, rows, setups[s])
        except ImportError as exc:
            log(f"[bench] no plots: {exc}")
    longs: list[LongRun] = []
    drift_runs: list[LongRun] = []
    if not args.no_long:
        longs, drift_runs = long_runs(sims, scenes, methods, args, out, skips)
    total = time.perf_counter() - total0
    write_summary(out / "summary.md", all_rows, longs, drift_runs, args.target, skips, total, args)
    if out.resolve() == DEFAULT_OUT.resolve():
        update_readme(out / "summary.md", ROOT / "README.md")
    log(f"[bench] done in {total:.0f}s; results in {out}")
    return 0


README_START, README_END = "<!-- bench:start -->", "<!-- bench:end -->"


def update_readme(summary: Path, readme: Path) -> bool:
    """Copy the headline of ``summary.md`` (ratios at matched accuracy, long runs) into the README."""
    doc = readme.read_text(encoding="utf-8") if readme.exists() else ""
    if README_START not in doc or README_END not in doc:
        return False
    text = summary.read_text(encoding="utf-8")
    block, scene = [], ""
    for line in text.splitlines():
        if line.startswith("Machine:"):
            block += [line, ""]
        elif line.startswith("## "):
            scene = line[3:]
        elif line.startswith("Wall time at matched accuracy"):
            block.append(f"- **{scene}**: {line}")
    if "## Long runs" in text:
        long = text[text.index("## Long runs") :].split("\n![", 1)[0].strip()
        block += ["", long.replace("## Long runs: energy", "**Long runs: energy.**")]
    head, tail = doc.split(README_START, 1)[0], doc.split(README_END, 1)[1]
    readme.write_text(
        f"{head}{README_START}\n" + "\n".join(block) + f"\n{README_END}{tail}", encoding="utf-8"
    )
    return True


def long_runs(sims, scenes, methods, args, out: Path, skips) -> tuple[list[LongRun], list[LongRun]]:
    longs: list[LongRun] = []
    drift_runs: list[LongRun] = []
    have_c = sims.backend_missing("c") is None
    for s in scenes:
        setup = SETUPS[s]
        if setup.long_h is None:
            continue
        scene = bench_scenes.get(s)
        cand = ["vcigen_c_trapezoid", "vcigen_casadi_trapezoid", "verlet_half_flip", "verlet_full_flip"]
        cand += ["dop853_events", "dop853_events_ms"]
        mine = [m for m in cand if m in methods and (have_c or not m.startswith("vcigen_c_"))]
        here = []
        for m in mine:
            t0 = time.perf_counter()
            lr = long_run(sims, scene, m, setup.long_h, args.long_steps)
            here.append(lr)
            log(
                f"[bench long] {s:15s} {m:24s} h={setup.long_h:g} {args.long_steps} steps: "
                f"wall {lr.wall:.3g}s impacts {lr.impacts} max dE/E0 {lr.energy_dev:.2e} "
                f"drift {lr.drift:.2e} ({time.perf_counter() - t0:.1f}s) {lr.note}"
            )
        longs += here
        try:
            plot_energy(out / f"energy_{s}.png", s, here)
        except ImportError as exc:
            log(f"[bench] no plots: {exc}")
        if have_c:
            for m in ("vcigen_c_trapezoid", "vcigen_c_midpoint"):
                if m in methods:
                    lr = long_run(sims, scene, m, setup.long_h, args.drift_steps)
                    lr.t = lr.rel_e = np.empty(0)
                    drift_runs.append(lr)
                    log(
                        f"[bench drift] {s:15s} {m:24s} {args.drift_steps} steps: wall {lr.wall:.3g}s "
                        f"max dE/E0 {lr.energy_dev:.2e} drift {lr.drift:.2e} {lr.note}"
                    )
        else:
            skips.setdefault(
                "energy drift after 1e6 steps",
                "not measured: needs the vcigen C backend, which is not available",
            )
    write_csv(out / "longrun.csv", LONG_COLUMNS, [long_csv_row(r) for r in [*longs, *drift_runs]])
    return longs, drift_runs


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
