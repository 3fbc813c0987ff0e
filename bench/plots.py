"""The plots of the speed-against-error bench (bench/run.py): work-precision and long-run energy."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from bench.methods import METHODS

if TYPE_CHECKING:
    from bench.long_runs import LongRun
    from bench.sweeps import Row, Setup


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
