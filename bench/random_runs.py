"""Random runs of one scene (``bench.hoop_drops``, ``bench.cam_drops``, ...): each backend's tallies of what
the runs met, and C against CasADi, over draws ``(q0, v0, params)`` from a seeded generator; :func:`dispatch`
runs the mode a bench's command line asks for."""

from __future__ import annotations

import argparse
import math
import time
import warnings
from collections.abc import Callable, Iterator

import numpy as np

import vcigen

Start = tuple[list[float], list[float], dict[str, float]]
PARTED = 1e3  # a gap between two runs that grows this many times in one grid step (above 1e-9): parted there


def arguments(doc: str, seed: int, h: float, drops: int | None = None) -> argparse.ArgumentParser:
    """The options every random-run bench takes: ``--drops`` (``None``: the bench's own default per mode),
    ``--seed``, ``--h``, ``--backend`` (one or both) and ``--agree`` (each run on both backends)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--drops", type=int, default=drops)
    ap.add_argument("--seed", type=int, default=seed)
    ap.add_argument("--h", type=float, default=h)
    ap.add_argument("--backend", nargs="+", default=["c"], choices=["c", "casadi"])
    ap.add_argument("--agree", action="store_true", help="each run on both backends")
    return ap


def quiet(
    sim: vcigen.Simulator, start: Start, h: float, t_end: float, sensitivities: bool = False
) -> vcigen.Result:
    """One run from ``start`` to ``t_end`` at ``h``, its warnings (counted in its stats) not printed."""
    q0, v0, params = start
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return sim.simulate(
            q0=q0, v0=v0, h=h, t_end=t_end, params=params, progress=False, sensitivities=sensitivities
        )


def least_force(res: vcigen.Result) -> float:
    """The least force a run booked (0 where it held nothing)."""
    return float(res.contact_force.min()) if res.contact_force.size else 0.0


def contact_flags(res: vcigen.Result, params: dict | None = None) -> dict[str, bool]:
    """What a run of the contact regimes met: an impact of impulse 0, a grazing impact, a restart of the jump
    (``jump_fallbacks``), a lift-off held on (``lifts_kept``), a booked force below -1e-9, a jam."""
    st = res.stats
    return {
        "impulse 0": any(abs(im.impulse) < 1e-12 for im in res.impacts),
        "grazing": any(im.kind == "grazing" for im in res.impacts),
        "restart": st["jump_fallbacks"] > 0,
        "held on": st["lifts_kept"] > 0,
        "force below 0": least_force(res) < -1e-9,
        "jam": st["jams"] > 0,
    }


def runs(
    sim: vcigen.Simulator,
    draw: Callable[[np.random.Generator], Start],
    drops: int,
    seed: int,
    h: float,
    t_end: float,
    failed: list[int],
    flags: Callable[[vcigen.Result, dict], dict[str, bool]] | None = None,
) -> Iterator[tuple[int, Start, vcigen.Result]]:
    """Each draw's index, start and run to ``t_end``; a run that raises a ``SolverError`` is printed (with the
    ``flags`` that hold on its run so far, ``SolverError.result``), its index appended to ``failed``, and
    skipped."""
    rng = np.random.default_rng(seed)
    for i in range(drops):
        start = draw(rng)
        try:
            res = quiet(sim, start, h, t_end)
        except vcigen.SolverError as exc:
            failed.append(i)
            held = flags(exc.result, start[2]) if flags is not None and exc.result is not None else {}
            noted = ", ".join(k for k, v in held.items() if v)
            print(f"  drop {i} {start}: {str(exc)[:200]}" + (f" [the run so far: {noted}]" if noted else ""))
            continue
        yield i, start, res


def tally(
    sim: vcigen.Simulator,
    draw: Callable[[np.random.Generator], Start],
    flags: Callable[[vcigen.Result, dict], dict[str, bool]],
    extremes: Callable[[vcigen.Result, dict], dict[str, float]],
    drops: int,
    seed: int,
    h: float,
    t_end: float,
) -> None:
    """Prints the runs that raise a ``SolverError`` (and the ``flags`` their runs so far hold), how many runs
    each of ``flags`` holds in, and the extremes over the runs of ``extremes`` (a name starting with "least"
    or "lowest" the least, else the largest); both are called with the run and its start's parameters."""
    count: dict[str, int] = {}
    most: dict[str, float] = {}
    failed: list[int] = []
    t0 = time.perf_counter()
    for _, start, res in runs(sim, draw, drops, seed, h, t_end, failed, flags):
        for key, flag in flags(res, start[2]).items():
            count[key] = count.get(key, 0) + bool(flag)
        for key, value in extremes(res, start[2]).items():
            low = key.startswith(("least", "lowest"))
            old = most.get(key, math.inf if low else -math.inf)
            most[key] = min(old, value) if low else max(old, value)
    wall = time.perf_counter() - t0
    print(f"[{sim.backend}] {drops} runs (seed {seed}, h = {h}), {wall:.1f} s: errors {len(failed)}")
    print("  runs with " + ", ".join(f"{k} {v}" for k, v in count.items()))
    print("  " + "; ".join(f"{k} {v:.3g}" for k, v in most.items()))


def parted(a: vcigen.Result, b: vcigen.Result) -> tuple[float, float, float] | None:
    """Where two runs of one start part in one grid step: ``(t, gap before, gap after)`` at the first step
    whose largest difference in ``q`` grows ``PARTED``-fold to above 1e-9 (something decided otherwise: an
    event's order, a force's sign; or an impact that amplifies that much), else ``None``: round-off grown
    smoothly, as chaotic motion grows it impact by impact (a tumbling box, 1e-16 to 5e-6 over 13 impacts)."""
    n = min(a.t.size, b.t.size)
    gap = np.abs(a.q[:n] - b.q[:n]).max(axis=1)
    jump = (gap[1:] > 1e-9) & (gap[1:] > PARTED * gap[:-1])
    if not jump.any():
        return None
    j = int(np.argmax(jump)) + 1
    return float(a.t[j]), float(gap[j - 1]), float(gap[j])


def how_apart(where: tuple[float, float, float] | None) -> str:
    """:func:`parted`'s answer ``where`` as a phrase."""
    if where is None:
        return "round-off grown"
    return f"parted in the step to t = {where[0]:.6g} ({where[1]:.1e} -> {where[2]:.1e})"


def agree(
    sims: dict[str, vcigen.Simulator],
    draw: Callable[[np.random.Generator], Start],
    drops: int,
    seed: int,
    h: float,
    t_end: float,
) -> None:
    """Each draw on both backends (``sims["c"]``, ``sims["casadi"]``): the runs more than 1e-6 apart in ``q``
    or with other impact counts printed, each with where they parted (:func:`parted`), then how many, how
    many parted in one step, and the largest gap."""
    rng = np.random.default_rng(seed)
    apart, split, worst = 0, 0, 0.0
    for i in range(drops):
        start = draw(rng)
        try:
            c, cas = quiet(sims["c"], start, h, t_end), quiet(sims["casadi"], start, h, t_end)
        except vcigen.SolverError as exc:
            print(f"  drop {i} {start}: {str(exc)[:200]}")
            continue
        gap = float(np.abs(c.q - cas.q).max())
        worst = max(worst, gap)
        if gap > 1e-6 or len(c.impacts) != len(cas.impacts):
            apart += 1
            where = parted(c, cas)
            split += where is not None
            counts = f"impacts C {len(c.impacts)}, CasADi {len(cas.impacts)}"
            print(f"  drop {i} {start[2]}: {gap:.2e} apart; {counts}; {how_apart(where)}")
    print(
        f"C against CasADi, {drops} runs (seed {seed}, h = {h}): apart {apart} "
        f"(parted in one step: {split}); largest apart {worst:.1e}"
    )


def dispatch(
    args: argparse.Namespace,
    simulator: Callable[[str], vcigen.Simulator],
    draw: Callable[[np.random.Generator], Start],
    flags: Callable[[vcigen.Result, dict], dict[str, bool]],
    extremes: Callable[[vcigen.Result, dict], dict[str, float]],
    t_end: float,
    drops: dict[str, int],
    modes: dict[str, Callable[[int, int, float], None]] | None = None,
    agree_t_end: float | None = None,
) -> None:
    """Runs the mode of a bench's parsed ``args`` (:func:`arguments`): ``--agree`` (:func:`agree`), else the
    first of ``modes`` whose option is set (called with the drops, seed and h), else each backend's
    :func:`tally`; ``--drops`` or, unset, ``drops[mode]`` (``"agree"``, ``"tally"``, each of ``modes``); runs
    to ``t_end`` (``--agree``'s to ``agree_t_end`` where given)."""
    chosen = "agree" if args.agree else next((m for m in modes or {} if getattr(args, m)), "tally")
    count = args.drops or drops[chosen]
    if chosen == "agree":
        sims = {b: simulator(b) for b in ("c", "casadi")}
        agree(sims, draw, count, args.seed, args.h, t_end if agree_t_end is None else agree_t_end)
    elif chosen == "tally":
        for backend in args.backend:
            tally(simulator(backend), draw, flags, extremes, count, args.seed, args.h, t_end)
    else:
        modes[chosen](count, args.seed, args.h)


def lift_offs_against(
    sim: vcigen.Simulator,
    draw: Callable[[np.random.Generator], Start],
    reference: Callable[[Start, float], list[float]],
    drops: int,
    seed: int,
    h: float,
    t_end: float,
    until: float,
    tol: float,
) -> None:
    """Each draw's run to ``t_end`` against ``reference(start, t_end)``, its lift-off times: the runs that
    raise a ``SolverError`` and those whose lift-offs before ``until`` differ from the reference's in number
    or by more than ``tol`` (each printed), then how many, and the largest difference over h^2 of the
    others."""
    differ, worst, failed = 0, 0.0, []
    for i, start, res in runs(sim, draw, drops, seed, h, t_end, failed):
        lifts = [u for u in reference(start, t_end) if u < until]
        mine = [t for t, _ in res.liftoffs if t < until]
        apart = max((abs(t - u) for t, u in zip(mine, lifts)), default=0.0)
        if len(mine) != len(lifts) or apart > tol:
            differ += 1
            counts = f"lift-offs {len(mine)}, reference {len(lifts)}"
            print(f"  drop {i} {start}: {counts}; apart {apart / h**2:.3g} h^2")
        else:
            worst = max(worst, apart / h**2)
    head = f"[{sim.backend}] {drops} runs (seed {seed}, h = {h}): errors {len(failed)}"
    print(f"{head}; lift-offs other than the reference's in {differ}; the others within {worst:.3g} h^2")
