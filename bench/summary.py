"""The summary of the speed-against-error bench (bench/run.py): ``summary.md`` and its headline in README.md.

Wall time at matched accuracy (:func:`wall_at`, interpolated on the work-precision curve), the
fitted order in h (:func:`order_of`), the long runs' table; :func:`update_readme` copies the
headline between the README's ``<!-- bench:start -->`` / ``<!-- bench:end -->`` markers.
"""

from __future__ import annotations

import argparse
import math
import platform
import subprocess
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bench.long_runs import LongRun
from bench.methods import METHODS
from bench.sweeps import MATCH_TOL, SETUPS, TAU_SPAN, Row


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
            log_w = math.log(w1) + slope * math.log(e1 / target)
            if log_w < math.log(1e300):  # a flat curve (error barely falls, time grows) extrapolates past it
                return math.exp(log_w), "~"
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
    targets: Sequence[float],
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
        walls = " | ".join(f"wall @ {t:g}" for t in targets)
        lines += [
            f"## {scene}",
            "",
            f"Errors at t = {setup.t_first} (after the first collision) and t = {setup.t_few} "
            f"(after a few impacts). `wall @ e`: wall time per run to reach error "
            f"e at t = {setup.t_first} (interpolated; `~` extrapolated from the two most "
            "accurate points; `<=` the cheapest run already does better). Impacts missed / "
            f"spurious: reference impacts in (tau, tau + {setup.t_few}] with no impact of the method "
            f"within {MATCH_TOL} s, and the reverse; at coarse h the trajectory error alone can move "
            "an impact after the first few out of that window.",
            "",
            f"| method | {walls} | best error (t={setup.t_first}) | its wall [s] | order in h "
            "| max dE/E0 | impacts missed / spurious (worst run) | max violation |",
            "|---|" + "---|" * len(targets) + "---|---|---|---|---|---|",
        ]
        for name, m in METHODS.items():
            mr = [r for r in rows if r.method == name]
            if not mr:
                continue
            if all(r.note.startswith("skip") for r in mr):
                lines.append(f"| {m.label} | skipped: {mr[0].note[6:]} |" + " |" * (len(targets) + 5))
                continue
            cells = " | ".join(_wall_cell(*wall_at(mr, t)) for t in targets)
            good = [r for r in mr if np.isfinite(r.err_first)]
            best = min(good, key=lambda r: r.err_first) if good else None
            order = _fmt(order_of(mr), ".2f") if m.kind == "h" else "(rtol sweep)"
            miss = max((r.missed for r in mr if np.isfinite(r.missed)), default=float("nan"))
            spur = max((r.spurious for r in mr if np.isfinite(r.spurious)), default=float("nan"))
            if best is None:
                lines.append(f"| {m.label} | {cells} | — | — | {order} | — | — | — |")
                continue
            dev = max((r.energy_dev for r in mr if np.isfinite(r.energy_dev)), default=np.nan)
            viol = max((r.max_violation for r in mr if np.isfinite(r.max_violation)), default=np.nan)
            lines.append(
                f"| {m.label} | {cells} | {_fmt(best.err_first)} "
                f"({'h' if m.kind == 'h' else 'rtol'}={best.x:g}) | {_fmt(best.wall)} | {order} | "
                f"{_fmt(dev)} | {_fmt(miss, 'g')} / {_fmt(spur, 'g')} | {_fmt(viol)} |"
            )
        notes = sorted(
            {f"{r.method} {r.x:g}: {r.note}" for r in rows if r.note and not r.note.startswith("skip")}
        )
        if notes:
            lines += ["", "Notes:", *(f"- {n}" for n in notes)]
        for tgt in targets:
            ratios = _ratios(rows, tgt)
            if ratios:
                others = ", ".join(f"{lab} x{r:.3g}" for lab, r in ratios[1:]) or "no other method reaches it"
                lines += [
                    "",
                    f"Wall time at matched accuracy ({tgt:g} at t = {setup.t_first}), relative to "
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
