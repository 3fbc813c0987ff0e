"""A :class:`~vcigen.derive.DiscreteSystem` -> the plain render context of the C templates.

The context is a dict of strings, numbers and lists only (it can be dumped as
JSON and read as the contract between Python and the templates). Python decides
*what* is emitted here; the templates in ``templates/`` only lay it out.
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Mapping
from dataclasses import asdict
from typing import Any

import sympy as sp

from .. import __version__
from ..derive import KINK, WHOLE, DiscreteSystem
from ..errors import HELD_NO_ROOT, HELD_ROWS, NONFINITE, NOT_CONVERGED, PHASES, REASON_LEN
from ..explicit import grid_routines, jump_quadratic, path_routines
from ..held import SQRT_POWERS, held_routines
from ..impact_step import unheld_note
from ..implicit import implicit_routines
from ..result import KINDS
from ..routines import Routine
from ..stage import reduced_phases
from ..stepper import Tolerances
from .cheld_map import held_maps, is_held_map
from .cprinter import print_routine_body
from .csens import SENS_REASONS, is_tangent, sens_routines, smooth_map_routine
from .cspecialise import phi_routine


# The Newton of the CasADi backend (casadi.rootfinder 'newton'); the C solver uses the same.
def c_number(v: object) -> str:
    """A Python number as a C99 literal (infinities as ``HUGE_VAL`` from math.h)."""
    if isinstance(v, float) and math.isinf(v):
        return "HUGE_VAL" if v > 0 else "(-HUGE_VAL)"
    if isinstance(v, float) and math.isnan(v):
        raise ValueError("a tolerance is NaN; give a number")
    return repr(v)


NEWTON = {"abstol": 1e-13, "abstol_step": 1e-15, "max_iter": 40}
# A fourth-order rule (internal points) runs Newton to round-off: at abstol 1e-13 the momentum each step
# leaves behind adds up over the steps to more than the h^4 error (5.7e-11 against 2.1e-11 at h = 0.0025
# on star_nonlinear, tests/test_lobatto3.py); the step test |dx| <= abstol_step still ends it.
HIGH_ORDER_ABSTOL = 1e-15


def newton_options(system: DiscreteSystem) -> dict[str, float]:
    """The Newton's stopping rule for ``system`` (both backends)."""
    return NEWTON | ({"abstol": HIGH_ORDER_ABSTOL} if system.stages else {})


# The implicit grid step of a rule with internal points also stops after a full Newton step shorter than
# SETTLED (1 + |x|): with the exact Jacobian the next step would be ~|dx|^2, below round-off, while
# |f| <= HIGH_ORDER_ABSTOL may be out of reach of the residual's round-off (momenta of a few units).
SETTLED = 1e-9


# Damped (backtracking) steps only far from the root: |dx| > DAMP_MIN_STEP (1 + |x|).
DAMPING = {"min_step": 1e-8, "max_halvings": 10}


HELD_SETS_MAX = 6  # rows at most for a held loop per active set (R + R (R - 1) / 2 loops: 21 at 6)


def held_sets(r: int) -> list[dict[str, Any]]:
    """The active sets of one or two rows of a scene with ``r`` rows, each with its switch key in
    ``<model>_held_glide`` (``i`` for ``{i}``, ``r + i r + j`` for ``{i, j}``, ``i < j``), its rows and its
    per-row flags: the held loop specialised to each (constant row indices), none above
    :data:`HELD_SETS_MAX` rows."""
    if r > HELD_SETS_MAX:
        return []
    sets = [[i] for i in range(r)] + [[i, j] for i in range(r) for j in range(i + 1, r)]
    return [
        {
            "key": s[0] if len(s) == 1 else r + s[0] * r + s[1],
            "rows": s,
            "act": [int(k in s) for k in range(r)],
        }
        for s in sets
    ]


def _tol_context(tol: Tolerances) -> dict[str, str]:
    """The tolerances as C literals (``grazing`` as the flag ``grazing_reflect``)."""
    out = {k: c_number(v) for k, v in asdict(tol).items() if k not in ("grazing", "jump_restarts")}
    out["grazing_reflect"] = "1" if tol.grazing == "reflect" else "0"
    out["grazing_contact"] = "1" if tol.grazing == "contact" else "0"
    return out


def model_hash(system: DiscreteSystem) -> str:
    """A stable hash of the model, the rule and the vcigen version (stamped in the sources)."""
    model = system.model
    parts = [
        __version__,
        model.name,
        system.rule.name,
        ",".join(model.coordinate_names),
        sp.srepr(model.L),
        *(f"{c}:{sp.srepr(e)}" for c, e in model.phi.items()),
        *(f"{s.name}={v!r}" for s, v in model.defaults.items()),
        *(f"e:{c}:{sp.srepr(e)}" for c, e in model.restitution_of.items() if e != 1),
        *(f"g:{c}:{sp.srepr(e)}" for c, e in model.constraint.items()),
        *(f"F:{sp.srepr(f)}" for f in model.force),
        *(f"f:{c}:{sp.srepr(mu)}:{sp.srepr(t)}" for c, (mu, t) in model.friction_of.items()),
    ]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:16]


def tangent_only(name: str) -> bool:
    """Whether routine ``name`` reads only into the tangent of the sensitivity variant (its ``d_*`` partials
    and the fused maps): its half-integer powers are printed with ``sqrt`` (``cprinter``), as the trajectory
    never reads them (the plain library and the variant still step bit for bit alike). On the bowl, libm's
    ``pow`` (four calls a step in its fused held tangent) was ~40% of the C time of a run with the tangent."""
    return is_tangent(name) or is_held_map(name) or name == "sens_smooth_map"


# Routines inlined into their loop whatever their size (GCC left held_circle_step out of line: its outputs
# then went through memory, 26 ns a step against 16 inlined, bench.held_curved)
ALWAYS_INLINE = frozenset({"held_circle_step", "held_circle_end"})


def routine_context(r: Routine, inverse_powers: bool = False) -> dict[str, Any]:
    """One routine as printable pieces: signature, temporaries, assignments (after its head's call).

    ``inverse_powers``: ``b^-k`` as ``1/(b ... b)``, not libm's ``pow`` (the routines of a rule with internal
    points: its quadrature nodes put the potential's negative powers in every residual)."""
    temps, outs, fills = print_routine_body(
        r,
        sqrt_powers=r.name in SQRT_POWERS or tangent_only(r.name),
        inverse_powers=inverse_powers or tangent_only(r.name),
        plain_cse=is_held_map(r.name),
    )
    return {
        "name": r.name,
        "doc": r.doc,
        "hot": r.name in ALWAYS_INLINE,
        "inputs": [{"name": a.name, "size": a.size} for a in r.inputs],
        "head": None
        if r.head is None
        else {
            "name": r.head.name,
            "args": [a.name for a in r.head.inputs] + [o.name for o in r.head.outputs],
        },
        "outputs": [
            {
                "name": o.name,
                "size": o.size,
                "rows": o.shape[0],
                "cols": o.shape[1],
                "fill": None if fill is None else {"first": fill[0], "end": fill[1]},
                "entries": [{"index": k, "expr": e} for k, e in entries],
            }
            for o, entries, fill in zip(r.outputs, outs, fills)
        ],
        "unused": []
        if r.head is not None
        else _unused(r, [e for _, e in temps] + [e for o in outs for _, e in o]),
        "temps": [{"name": n, "expr": e} for n, e in temps],
    }


def _unused(r: Routine, printed: list[str]) -> list[str]:
    """The inputs none of whose symbols an output holds, or that the printed C never reads (``(void)`` in C).

    The second catches terms that cancel only in the CSE (``8 (v + 4 u) - 8 (v - 4 u)`` of a stationarity)."""
    used = set().union(*(e.free_symbols for o in r.outputs for e in o.expr.flat())) if r.outputs else set()
    text = "\n".join(printed)
    return [
        a.name
        for a in r.inputs
        if not set(a.symbols) & used or not re.search(rf"\b{re.escape(a.name)}\[", text)
    ]


def with_heads(routines: list[Routine]) -> list[Routine]:
    """``routines`` with each shared :attr:`~vcigen.routines.Routine.head` once, before its first user."""
    out, seen = [], set()
    for r in routines:
        if r.head is not None and r.head.name not in seen:
            seen.add(r.head.name)
            out.append(r.head)
        out.append(r)
    return out


def is_residual(r: Routine) -> bool:
    """A routine of an unknown ``x`` (first input) that the solvers call through an adapter. The tangents
    ``d_<residual>`` (vcigen.tangents) take the same inputs but are only evaluated, directly."""
    return r.inputs[0].name == "x" and not is_tangent(r.name)


def _c_routine(system: DiscreteSystem, r: Routine) -> Routine:
    """``r`` as emitted: with internal points the derived ``segment`` (it takes ``u``) is ``segment_at``, and
    ``<model>_segment`` (newton.c.j2) solves the stage ``u`` first, as ``CasadiKernels.segment`` does."""
    if r.name != "segment" or not system.stages:
        return r
    return Routine("segment_at", r.inputs, r.outputs, r.doc + " At the internal unknowns u.")


def _residual_ids(system: DiscreteSystem) -> list[dict[str, Any]]:
    """Residual routines in a fixed order with an integer id (the ctypes ``solve`` switch).

    ``nx`` is the phase's own unknowns: with internal points the Newton appends and drops them
    (``<model>_newton`` in newton.c.j2); the stage alone is solved inside ``<model>_segment``."""
    out = []
    for name, r in system.routines.items():
        if not is_residual(r) or name == "stage":  # the stage is solved inside <model>_segment
            continue
        offsets, k = [], 0
        for a in r.inputs[1:-1]:  # everything between the unknown and par, flattened
            offsets.append(k)
            k += a.size
        whole = name in WHOLE  # its unknowns are all its own (the constrained step): no stage appended
        nx = r.inputs[0].size - (0 if whole else system.stages)
        out.append({"id": len(out), "name": name, "nx": nx, "offsets": offsets, "nargs": k, "whole": whole})
    return out


def render_context(
    system: DiscreteSystem,
    setup: Mapping[str, Any] | None = None,
    tol: Tolerances | None = None,
    sensitivities: bool = False,
) -> dict[str, Any]:
    """Everything the templates need, as plain data.

    ``sensitivities``: the library variant that propagates the tangent ``d(q_k, p_k)/d(q0, v0, params)``
    inside its loop (MATH.md, *Exact sensitivities*; ``templates/sens.c.j2``). ``system`` must hold the
    ``d_*`` routines (``derive(..., sensitivities=True)``). The variant is the plain library plus the
    tangent's code (its trajectory the same, bit for bit); without the flag the ``d_*`` routines are left
    out, so the plain library is the same whatever the system holds.
    """
    model = system.model
    structure = system.structure  # detected once per system (vcigen.structure), read by both backends
    if sensitivities:
        missing = [r for r in sens_routines(system.contact_names) if r not in system.routines]
        if missing:
            raise ValueError(
                f"the sensitivity variant needs the routines {missing}: "
                "derive(model, rule, sensitivities=True)"
            )
    kept = [r for r in system.routines.values() if sensitivities or not is_tangent(r.name)]
    routines = [_c_routine(system, r) for r in kept]
    routines += [phi_routine(system)]
    sens_map = smooth_map_routine(system) if sensitivities else None  # the smooth step's tangent, fused
    routines += [sens_map] if sens_map else []
    # a held step's tangent per active set of one or two rows, fused (vcigen.backends.cheld_map)
    fused = held_maps(system, held_sets(system.r)) if sensitivities else []
    routines += [r for f in fused for r in (f.atoms, f.phi, f.map)]
    if structure.explicit_path:
        routines += path_routines(system)
    grid = grid_routines(system) if structure.explicit_grid else []
    quad = jump_quadratic(system) if structure.jump_quadratic else None
    routines += grid + ([quad] if quad else [])
    # the implicit grid step (vcigen.implicit): Newton on (46) from the step's hoisted invariants; with
    # internal points on (v, u), u carried from the step before
    implicit = implicit_routines(system) if structure.implicit_grid else []
    direct = {r.name for r in implicit}  # called directly by the implicit grid step, no adapter
    routines += implicit
    held = held_routines(system) if structure.held else []  # the held grid step (vcigen.held)
    routines += held
    # the stage eliminated (vcigen.stage): each Newton phase on (z, its own unknowns but v), and back
    reduced = reduced_phases(system)
    routines += [r for _, rz, back in reduced for r in (rz, back)]
    prefix = model.name
    setup = dict(setup or {})
    n = system.n
    return {
        "prefix": prefix,
        "PREFIX": prefix.upper(),
        "model": model.name,
        "rule": system.rule.name,
        "rule_paper": system.rule.paper,
        "hash": model_hash(system),
        "version": __version__,
        "n": n,
        "ns": system.stages,  # internal unknowns of a segment (internal points): the Newton hides them
        "stages": system.rule.stages,  # internal points (held with their own multipliers when sustained)
        "inner_ratio": repr(system.rule.inner_ratio),  # Lam_m's Newton start per Lam (SustainedSteps)
        "lam_rate": repr(system.rule.lam_rate),  # Lam's force rate times h (the first held step's guess)
        "unheld": unheld_note(system),  # what a jump error adds under such a rule (Stepper._unheld)
        "m": system.m,
        "r": system.r,
        "nc": len(model.constraint),
        "kinds": [{"index": k, "name": nm, "macro": nm.upper()} for k, nm in enumerate(KINDS)],
        "rows": [
            {"index": i, "name": nm, "contact": c, "constraint": k, "stick": f, "free": int(k >= 0 or f >= 0)}
            for i, (nm, c, k, f) in enumerate(
                zip(system.rows.names, system.rows.contact, system.rows.constraint, system.rows.sticks)
                if system.rows
                else ()
            )
        ],
        # Coulomb friction in sustained contact (vcigen.sustained): frictional contacts, their stick rows,
        # and where their slots (slip coefficients, then stick values) start in par
        "nf": len(system.rows.frictional) if system.rows else 0,
        "fric": [
            {"index": f, "contact": j, "stick_row": system.rows.sticks.index(f)}
            for f, j in enumerate(system.rows.frictional if system.rows else ())
        ],
        "fslot": len(model.defaults),
        "nb": sum(len(b) for b in system.rows.branches) if system.rows else 0,
        "branch_first": [
            sum(len(b) for b in system.rows.branches[:f]) for f in range(len(system.rows.branches))
        ]
        if system.rows
        else [],
        "branch_count": [len(b) for b in system.rows.branches] if system.rows else [],
        "kink": c_number(KINK),
        "npar": len(system.params),
        "timed": system.timed,  # the last parameter slot is the time a segment starts at (forces of time)
        "mutable_par": system.timed or bool(system.rows and system.rows.frictional),  # the run's own par copy
        "forced": bool(model.force),  # a step's energy is its last segment's (Lagrange-d'Alembert)
        "frictional": bool(model.friction_of),  # Coulomb friction at impacts (<model>_frictional_law)
        # isotropic cones (two tangents): per contact whether it has one, per frictional contact its partner
        "cone": "friction_cone" in system.routines,
        "cone_contact": [int(len(model.tangents_of.get(c, ())) == 2) for c in system.contact_names],
        "partner": list(system.rows.partner) if system.rows and system.rows.partner else [],
        # two one-tangent frictional contacts or more: one may ride on another's stick (stick_split)
        "stick_split": sum(
            1
            for f in range(len(system.rows.frictional) if system.rows else 0)
            if not (system.rows.partner and system.rows.partner[f] >= 0)
        )
        >= 2,
        "nk": grid[0].outputs[0].size if grid else 0,
        "nks_dim": max(1, implicit[0].outputs[0].size) if implicit else 1,
        "held": bool(held),
        "nkh": held[0].outputs[0].size if held else 0,
        "held_hess": [{"i": i, "j": j, "w": c_number(float(w))} for i, j, w in structure.held_pattern],
        "nh_dim": max(len(structure.held_pattern), 1) if held else 1,
        # per row, 1 where held alone its step is closed-form (held.closed_forms: <model>_held_closed_step);
        # empty when no row has one
        "held_closed": [int(f) for f in structure.held_closed] if any(structure.held_closed) else [],
        # per row, 1 where that closed step is a rotation (vcigen.held_circle: <model>_held_circle_loop);
        # empty when no row has one
        "held_circle": [int(f) for f in structure.held_circle] if any(structure.held_circle) else [],
        "held_sets_max": HELD_SETS_MAX,
        "held_sets": held_sets(system.r) if held else [],
        # the coordinates some row's gradient has: the held step's products with gradients skip the others
        # (terms 0 * x: the same sums for finite x, and a non-finite x still fails the step's checks)
        "held_gcols": list(structure.held_columns),
        "held_gconst": list(structure.held_constant),
        # of those, the coordinates the free acceleration M^-1 rhs has (G1 acc skips the terms g * 0.0)
        "held_acols": [i for i in structure.held_columns if held[4].output("acc").expr[i] != 0],
        "coordinates": list(model.coordinate_names),
        "contacts": [{"index": j, "name": c} for j, c in enumerate(system.contact_names)],
        "row_names": list(system.rows.names) if system.rows else [],
        "params": [
            {"index": k, "name": s.name, "default": repr(float(v))}
            for k, (s, v) in enumerate(model.defaults.items())
        ],
        "phases": [
            {"index": k, "name": ph, "macro": ph.upper().replace(" ", "_")} for k, ph in enumerate(PHASES)
        ],
        "nonfinite": NONFINITE,
        "not_converged": NOT_CONVERGED,
        "held_no_root": HELD_NO_ROOT,
        "held_rows": HELD_ROWS,
        "reason_len": REASON_LEN,
        "tol": _tol_context(tol or Tolerances()),
        "jump_restarts": [c_number(float(f)) for f in (tol or Tolerances()).jump_restarts],
        "newton": {k: repr(v) for k, v in newton_options(system).items()} | {"settled": repr(SETTLED)},
        "damping": {k: repr(v) for k, v in DAMPING.items()},
        "structure": {
            "smooth_linear": structure.smooth_linear,
            "smooth_diagonal": structure.smooth_diagonal,
            "mass_diagonal": structure.mass_diagonal,
            "explicit_path": structure.explicit_path,
            "explicit_grid": structure.explicit_grid,
            "jump_quadratic": structure.jump_quadratic,
            "implicit_grid": structure.implicit_grid,
            # its invariants carried from step to step (not when par changes between steps: time, friction)
            "carry": structure.carry,
            # the stage eliminated in closed form (vcigen.stage): the implicit grid step's Newton on the
            # internal point's mean velocity z = offset v + u alone; linear: one solve
            "stage_reduced": structure.stage_reduced,
            "stage_linear": structure.stage_linear,
        },
        # the internal point's place: z = node v + u (vcigen.stage)
        "stage_offset": c_number(float(system.rule.nodes[0])) if structure.stage_reduced else "0.0",
        "reduced": [name for name, _, _ in reduced],
        "stage_guess": any(r.name == "smooth_guess" for r in implicit),  # vcigen.stage.predictor
        # the sizes <model>_solve_sized unrolls: the stage, (v, u) and the phases with u; their reductions
        "sized": sorted(
            {system.stages, n + system.stages, n + system.stages + 1, n + system.stages + 2}
            | ({n + 1, n + 2} if reduced else set())
        )
        if system.stages
        else [],
        "structure_lines": structure.lines(),  # each flag and why, for the header's comment block
        "notes": structure.notes(system),
        "routines": [routine_context(r, inverse_powers=bool(system.stages)) for r in with_heads(routines)],
        "adapters": [
            {"name": r.name, "args": list(range(len(r.inputs) - 1)), "outs": list(range(len(r.outputs)))}
            for r in routines
            # the implicit grid step's routines are called directly; the stage's adapter is <model>_segment's
            if is_residual(r) and r.name not in direct
        ],
        "residuals": _residual_ids(system),
        # the sensitivity variant (templates/sens.c.j2): K = 2n + P columns, P the model's parameters
        "sens": bool(sensitivities),
        "sens_map": sens_map is not None,
        "held_maps": [f.context() for f in fused],
        "np": len(model.defaults),
        "sens_reasons": [
            {"index": k, "name": why, "macro": macro} for k, (macro, why) in enumerate(SENS_REASONS)
        ],
        "setup": {
            "q0": [repr(float(x)) for x in setup.get("q0", [0.0] * n)],
            "v0": [repr(float(x)) for x in setup.get("v0", [0.0] * n)],
            "h": repr(float(setup.get("h", 0.01))),
            "t_end": repr(float(setup["t_end"])) if setup.get("t_end") is not None else "-1.0",
            "n_impacts": str(int(setup["n_impacts"])) if setup.get("n_impacts") is not None else "-1",
        },
    }
