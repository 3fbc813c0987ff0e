"""The internal stage of a rule with internal points, eliminated in closed form where the model allows.

Every phase of a rule with an internal point (``lobatto3``) is a Newton on its own unknowns and the
stage's ``u`` (``2n`` for the smooth step (46)). lobatto3 writes the internal point as
``q_m = q0 + tau (v/2 + u)`` (:func:`vcigen.rules._lobatto3`); in the internal point's own mean velocity
``z = (q_m - q0)/tau = v/2 + u`` (:attr:`vcigen.rules.Rule.nodes`), the momentum rows of a
phase, ``p-(q0, v, tau, u) - p0``, are for ``L = 1/2 qdot.M qdot - V(q)`` with a constant ``M``

    p- - p0 = M v + (tau/3) grad V(q0 + tau z) + (tau/6) grad V(q0) - p0,

linear in ``v`` with the constant Jacobian ``M``. Solved for ``v`` in closed form,
``v(z) = M^-1 (p0 - (tau/6) grad V(q0) - (tau/3) grad V(q0 + tau z))``, and put in the stage's
stationarity rows, they leave ``n`` rows in ``z``: (46) becomes ``n`` unknowns instead of ``2n``, with
the ``n x n`` Jacobian ``(16/3) M + (2 tau^2/9) Hess V(q_m)`` (O(1): nothing divides by a sub-step).

The reduction is generic (:func:`reduce_rows`): substitute ``u = z - offset v``, require the momentum
rows' Jacobian in ``v`` to be free of ``v`` and ``z`` (checked), solve them for ``v``
symbolically and drop them. What detects it is the Jacobian itself, so a velocity-linear force (damping)
keeps it and a configuration-dependent mass (the double pendulum) does not. When the remaining rows are
linear in ``z`` too (a quadratic ``V``: the oscillator), one Newton step is exact: the step is explicit.

The reduced rows are the stage's stationarity rows at ``v(z)``; the momentum rows hold by construction
(to round-off), so the reduced Newton's residual norm is the full phase's.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import sympy as sp

from .calculus import jacobian
from .routines import Arg, Output, Routine

if TYPE_CHECKING:
    from .derive import DiscreteSystem


@dataclass(frozen=True)
class Reduced:
    """A phase's rows with the momentum rows solved for the velocity (:func:`reduce_rows`).

    ``unknowns``: ``(z, extras)``; ``res``: the stationarity rows then the phase's other rows, in them;
    ``x``: the phase's full unknowns ``(v, extras, u)`` in them (the closed-form back substitution).
    """

    unknowns: tuple[sp.Symbol, ...]
    res: sp.Matrix
    x: sp.Matrix

    def jac(self) -> sp.Matrix:
        return jacobian(self.res, self.unknowns)


def _mixed(rows: sp.Matrix, v, us, offset, zs) -> sp.Matrix:
    """``rows`` with ``u = z - offset v`` (the internal point's argument ``v/2 + u`` collapses to ``z``)."""
    sub = {u: z - offset * vi for u, z, vi in zip(us, zs, v)}
    return rows.xreplace(sub)


def reduce_rows(
    rows: sp.Matrix,
    v: tuple[sp.Symbol, ...],
    extras: tuple[sp.Symbol, ...],
    us: tuple[sp.Symbol, ...],
    offset: sp.Expr,
) -> Reduced | None:
    """``rows`` (stationarity ``ns``, momentum ``n``, then the phase's own) in ``x = (v, extras, u)`` ->
    :class:`Reduced` in ``(z, extras)``, or ``None`` if the momentum rows are not linear in ``v`` at a fixed
    internal point (see the module)."""
    n, ns = len(v), len(us)
    zs = tuple(sp.Dummy(f"z{i}", real=True) for i in range(ns))
    mixed = _mixed(rows, v, us, offset, zs)
    mom = mixed[ns : ns + n, :]
    jac = jacobian(mom, v).applyfunc(sp.expand)  # expanded: terms of v that cancel only then do
    # linear in v at a fixed internal point: its Jacobian free of v and z (a force's share may hold a
    # sub-step alpha, an unknown of (47): v is then a rational function of it, still in closed form)
    if jac.free_symbols & (set(v) | set(zs)):
        return None
    zero = dict.fromkeys(v, sp.S.Zero)
    rhs = -mom.xreplace(zero)
    if all(jac[i, k] == 0 for i in range(n) for k in range(n) if i != k):
        vz = sp.Matrix([rhs[i] / jac[i, i] for i in range(n)])
    else:
        vz = jac.LUsolve(rhs)
    rep = dict(zip(v, vz))
    rest = mixed[:ns, :].col_join(mixed[ns + n :, :]).xreplace(rep)
    u = sp.Matrix([z - offset * vi for z, vi in zip(zs, vz)])
    x = vz.col_join(sp.Matrix(list(extras))).col_join(u) if extras else vz.col_join(u)
    return Reduced(zs + tuple(extras), rest, x)


@lru_cache(maxsize=64)
def _reduced(rows: sp.ImmutableMatrix, v: tuple, extras: tuple, us: tuple, offset: sp.Expr) -> Reduced | None:
    return reduce_rows(sp.Matrix(rows), v, extras, us, offset)


def reduced_smooth(system: DiscreteSystem) -> Reduced | None:
    """The smooth step (46) of ``system`` reduced to its internal point (:func:`reduce_rows`), or ``None``
    (no internal point, no closed form for it, or momentum rows not linear in ``v`` at a fixed one)."""
    if not system.stages or len(system.rule.nodes) != 1:  # one internal point, at a known place
        return None
    offset = system.rule.nodes[0]
    smooth = system.routines["smooth"]
    xs = smooth.inputs[0].symbols
    n = system.n
    return _reduced(sp.ImmutableMatrix(smooth.output("res").expr), xs[:n], (), xs[n:], offset)


def reduced_phases(system: DiscreteSystem) -> list[tuple[str, Routine, Routine]]:
    """Per phase solved by Newton (the smooth step (46), the contact times (47), the jump (48), (78)):
    ``(name, <name>_z, <name>_zback)``, the phase reduced to ``(z, its own unknowns but the velocity)``
    (residual and Jacobian, :func:`reduce_rows`) and the closed form of its full unknowns ``(v, ..., u)``
    from them; empty unless ``system.structure.stage_reduced``. The C Newton of a phase runs on the
    first and returns through the second (templates/newton.c.j2)."""
    if not system.structure.stage_reduced:
        return []
    n, ns, offset = system.n, system.stages, system.rule.nodes[0]
    # the phases whose rows are (stationarity, the momentum rows p- - ..., their own) over unknowns
    # (v, their own, u) (vcigen.derive); others (rows of sustained contact, if a rule with internal points
    # gets them) keep the general Newton
    known = {"smooth", "jump"} | {
        f"{p}_{c}" for p in ("contact_time", "jump_contact") for c in system.contact_names
    }
    out = []
    for name, r in system.routines.items():
        if name not in known:
            continue
        xs = r.inputs[0].symbols
        nx = len(xs) - ns
        res = sp.ImmutableMatrix(r.output("res").expr)
        red = _reduced(res, xs[:n], xs[n:nx], xs[nx:], offset)
        if (
            red is None
        ):  # a force's share nonlinear in v where (46) is not: this phase keeps the general Newton
            continue
        args = r.inputs[1:]
        out.append(
            (
                name,
                Routine(
                    f"{name}_z",
                    (Arg("x", red.unknowns), *args),
                    (Output("res", red.res), Output("jac", red.jac())),
                    f"{name} with the stage eliminated (vcigen.stage): unknowns (z, the phase's own but the "
                    "velocity), rows the stationarity and the phase's own but the momentum rows.",
                ),
                Routine(
                    f"{name}_zback",
                    (Arg("x", red.unknowns), *args),
                    (Output("full", red.x),),
                    f"(v, ..., u) of {name} from the unknowns of {name}_z in closed form (vcigen.stage).",
                ),
            )
        )
    return out


def predictor(red: Reduced, tau: sp.Symbol) -> sp.Matrix | None:
    """A guess of the reduced smooth step's ``z``: one Newton step from ``z = 0`` with the Jacobian at
    ``tau = 0`` (``(16/3) M``), i.e. ``z = M^-1 (p0/2 - (tau/8) grad V(q0))`` for ``T - V``; its error is
    ``O(tau^2 Hess V z)`` (the O(h) of the step before's ``z`` as a guess), so the Newton needs one step
    fewer. ``None`` if that Jacobian depends on ``z``."""
    j0 = red.jac().xreplace({tau: 0}).applyfunc(sp.expand)
    if j0.free_symbols & set(red.unknowns):
        return None
    g0 = -red.res.xreplace(dict.fromkeys(red.unknowns, sp.S.Zero))
    n = j0.rows
    if all(j0[i, k] == 0 for i in range(n) for k in range(n) if i != k):
        return sp.Matrix([g0[i] / j0[i, i] for i in range(n)])
    return j0.LUsolve(g0)
