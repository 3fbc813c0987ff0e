"""Cost of a run with exact sensitivities over the same run without (issue 11), per backend.

    .venv/bin/python -m bench.sensitivity_cost [--repeats 5] [--c-repeats 50] [--scale 1] [--c-fallback]
        [--rule trapezoid]

Each scene is run with ``simulate(..., sensitivities=False)`` and ``True`` (same start, same ``h``, same
``t_end``), both variants interleaved round-robin, best of ``--repeats``; the time is the stepper's own loop
(``res.stats["wall_time"]``, without the Python set-up of ``simulate``), after one warm-up run of each (the
``d_*`` Functions are built on the first ``sensitivities=True`` run). The ratio is with / without. A C run
of these scenes takes tens of microseconds: best of ``--c-repeats`` there.

The C column needs the C backend's own tangent propagation (helper sens-c: ``CSimulator._run_sensitive``
overridden); without it the column is skipped with a message. ``--c-fallback`` measures what
``simulate(sensitivities=True)`` does on C meanwhile: the Python stepper over the compiled kernels with the
tangent in CasADi, against the C loop without (a ratio of two different loops, for information).

Scenes (``tests/test_sensitivity.py`` has their FD checks):

* ``box``: a particle in the unit box under gravity, ``q0 = (0.3, 0.6)``, ``v0 = (2.3, -1.1)``, h = 0.01;
* ``star``: ``examples/star.py``, ``q0 = (0, 1.2, 0)``, ``v0 = (-2, 0, 5)``, h = 0.005;
* ``double_pendulum``: against the wall ``x = 1.2``, ``q0 = (0.3, 0.6)``, ``v0 = (1.5, 2)``, h = 0.01;
* ``driven``: the damped, driven oscillator with restitution (forces of time), ``q0 = 0``, ``v0 = 3``.

``--rule lobatto3``: the same under the fourth-order rule (its internal points one more unknown of each
phase's tangent, on both backends).

Writes ``bench/results/sensitivity_cost.csv`` (``sensitivity_cost_<rule>.csv`` for another rule).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent), str(HERE.parent / "tests")]

import hard_scenes  # noqa: E402
from forced_scenes import driven_oscillator  # noqa: E402
from scenes import load_example  # noqa: E402

import vcigen  # noqa: E402
from vcigen.simulator import Simulator  # noqa: E402

# scene -> (model maker, q0, v0, h, t_end, params)
SCENES = {
    "box": (hard_scenes.box, [0.3, 0.6], [2.3, -1.1], 0.01, 4.0, {"g": 9.81}),
    "star": (lambda: load_example("star").model(), [0.0, 1.2, 0.0], [-2.0, 0.0, 5.0], 0.005, 2.0, None),
    "double_pendulum": (hard_scenes.double_pendulum, [0.3, 0.6], [1.5, 2.0], 0.01, 2.0, None),
    "driven": (driven_oscillator, [0.0], [3.0], 0.01, 4.0, None),
}


def has_own_tangent(sim: vcigen.Simulator) -> bool:
    """Whether the backend propagates the tangent itself (else the Python stepper over its kernels)."""
    return type(sim)._run_sensitive is not Simulator._run_sensitive


def best_times(
    sim: vcigen.Simulator, scene: str, repeats: int, scale: float
) -> tuple[float, float, int, int]:
    """``(best without, best with, steps, impacts)``: loop seconds of the same run, interleaved."""
    _, q0, v0, h, t_end, params = SCENES[scene]
    t_end = t_end * scale
    off, on = [], []
    for i in range(repeats + 1):
        a = sim.simulate(q0, v0, h, t_end=t_end, params=params, progress=False)
        b = sim.simulate(q0, v0, h, t_end=t_end, params=params, progress=False, sensitivities=True)
        assert a.n_impacts == b.n_impacts and not b.sensitivity_breaks, (scene, b.sensitivity_breaks)
        if i:  # the first pair warms up (the d_* Functions are built on first use)
            off.append(a.stats["wall_time"])
            on.append(b.stats["wall_time"])
    return min(off), min(on), a.t.size - 1, a.n_impacts


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every t_end")
    ap.add_argument("--c-repeats", type=int, default=50, help="repeats on C (its runs take microseconds)")
    ap.add_argument("--c-fallback", action="store_true", help="time C's fallback (Python stepper) too")
    ap.add_argument("--rule", default="trapezoid", help="the rule of every build (default trapezoid)")
    args = ap.parse_args(argv)
    rows = []
    problem = hard_scenes.c_backend_problem()
    for scene in SCENES:
        row = {"scene": scene}
        for backend in ("casadi", "c"):
            if backend == "c" and problem:
                print(f"{scene}: C skipped ({problem})")
                continue
            sim = vcigen.build(SCENES[scene][0](), backend=backend, rule=args.rule)
            if backend == "c" and not (has_own_tangent(sim) or args.c_fallback):
                print(
                    f"{scene}: C skipped: the C backend has no tangent propagation of its own in this tree "
                    "(sens-c); simulate(sensitivities=True) runs the Python stepper over the C kernels "
                    "(--c-fallback times it)"
                )
                continue
            repeats = args.repeats if backend == "casadi" else max(args.repeats, args.c_repeats)
            off, on, steps, impacts = best_times(sim, scene, repeats, args.scale)
            key = backend if backend == "casadi" or has_own_tangent(sim) else "c_fallback"
            row.update(
                {
                    "steps": steps,
                    "impacts": impacts,
                    f"{key}_ns_per_step_off": 1e9 * off / steps,
                    f"{key}_ns_per_step_on": 1e9 * on / steps,
                    f"{key}_ratio": on / off,
                }
            )
            print(
                f"{scene:16s} {key:10s} {steps:5d} steps {impacts:3d} impacts: "
                f"{1e9 * off / steps:9.0f} ns/step off, {1e9 * on / steps:9.0f} on, ratio {on / off:6.2f}"
            )
        rows.append(row)
    suffix = "" if args.rule == "trapezoid" else f"_{args.rule}"
    out = HERE / "results" / f"sensitivity_cost{suffix}.csv"
    out.parent.mkdir(exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, keys)
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
