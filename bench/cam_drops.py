"""Random runs of a cam and its follower: the follower rides the cam, jumps off, flies, lands, bounces.

    .venv/bin/python -m bench.cam_drops [--drops 3000] [--seed 2] [--h 0.005] [--backend c]
    .venv/bin/python -m bench.cam_drops --agree [--drops 1000] [--seed 5]
    .venv/bin/python -m bench.cam_drops --lift-offs [--drops 600] [--seed 1]

The model of ``tests/test_cam_follower.py`` (a flywheel of inertia ``I`` carrying a disk cam of radius 1,
``eps`` off its axle; a flat follower of mass 1 on a spring ``k`` free at ``y0``, under gravity; Coulomb
friction ``mu`` and restitution ``e`` on the face). Each draw: ``I`` uniform in (1, 50), ``eps`` in (0.05,
0.5), ``k`` in (5, 200), ``y0`` in (0, 0.9), ``mu`` in {0, 0, 0.1, 0.5}, ``e`` in {0, 0.3, 0.6, 0.9}, the turn
uniform and the spin up to 1.3 times the one where the cam's top falls away at the spring's and gravity's
pull; three in four start on the cam at its speed, one in four dropped from up to 0.2 above it; to ``t = 4``.

* Tallies per backend: the runs that end in a ``SolverError`` (each printed) and the runs with an impact of
  impulse 0, a grazing impact, a restart (``jump_fallbacks``), a lift-off held on (``lifts_kept``), a booked
  force below -1e-9 (and the least), friction work above 1e-12 in a step (and the most), a jam.
* ``--agree``: each draw on both backends (to ``t = 2``), those more than 1e-6 apart printed.
* ``--lift-offs``: the draws that start on the cam, pressed, and jump within 3 s (``reference``, the test's
  event-driven scipy reference), run at ``h`` and ``h / 2`` in C: the first lift-off's error against the
  reference in units of ``h^2``, for those held on (``lifts_kept``) and those not; the order between the two
  (a reference that takes more than ``REFERENCE_SECONDS`` is skipped, counted).
"""

from __future__ import annotations

import math
import signal
import sys
from pathlib import Path

import numpy as np

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hard_scenes import G  # noqa: E402
from test_cam_follower import reference, simulator  # noqa: E402

from bench.random_runs import arguments, contact_flags, dispatch, least_force, quiet  # noqa: E402

REFERENCE_SECONDS = 20  # a reference that takes longer is skipped (counted)


def draw(rng: np.random.Generator) -> tuple[list[float], list[float], dict[str, float]]:
    """One start ``(q0, v0, params)``."""
    p = {
        "I": float(rng.uniform(1, 50)),
        "eps": float(rng.uniform(0.05, 0.5)),
        "k": float(rng.uniform(5, 200)),
        "y0": float(rng.uniform(0.0, 0.9)),
        "mu": float(rng.choice([0.0, 0.0, 0.1, 0.5])),
        "e": float(rng.choice([0.0, 0.3, 0.6, 0.9])),
    }
    th0 = float(rng.uniform(-math.pi, math.pi))
    w = float(rng.uniform(0, 1.3)) * math.sqrt((p["k"] * (1 - p["y0"]) + G) / p["eps"])
    gap = float(rng.choice([0.0, 0.0, 0.0, rng.uniform(0, 0.2)]))
    vy = p["eps"] * math.cos(th0) * w if gap == 0.0 else float(rng.normal(0, 1))
    return [th0, 1.0 + p["eps"] * math.sin(th0) + gap], [w, vy], p


def flags(res: vcigen.Result, params: dict | None = None) -> dict[str, bool]:
    return {**contact_flags(res), "friction pushing": extremes(res)["most friction work in a step"] > 1e-12}


def extremes(res: vcigen.Result, params: dict | None = None) -> dict[str, float]:
    fw = res.friction_work
    return {
        "least force": least_force(res),
        "most friction work in a step": float(fw.max()) if fw is not None and fw.size else 0.0,
        "most impacts in a run": len(res.impacts),
    }


def lift_offs(drops: int, seed: int, h: float) -> None:
    rng = np.random.default_rng(seed)
    rows = {True: [], False: []}  # held on or not: (error at h, at h / 2) in units of h^2 and (h / 2)^2
    slow = 0

    def late(*_):
        raise TimeoutError

    signal.signal(signal.SIGALRM, late)
    for _ in range(drops):
        (th0, y0_), (w, _vy), p = draw(rng)
        if y0_ != 1.0 + p["eps"] * math.sin(th0):
            continue
        signal.alarm(REFERENCE_SECONDS)
        try:
            t_lift, _, _ = reference(th0, w, p)
        except (AssertionError, IndexError):
            continue
        except TimeoutError:
            slow += 1
            continue
        finally:
            signal.alarm(0)
        errs, kept = [], False
        for hh in (h, h / 2):
            res = quiet(simulator("c"), ([th0, y0_], [w, p["eps"] * math.cos(th0) * w], p), hh, t_lift + 0.05)
            if not res.liftoffs or res.impacts and res.impacts[0].t < res.liftoffs[0][0]:
                break  # it left earlier (a start whose force is 0 to round-off) or bounced first
            errs.append((res.liftoffs[0][0] - t_lift) / hh**2)
            kept = kept or res.stats["lifts_kept"] > 0
        if len(errs) == 2:
            rows[kept].append(errs)
    print(f"  references skipped after {REFERENCE_SECONDS} s (counted): {slow}")
    for kept, name in ((True, "held on"), (False, "released at once")):
        e = np.abs(np.array(rows[kept])).reshape(-1, 2)
        if not len(e):
            print(f"  {name}: none")
            continue
        order = np.log2(4 * np.maximum(e[:, 0], 1e-300) / np.maximum(e[:, 1], 1e-300))
        print(
            f"  {name}: {len(e)} jumps; |error| / h^2 at h = {h}: median {np.median(e[:, 0]):.3g}, largest "
            f"{e[:, 0].max():.3g}; at h / 2 largest {e[:, 1].max():.3g}; order (where above 1e-3 h^2) "
            f"{np.median(order[e[:, 0] > 1e-3]) if (e[:, 0] > 1e-3).any() else math.nan:.2f} median"
        )


def main() -> None:
    ap = arguments(__doc__, seed=2, h=0.005)
    ap.add_argument("--lift-offs", action="store_true", help="lift-off times against the reference")
    drops = {"agree": 1000, "lift_offs": 600, "tally": 3000}
    modes = {"lift_offs": lift_offs}
    dispatch(ap.parse_args(), simulator, draw, flags, extremes, 4.0, drops, modes, agree_t_end=2.0)


if __name__ == "__main__":
    main()
