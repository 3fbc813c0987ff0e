"""Shared by the contact-regime examples: command line, timed build and run, impact kinds, plots."""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 - after the backend is chosen

import vcigen  # noqa: E402

KIND_COLOURS = {"elastic": "C0", "restitution": "C2", "plastic": "C3", "grazing": "C1"}


def args(doc: str) -> argparse.Namespace:
    """``--backend {casadi,c}`` (default casadi) and ``--out DIR`` (default ``results``)."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--backend", default="casadi", choices=["casadi", "c"])
    ap.add_argument("--out", default="results", help="folder for the PNG plot")
    return ap.parse_args()


def build(model: vcigen.Model, backend: str) -> vcigen.Simulator:
    """``vcigen.build`` with its wall time printed."""
    start = time.perf_counter()
    sim = vcigen.build(model, backend=backend)
    print(f"build [{backend}]: {time.perf_counter() - start:.2f} s")
    return sim


def simulate(sim: vcigen.Simulator, **run) -> vcigen.Result:
    """``sim.simulate(**run)`` with its wall time and step count printed."""
    start = time.perf_counter()
    res = sim.simulate(**run)
    print(f"simulate [h = {run['h']}]: {time.perf_counter() - start:.3f} s, {res.t.size - 1} steps")
    return res


def kinds(res: vcigen.Result) -> str:
    """``"9 impacts: 8 restitution, 1 plastic"`` (kinds in the order of vcigen.result.KINDS)."""
    count = Counter(im.kind for im in res.impacts)
    parts = [f"{count[k]} {k}" for k in KIND_COLOURS if count[k]]
    return f"{res.n_impacts} impacts" + (": " + ", ".join(parts) if parts else "")


def mark_impacts(ax, res: vcigen.Result, values, size: float = 18) -> None:
    """Impact markers at ``(im.t, values[i])``, one colour per kind, with a legend entry each."""
    for kind, colour in KIND_COLOURS.items():
        pts = [(im.t, v) for im, v in zip(res.impacts, values) if im.kind == kind]
        if pts:
            t, v = zip(*pts)
            ax.scatter(t, v, s=size, color=colour, zorder=3, label=f"{kind} impact ({len(pts)})")


def save(fig, out: str, name: str) -> Path:
    """Write ``<out>/<name>.png`` and say so."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.png"
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    print(f"wrote {path}")
    return path
