r"""Sensitivities of random runs against central differences: ``res.sensitivity`` (API.md, *Sensitivities*)
through impacts, held steps, lift-offs and friction, column by column, over the random campaigns' draws.

    .venv/bin/python -m bench.sens_fuzz [--scene plate hoop ...] [--draws 100] [--seed 1] [--backend c]
        [--rule trapezoid]

For each draw of a scene (the draws of its campaign bench, below) the run with ``sensitivities=True`` gives
``S_K = d(q_K, p_K) / d(q0, v0, params)`` at ``K``, the grid point where its first break is booked
(``res.sensitivity_breaks``: NaN from there) or the run's end. Each column ``x`` of ``S_K`` is checked against
central differences of runs from ``x +- eps`` and ``x +- eps / 4`` (``eps = 1e-5 max(1, |x|)``), where:

* each of those four runs has the run's mode sequence up to ``K`` (the same impacts, of the same kind on the
  same contacts in the same steps; the same lift-offs; the same held contacts at every grid point), else the
  column is *skipped*: the tangent is the derivative "for the mode sequence of the run" (API.md) and a
  difference across a mode change is not one;
* the map is smooth there (:func:`classify`): at a *kink*, where the one-sided differences part by the same
  amount at ``eps`` and ``eps / 4``, the column is not checked either. Kinks are the discrete map's: a hoop
  started rolling exactly (``bench.hoop_drops``' draws) slips for ``O(eps)`` on either side of it and stops
  inside the first step, and the two one-sided derivatives differ at ``O(h^2)`` (``d(q, p) / d v0[x]`` at t =
  0.02: 1.2e-1, 2.9e-2, 7.3e-3, 1.8e-3 at ``h`` = 0.01 to 0.00125; the tangent, the rolling mode's, 4.6e-3 to
  7.2e-5 from their mean: ``--scene hoop --seed 1 --kink 4 'v0[x]'``).

A checked column's error is ``(max |S_K[:, j] - D_j| - d) / max(|D_j|, |S_K[:, j]|, 1e-3)`` with ``D_j`` the
central difference at ``eps / 4`` and ``d`` its distance from the one at ``eps`` (at most 1e-4 of that scale):
what the differences cannot resolve, the runs' solver tolerance over ``eps`` (a cam's flywheel, ``d(q, p) /
dk`` of 1e-4: the tangent within 3e-8 of the difference at ``eps = 1e-4``, 1.8e-5 of the scale at 1e-6, 3e-4
at 1e-8). Printed per scene: the columns checked, skipped and at a kink, the largest error and the draws
above ``--tol`` (1e-4).

Scenes (``h``, ``t_end``): ``plate`` (``tests/test_box_on_a_vibrating_plate.py``; 0.005, 1), ``hoop``
(``bench.hoop_drops``; 0.01, 1), ``cam`` (``bench.cam_drops``), ``table`` (``bench.table_drops``), ``damper``
(``bench.damper_drops``) (0.01, 1 each), ``box_v`` and ``groove`` (``bench.box_v_drops``,
``bench.groove_drops``; 0.01, 2), ``tumbling`` (``bench.tumbling``; 0.005, 2): those eight the default
(``--h``, ``--t-end`` override theirs); and ``box_v_smooth``,
``groove_smooth``, ``cam_smooth``, the frictionless variants of three of them on the same draws (less
``mu``): with ``table`` and ``damper`` what ``--rule lobatto3`` builds (no friction under that rule yet).
``pendulum`` and ``four_bar`` (``bench.chains_fuzz``: a double pendulum on two rods, a parallelogram linkage,
over a rough floor; 0.01, 2): with bilateral constraints a moved start is taken back onto them, ``v0``
tangent (:func:`onto_constraints`), and the column's tangent is ``S_K dz`` along that path. Bodies on bodies
and isotropic cones: ``puck`` (``bench.puck_drops``: three pucks on a rough plane; 0.01, 1), ``pyramid``
(``bench.pyramids``: three disks; 0.01, 2), ``pile`` and ``boxes`` (``bench.stacks_fuzz``: four balls in a
tetrahedron, isotropic cones on the floor, 0.005, 1; a box dropped on a box, 0.01, 2).

    .venv/bin/python -m bench.sens_fuzz --rule lobatto3 \
        --scene box_v_smooth groove_smooth cam_smooth table damper

``--agree``: C's tangent against CasADi's on each draw (:func:`agree`; ``--only I ...``: those draws alone):
the breaks, and the tangents up to the earlier first break, beside the runs' own gap. ``--kink DRAW
COLUMN``: :func:`kink_widths`.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
import sympy as sp

import vcigen
from bench.random_runs import Start, quiet

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

EPS = 1e-5  # the larger difference step, relative to max(1, |x|)
AGREE = 1e-4  # the two central differences agree to this of the column's scale
KINK = 1e-4  # one-sided differences parting by more than this of the scale, not shrinking with eps: a kink
# (a smaller kink would be checked, its error below --tol's default)
FLOOR = 1e-3  # the least scale of a column
KINK_HS = (0.01, 0.005, 0.0025, 0.00125)  # --kink's steps


class Scene(NamedTuple):
    """A scene: its model's maker and its draw as ``"module:function"`` (``bench.*`` or a test module), the
    step and the end time, the maker's keywords."""

    model: str
    draw: str
    h: float
    t_end: float
    keywords: dict = {}


# the *_smooth scenes: the models without friction (what lobatto3 builds), on the same draws
SMOOTH = {"rough": False}
PLATE = "test_box_on_a_vibrating_plate"
SCENES = {
    "plate": Scene(f"{PLATE}:box_on_plate", f"{PLATE}:draw", 0.005, 1.0),
    "hoop": Scene("test_hopping_hoop:hoop", "bench.hoop_drops:draw", 0.01, 1.0),
    "cam": Scene("test_cam_follower:cam", "bench.cam_drops:draw", 0.01, 1.0),
    "cam_smooth": Scene("test_cam_follower:cam", "bench.cam_drops:draw", 0.01, 1.0, SMOOTH),
    "table": Scene("test_shaken_table:table", "bench.table_drops:draw", 0.01, 1.0),
    "damper": Scene("test_impact_damper:impact_damper.model", "bench.damper_drops:draw", 0.01, 1.0),
    "box_v": Scene("bench.box_v_drops:model", "bench.box_v_drops:draw", 0.01, 2.0),
    "box_v_smooth": Scene("bench.box_v_drops:model", "bench.box_v_drops:draw", 0.01, 2.0, SMOOTH),
    "groove": Scene("bench.groove_drops:model", "bench.groove_drops:draw", 0.01, 2.0),
    "groove_smooth": Scene("bench.groove_drops:model", "bench.groove_drops:draw", 0.01, 2.0, SMOOTH),
    "tumbling": Scene("test_tumbling_box:tumble", "bench.tumbling:drop", 0.005, 2.0),
    "puck": Scene("bench.puck_drops:model", "bench.puck_drops:scene", 0.01, 1.0),
    "pyramid": Scene("bench.pyramids:pyramid.model", "bench.pyramids:draw", 0.01, 2.0),
    "pile": Scene("bench.stacks_fuzz:tetra_pile", "bench.stacks_fuzz:pile_draw", 0.005, 1.0),
    "boxes": Scene("bench.stacks_fuzz:two_boxes", "bench.stacks_fuzz:boxes_draw", 0.01, 2.0),
    "pendulum": Scene("bench.chains_fuzz:pendulum", "bench.chains_fuzz:pendulum_draw", 0.01, 2.0),
    "four_bar": Scene("bench.chains_fuzz:linkage", "bench.chains_fuzz:linkage_draw", 0.01, 2.0),
}
ROUGH = ["box_v", "cam", "damper", "groove", "hoop", "plate", "table", "tumbling"]  # the default scenes


def onto_constraints(model: vcigen.Model) -> Callable[[Start], Start] | None:
    """``start -> start`` onto the model's bilateral constraints ``g(q) = 0`` (Newton along ``grad g``) with
    ``v0`` tangent to them (``v0 - G^T (G G^T)^-1 G v0``): the start a moved column leaves; None without
    constraints."""
    if not model.constraints:
        return None
    q, pars = list(model.q), list(model.params)
    g = sp.Matrix(list(model.constraints.values()))
    g_fn, jac_fn = sp.lambdify([q, pars], g, "numpy"), sp.lambdify([q, pars], g.jacobian(q), "numpy")
    defaults = {str(k): float(v) for k, v in model.params.items()}

    def onto(start: Start) -> Start:
        par = [start[2].get(str(k), defaults[str(k)]) for k in pars]
        x = np.array(start[0], dtype=float)
        for _ in range(50):
            r = np.asarray(g_fn(x, par), dtype=float).ravel()
            if np.abs(r).max() <= 1e-15:
                break
            jac = np.asarray(jac_fn(x, par), dtype=float)
            x = x - jac.T @ np.linalg.solve(jac @ jac.T, r)
        jac = np.asarray(jac_fn(x, par), dtype=float)
        v = np.array(start[1], dtype=float)
        v = v - jac.T @ np.linalg.solve(jac @ jac.T, jac @ v)
        return x.tolist(), v.tolist(), dict(start[2])

    return onto


def _named(where: str) -> Callable:
    """``"module:a.b"``: that module's ``a.b``."""
    module, path = where.split(":")
    obj = importlib.import_module(module)
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def scene(
    name: str, backend: str, rule: str = "trapezoid"
) -> tuple[vcigen.Simulator, Callable[[np.random.Generator], Start], Callable[[Start], Start] | None]:
    """The scene's simulator, its draw ``rng -> (q0, v0, params)`` (its campaign's draws, in its order; the
    parameters the model does not have, a smooth variant's ``mu``, left out; on the model's constraints) and
    :func:`onto_constraints`."""
    sc = SCENES[name]
    model = _named(sc.model)(**sc.keywords)
    sim = vcigen.build(model, backend=backend, rule=rule)
    known = {str(k) for k in model.params}
    drawn = _named(sc.draw)
    onto = onto_constraints(model)

    def draw(rng: np.random.Generator) -> Start:
        d = drawn(rng)  # a dict of simulate's arguments, (params, q0, v0) or (q0, v0, params)
        if isinstance(d, dict):
            q0, v0, params = d["q0"], d["v0"], d.get("params", {})
        elif isinstance(d[0], dict):
            params, q0, v0 = d
        else:
            q0, v0, params = d
        q0, v0 = [float(x) for x in q0], [float(x) for x in v0]
        start = q0, v0, {k: v for k, v in params.items() if k in known}
        return start if onto is None else onto(start)

    return sim, draw, onto


def first_break(res: vcigen.Result) -> int:
    """The grid point where the tangent's first break is booked (NaN after it), or the run's last."""
    return res.sensitivity_breaks[0][0] if res.sensitivity_breaks else len(res.t) - 1


def end_state(res: vcigen.Result, k: int) -> np.ndarray:
    """``(q_k, p_k)``: the rows of the tangent ``res.sensitivity[k]``."""
    return np.concatenate([res.q[k], res.p[k]])


def steps(name: str, h: float | None, t_end: float | None) -> tuple[float, float]:
    """The scene's ``h`` and ``t_end`` unless given."""
    return (SCENES[name].h if h is None else h), (SCENES[name].t_end if t_end is None else t_end)


def modes(res: vcigen.Result, k: int) -> tuple:
    """The run's mode sequence up to grid point ``k``: impacts (step, contact, kind), lift-offs (step,
    contact) and the held contacts at each grid point."""
    h, t0 = res.h, float(res.t[0])
    impacts = [(im.step, im.contact, im.kind) for im in res.impacts if im.step < k]
    lifts = [(int((t - t0) // h), c) for t, c in res.liftoffs if t < t0 + k * h - 1e-12 * h]
    held = res.active[: k + 1].tobytes() if res.active is not None else b""
    return impacts, lifts, held


def moved(start: Start, names: list[str], j: int, dx: float) -> Start:
    """``start`` with its ``j``-th column (of ``res.sensitivity_names``: q0, v0, then params) moved by dx."""
    q0, v0, params = list(start[0]), list(start[1]), dict(start[2])
    n = len(q0)
    if j < n:
        q0[j] += dx
    elif j < 2 * n:
        v0[j - n] += dx
    else:
        params[names[j]] += dx
    return q0, v0, params


def value(start: Start, names: list[str], j: int) -> float:
    n = len(start[0])
    return float(start[0][j] if j < n else start[1][j - n] if j < 2 * n else start[2][names[j]])


def classify(base, ends: dict[float, np.ndarray], eps: float, tangent) -> tuple[str, float]:
    """``("checked", error)`` or ``("kink", nan)`` from the ends ``ends[dx]`` of the runs moved by ``dx`` in
    ``(eps, -eps, eps/4, -eps/4)`` and the unmoved run's ``base``: a kink where the one-sided differences part
    by more than ``KINK`` of the scale and by more than half as much at ``eps / 4`` as at ``eps`` (on a smooth
    map they part by ``O(eps)``), or where the two central differences disagree by more than ``AGREE``."""
    if not np.isfinite(tangent).all():  # before the first break the tangent is finite: an error
        return "checked", float("inf")
    e4 = eps / 4
    central = (ends[e4] - ends[-e4]) / (2 * e4)
    scale = max(float(np.abs(central).max()), float(np.abs(tangent).max()), FLOOR)
    parted = float(np.abs(ends[eps] + ends[-eps] - 2 * base).max()) / eps
    parted4 = float(np.abs(ends[e4] + ends[-e4] - 2 * base).max()) / e4
    wide = (ends[eps] - ends[-eps]) / (2 * eps)
    spread = float(np.abs(wide - central).max())
    if (parted4 > KINK * scale and parted4 > 0.5 * parted) or spread > AGREE * scale:
        return "kink", float("nan")
    return "checked", max(0.0, float(np.abs(np.asarray(tangent) - central).max()) - spread) / scale


def flat(start: Start, names: list[str]) -> np.ndarray:
    """``(q0, v0, params)`` in the order of the tangent's columns."""
    n = len(start[0])
    return np.array([*start[0], *start[1], *(start[2][name] for name in names[2 * n :])], dtype=float)


def check_draw(sim: vcigen.Simulator, start: Start, h: float, t_end: float, onto=None) -> dict:
    """The columns of one draw: ``{"k": K, "columns": {name: ("checked", error) | ("kink", nan) | ("skipped",
    nan)}, "impacts": impacts before K, "breaks": the first break}``; None where the run raises. With
    ``onto`` (:func:`onto_constraints`) each moved start is taken onto the constraints, and the column's
    tangent is ``S_K dz``, ``dz`` the central difference of those starts: the derivative along that path."""
    try:
        res = quiet(sim, start, h, t_end, sensitivities=True)
    except vcigen.SolverError:
        return None
    k = first_break(res)
    names, sig = res.sensitivity_names, modes(res, k)
    base = end_state(res, k)
    columns = {}
    for j, name in enumerate(names):
        eps = EPS * max(1.0, abs(value(start, names, j)))
        ends, starts = {}, {}
        for dx in (eps, -eps, eps / 4, -eps / 4):
            starts[dx] = moved(start, names, j, dx) if onto is None else onto(moved(start, names, j, dx))
            try:
                other = quiet(sim, starts[dx], h, t_end)
            except (vcigen.SolverError, ValueError):  # ValueError: moved out of the admissible set
                break
            if modes(other, k) != sig:
                break
            ends[dx] = end_state(other, k)
        if len(ends) < 4:
            columns[name] = ("skipped", float("nan"))
        elif onto is None:
            columns[name] = classify(base, ends, eps, res.sensitivity[k][:, j])
        else:
            e4 = eps / 4
            dz = (flat(starts[e4], names) - flat(starts[-e4], names)) / (2 * e4)
            columns[name] = classify(base, ends, eps, res.sensitivity[k] @ dz)
    impacts = sum(1 for im in res.impacts if im.step < k)
    held = int(res.active[:k].any(axis=1).sum()) if res.active is not None else 0
    lifts = sum(1 for t, _ in res.liftoffs if t < float(res.t[k]))
    return {
        "k": k,
        "columns": columns,
        "impacts": impacts,
        "held": held,
        "lifts": lifts,
        "breaks": res.sensitivity_breaks[:1],
    }


def fuzz(
    name: str, draws: int, seed: int, backend: str = "c", h: float | None = None, t_end=None, rule="trapezoid"
) -> dict:
    """Every draw of the scene: the tallies of its columns and each draw's largest error."""
    sim, draw, onto = scene(name, backend, rule)
    h, t_end = steps(name, h, t_end)
    rng = np.random.default_rng(seed)
    tally = {"checked": 0, "skipped": 0, "kink": 0}
    through = {"impacts": 0, "held": 0, "lifts": 0}  # the events before the points of the draws checked
    worst, errors = [], 0
    for i in range(draws):
        start = draw(rng)
        out = check_draw(sim, start, h, t_end, onto)
        if out is None:
            errors += 1
            continue
        checked = [(err, col) for col, (kind, err) in out["columns"].items() if kind == "checked"]
        for kind, _ in out["columns"].values():
            tally[kind] += 1
        if checked:
            for key in through:
                through[key] += out[key]
            err, col = max(checked)
            worst.append((err, i, col, out["k"], out["impacts"], out["breaks"]))
    worst.sort(reverse=True)
    return {"tally": tally, "through": through, "worst": worst, "errors": errors, "h": h, "t_end": t_end}


def agree(
    name: str,
    draws: int,
    seed: int,
    h: float | None = None,
    t_end=None,
    rule="trapezoid",
    only: Sequence[int] | None = None,
) -> dict:
    """The tangents of C and CasADi on the same draws (``only``: those of them alone): the breaks (each
    backend's ``sensitivity_breaks``) and, up to the earlier first break, ``max |S_C - S_CasADi| /
    max(|S_CasADi|, 1)`` over the grid, beside the runs' gap in ``(q, p)`` there (round-off grown by chaos
    parts the tangents with the runs)."""
    sims = {}
    for backend in ("c", "casadi"):
        sims[backend], draw, _ = scene(name, backend, rule)
    h, t_end = steps(name, h, t_end)
    rng = np.random.default_rng(seed)
    rows, errors = [], 0
    for i in range(draws):
        start = draw(rng)
        if only is not None and i not in only:
            continue
        try:
            res = {b: quiet(sims[b], start, h, t_end, sensitivities=True) for b in sims}
        except vcigen.SolverError:
            errors += 1
            continue
        a, b = res["c"], res["casadi"]
        k = min(first_break(a), first_break(b))
        sa, sb = a.sensitivity[: k + 1], b.sensitivity[: k + 1]
        gap_s = float(np.abs(sa - sb).max() / max(float(np.abs(sb).max()), 1.0))
        states = np.abs(np.concatenate([a.q[: k + 1] - b.q[: k + 1], a.p[: k + 1] - b.p[: k + 1]], axis=1))
        same_breaks = list(a.sensitivity_breaks) == list(b.sensitivity_breaks)
        rows.append(
            (
                gap_s,
                i,
                k,
                float(states.max()),
                same_breaks,
                a.sensitivity_breaks[:1],
                b.sensitivity_breaks[:1],
            )
        )
    rows.sort(reverse=True)
    return {"rows": rows, "errors": errors, "h": h, "t_end": t_end}


def kink_widths(
    name: str, seed: int, index: int, column: str, t: float, hs, eps: float = 1e-7
) -> list[tuple]:
    """At the draw ``index`` of the scene's seed, for each ``h`` in ``hs``: ``(h, the one-sided differences'
    gap, the tangent's distance from their mean)`` of ``(q, p)`` at ``t`` in ``column`` (max norms, steps of
    ``eps``). A kink of the discrete map whose gap shrinks as ``h^2`` is the method's error, not the tangent's
    (``--kink``)."""
    sim, draw, _ = scene(name, "c")
    rng = np.random.default_rng(seed)
    for _ in range(index + 1):
        start = draw(rng)
    out = []
    for h in hs:
        k = round(t / h)
        res = quiet(sim, start, h, k * h + h / 2, sensitivities=True)
        names = res.sensitivity_names
        j = names.index(column)
        base = end_state(res, k)
        side = []
        for dx in (eps, -eps):
            other = quiet(sim, moved(start, names, j, dx), h, k * h + h / 2)
            side.append((end_state(other, k) - base) / dx)
        gap = float(np.abs(side[0] - side[1]).max())
        off = float(np.abs(res.sensitivity[k][:, j] - (side[0] + side[1]) / 2).max())
        out.append((h, gap, off))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", nargs="+", choices=sorted(SCENES), default=ROUGH)
    ap.add_argument("--draws", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--backend", choices=["c", "casadi"], default="c")
    ap.add_argument("--rule", choices=sorted(vcigen.RULES), default="trapezoid")
    ap.add_argument("--h", type=float, default=None)
    ap.add_argument("--t-end", type=float, default=None)
    ap.add_argument("--tol", type=float, default=1e-4, help="print the draws whose error is above this")
    ap.add_argument(
        "--kink",
        nargs=2,
        metavar=("DRAW", "COLUMN"),
        help="the one-sided differences of that draw of the first --scene at --at, h = 0.01 / 2^i (C)",
    )
    ap.add_argument("--at", type=float, default=0.02)
    ap.add_argument("--agree", action="store_true", help="C's tangent against CasADi's on each draw instead")
    ap.add_argument("--only", type=int, nargs="+", help="--agree: these draws (of --draws) alone")
    a = ap.parse_args(argv)
    if a.agree:
        return main_agree(a)
    if a.kink:
        print(f"{a.scene[0]}, seed {a.seed}, draw {a.kink[0]}, d(q, p)(t = {a.at}) / d {a.kink[1]}:")
        for h, gap, off in kink_widths(a.scene[0], a.seed, int(a.kink[0]), a.kink[1], a.at, KINK_HS):
            print(
                f"  h = {h:<8g} one-sided differences apart {gap:.2e}; the tangent from their mean {off:.2e}"
            )
        return 0
    above = 0
    for name in a.scene:
        t0 = time.perf_counter()
        try:
            out = fuzz(name, a.draws, a.seed, a.backend, a.h, a.t_end, a.rule)
        except ValueError as err:  # a rule that does not support the model (lobatto3: friction)
            print(f"{name} [{a.backend}, {a.rule}]: not built: {err}", flush=True)
            continue
        tally, worst, through = out["tally"], out["worst"], out["through"]
        largest = f"{worst[0][0]:.1e} (draw {worst[0][1]}, {worst[0][2]})" if worst else "-"
        print(
            f"{name} [{a.backend}, {a.rule}, h = {out['h']}, t_end = {out['t_end']}], {a.draws} draws "
            f"(seed {a.seed}), "
            f"{time.perf_counter() - t0:.0f} s: columns checked {tally['checked']}, skipped (mode changed) "
            f"{tally['skipped']}, at a kink {tally['kink']}; runs raising {out['errors']}; largest error "
            f"{largest}; through {through['impacts']} impacts, {through['held']} held steps, "
            f"{through['lifts']} lift-offs",
            flush=True,
        )
        for err, i, col, k, impacts, breaks in worst:
            if err > a.tol:
                above += 1
                why = f"its first break {breaks[0]}" if breaks else "no break"
                print(f"  draw {i}: {col} {err:.2e} at grid point {k} ({impacts} impacts before it; {why})")
    print(f"draws with an error above {a.tol:g}: {above}")
    return 1 if above else 0


def main_agree(a: argparse.Namespace) -> int:
    """``--agree``: per scene, the draws whose tangents or breaks differ between the backends."""
    apart = 0
    for name in a.scene:
        t0 = time.perf_counter()
        try:
            out = agree(name, a.draws, a.seed, a.h, a.t_end, a.rule, a.only)
        except ValueError as err:
            print(f"{name} [{a.rule}]: not built: {err}", flush=True)
            continue
        rows = out["rows"]
        breaks = sum(1 for r in rows if not r[4])
        largest = f"{rows[0][0]:.1e} (draw {rows[0][1]}, the runs {rows[0][3]:.1e} apart)" if rows else "-"
        which = f"{a.draws} draws" if a.only is None else f"draws {', '.join(map(str, a.only))} of {a.draws}"
        print(
            f"{name} [C against CasADi, {a.rule}, h = {out['h']}, t_end = {out['t_end']}], {which} "
            f"(seed {a.seed}), {time.perf_counter() - t0:.0f} s: runs raising {out['errors']}; other breaks "
            f"{breaks}; largest tangent gap {largest}",
            flush=True,
        )
        for gap_s, i, k, gap_q, same, ba, bb in rows:
            if gap_s > a.tol or not same:
                apart += 1
                print(
                    f"  draw {i}: tangents {gap_s:.2e} apart to grid point {k} (runs {gap_q:.1e}); breaks "
                    f"C {ba}, CasADi {bb}{'' if same else ' (the lists differ)'}"
                )
    print(f"draws whose tangents part by more than {a.tol:g} or whose breaks differ: {apart}")
    return 1 if apart else 0


if __name__ == "__main__":
    sys.exit(main())
