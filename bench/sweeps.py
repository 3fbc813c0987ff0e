"""The h / rtol sweep of the speed-against-error bench (bench/run.py): references, runs, one row each.

Every run starts at one of several *start phases* ``tau_j`` in ``[0, TAU_SPAN)`` (the reference
state at ``tau_j``) and is evaluated at ``tau_j + T``, so the first impact falls at different places
inside a step; :func:`evaluate` aggregates the runs of one (method, h or rtol) into a :class:`Row`:
errors RMS over the phases, wall times the median.
"""

from __future__ import annotations

import csv
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench import reference
from bench.methods import METHODS, VcigenSims, log, run_method
from bench.scenes import Scene
from vcigen.progress import format_seconds

Array = np.ndarray
GOLDEN = 0.6180339887498949
TAU_SPAN = 0.02  # start phases tau_j = TAU_SPAN * frac(j * golden ratio)
MATCH_TOL = 0.05  # an impact matches a reference impact within this many seconds
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


def _halvings(h: float, k: int) -> tuple[float, ...]:
    """``h/2, h/4, ..., h/2^k``."""
    return tuple(h / 2**i for i in range(1, k + 1))


@dataclass(frozen=True)
class Setup:
    """Per scene: evaluation times after the first collision and after a few impacts."""

    t_first: float
    t_few: float
    hs: tuple[float, ...]
    long_h: float | None = None  # step of the long runs (None: no long run)
    # Finer steps for the compiled vcigen methods only (cheap in C), so that their curves reach errors
    # of 1e-10 and overlap the event-driven ones where the two are compared (wall time at 1e-8).
    fine_hs: tuple[float, ...] = ()
    # A fourth-order rule's own sweep (vcigen.RULES[...].order == 4): coarser steps, since its error meets
    # round-off (~1e-12) near h = 1e-3 already, where the second-order rules are at 1e-6; each divides the
    # evaluation times of every scene
    high_order_hs: tuple[float, ...] = (0.1, *_halvings(0.1, 7))

    def hs_for(self, method: str) -> tuple[float, ...]:
        """The step sizes a method of kind ``"h"`` runs: the finer ones too for vcigen's C backend, the
        fourth-order sweep for ``lobatto3``."""
        if method.endswith("_lobatto3"):
            return self.high_order_hs
        return self.hs + self.fine_hs if method.startswith("vcigen_c_") else self.hs


SETUPS: dict[str, Setup] = {
    # particle impacts at 0.45, 1.35, 2.26, 3.16
    "particle": Setup(
        0.8, 2.5, (0.02, 0.01, 0.005, 0.0025, 0.00125), long_h=0.01, fine_hs=_halvings(0.00125, 7)
    ),
    # star (linear gravity) impacts at 0.756, 2.263, 3.029, 4.405
    "star": Setup(
        1.5, 3.5, (0.02, 0.01, 0.005, 0.0025, 0.00125), long_h=0.005, fine_hs=_halvings(0.00125, 7)
    ),
    # star, V = -m g R^2/(R+y): a pair at 1.239 / 1.248 (second vertex), then 2.758, 3.159
    "star_nonlinear": Setup(
        2.0, 3.5, (0.02, 0.01, 0.005, 0.0025, 0.00125, 0.000625), fine_hs=_halvings(0.000625, 8)
    ),
    # double pendulum against a wall: impacts at 0.094, 0.822, 1.611, 2.481
    # (lobatto3: one halving more than the default, to h = 0.1/256, so its error reaches 1e-10 here too)
    "pendulum_wall": Setup(
        0.5,
        2.0,
        (0.02, 0.01, 0.005, 0.0025, 0.00125),
        fine_hs=_halvings(0.00125, 7),
        high_order_hs=(0.1, *_halvings(0.1, 8)),
    ),
}
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)


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


def eta(counter) -> str:
    """``"1m20s left"``: the time left at the pace so far (``counter``: runs done, in all, start time)."""
    done, total, start = counter
    elapsed = time.perf_counter() - start
    return f"{format_seconds(elapsed * (total - done) / done) if done else '?'} left"


def sweep_scene(
    sims: VcigenSims, scene: Scene, setup: Setup, methods: Sequence[str], rtols, n_phases: int, counter
) -> list[Row]:
    start = time.perf_counter()
    ref = scene_reference(scene, setup, n_phases)
    log(f"[bench] {scene.name}: reference in {time.perf_counter() - start:.1f}s, {n_phases} start phases")
    rows: list[Row] = []
    for method in methods:
        xs = setup.hs_for(method) if METHODS[method].kind == "h" else rtols
        for x in xs:
            counter[0] += 1
            t0 = time.perf_counter()
            runs = run_method(sims, method, scene, x, ref["starts"], setup.t_few)
            row = evaluate(scene, setup, method, x, runs, ref)
            rows.append(row)
            log(
                f"[bench {counter[0]:3d}/{counter[1]} {eta(counter)}] {scene.name:15s} {method:24s} "
                f"{x:<9.3g} "
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
