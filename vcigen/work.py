"""The discrete work of the forces (Lagrange-d'Alembert, MATH.md *Forcing*), booked per grid step.

A segment ``(q0, v, tau)`` starting at ``t0`` does the work ``(f_d- + f_d+) . v`` of the rule's
discrete forces, which is exactly the difference of the energies at its two ends
(``vcigen.derive.Segment``). Across an impact the energy at the end of one segment is the energy
at the start of the next (the alpha-variation with (37)); so with ``res.energy`` the energy at the end
of each step, ``E_k - E_{k-1} - W_k`` is the smooth steps' own bounded O(h^2) error and restitution
losses alone. The work is booked from the run's segments: grid points and impact points.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import sympy as sp

from .derive import DiscreteSystem
from .result import Result

WorkFn = Callable[..., np.ndarray]


def work_function(system: DiscreteSystem) -> WorkFn | None:
    """``(q0 (K, n), v (K, n), tau (K,), par) -> (K,)`` of the segment work, or ``None`` without forces."""
    seg = system.segment
    if not system.model.force or seg is None:
        return None
    par = [sp.Symbol(f"_par{i}") for i in range(len(system.params))]
    expr = seg.work.xreplace(dict(zip(system.params, par)))
    fn = sp.lambdify([*seg.q0, *seg.v, seg.tau, *par], expr, modules="numpy")

    def work(q0: np.ndarray, v: np.ndarray, tau: np.ndarray, t0: np.ndarray, values) -> np.ndarray:
        args = list(values) if not system.timed else [*list(values)[:-1], t0]
        out = fn(*q0.T, *v.T, tau, *args)
        return np.broadcast_to(np.asarray(out, dtype=float), tau.shape).copy()

    return work


def step_work(res: Result, work: WorkFn | None, par) -> np.ndarray:
    """``(N-1,)``: the discrete work over each grid step, summed over its segments (0 without forces)."""
    steps = res.energy.size
    if work is None or steps == 0:
        return np.zeros(steps)
    q, t, h = res.q, res.t, res.h
    out = work(q[:-1], (q[1:] - q[:-1]) / h, np.full(steps, h), t[:-1], par)
    by_step: dict[int, list] = {}
    for im in res.impacts:
        if im.step < steps:
            by_step.setdefault(im.step, []).append(im)
    for k, ims in by_step.items():
        ims.sort(key=lambda im: im.t)
        ts = np.array([t[k], *(im.t for im in ims), t[k + 1]])
        qs = np.array([q[k], *(im.q for im in ims), q[k + 1]])
        tau = np.diff(ts)
        keep = tau > 1e-14 * h  # simultaneous impacts: no segment between them
        if not keep.any():
            continue
        dq = np.diff(qs, axis=0)[keep]
        out[k] = float(np.sum(work(qs[:-1][keep], dq / tau[keep, None], tau[keep], ts[:-1][keep], par)))
    return out


def tangent_function(system: DiscreteSystem):
    """``q (K, n), par -> (K, m, n)``: each contact's tangent gradient (the derived ``friction`` routine's
    ``tgrad``; 0 where frictionless), or ``None`` without friction. With isotropic cones, ``(K, m, 2, n)``:
    the second tangent's (``friction_cone``'s ``tgrad2``) too."""
    routine = system.routines.get("friction")
    if routine is None:
        return None
    q, par = routine.input("q").symbols, routine.input("par").symbols
    cone = system.routines.get("friction_cone")
    grads = routine.output("tgrad").expr.tolist()
    fns = [sp.lambdify([*q, *par], grads, modules="numpy")]
    if cone is not None:
        fns.append(sp.lambdify([*q, *par], cone.output("tgrad2").expr.tolist(), modules="numpy"))

    def tangents(qs: np.ndarray, values) -> np.ndarray:
        out = [
            np.stack(
                [
                    np.stack([np.broadcast_to(np.asarray(g, float), qs.shape[:1]) for g in row], -1)
                    for row in fn(*qs.T, *values)
                ],
                1,
            )
            for fn in fns
        ]
        return out[0] if len(out) == 1 else np.stack(out, 2)

    return tangents


def friction_work(res: Result, tangents, mu_f, par) -> np.ndarray:
    """``(N-1,)``: the work of Coulomb friction in sustained contact, ``-mu_f lambda h |t . v|`` per step with
    the mean normal force ``lambda`` of ``res.contact_force`` and the tangent gradient ``t`` at the step's
    midpoint (0 while a contact sticks, to round-off). Friction at impacts is in each impact's energy loss."""
    steps = res.energy.size
    if tangents is None or steps == 0 or res.contact_force is None:
        return np.zeros(steps)
    q = res.q
    mid = 0.5 * (q[:-1] + q[1:])
    grads = tangents(mid, par)
    out = np.zeros(steps)
    for j, mu in enumerate(mu_f):
        lam = res.contact_force[:, j]
        held = lam != 0.0
        if not held.any() or mu <= 0.0:
            continue
        dq = q[1:][held] - q[:-1][held]
        if grads.ndim == 3:
            slide = np.abs(np.einsum("kn,kn->k", grads[held, j], dq))
        else:  # isotropic cones: the length of the two-tangent sliding
            slide = np.hypot(*np.einsum("kdn,kn->dk", grads[held, j], dq))
        out[held] -= mu_f[j] * lam[held] * slide
    return out
