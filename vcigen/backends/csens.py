"""Exact sensitivities in C: the library variant whose loop carries the tangent, and its runs.

``simulate(..., sensitivities=True)`` on the C backend builds (once, lazily, cached like the plain one) a
second library of the model: its system with the ``d_*`` routines (:func:`vcigen.tangents.tangent_routines`)
rendered with ``render_context(..., sensitivities=True)`` (``CSimulator.sens_kernels``). The variant is
the plain library plus the tangent's code, so the trajectory is the same bit for bit;
``templates/sens.c.j2`` propagates ``S_k = d(q_k, p_k)/d(q0, v0, params)`` inside ``<model>_run`` through
every phase, as :mod:`vcigen.sensitivity` does for the Python stepper (same phases, same order, same
breaks). A scene that never asks never builds it.

:class:`SensRun` is a :class:`~vcigen.backends.crun.CRun` with the tangent's buffers: ``s`` (the current
``2n x K`` tangent, in/out of every call like ``q, p``), ``S`` (its rows, grown with ``Q``), ``W`` (one
uint32 per grid step: the bits of :data:`SENS_REASONS` of why it is not covered) and ``lost``.
"""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np
import sympy as sp

from ..derive import DiscreteSystem
from ..explicit import expanded
from ..result import BREAK_REASONS, Result
from ..routines import Arg, Output, Routine
from ..tangents import is_tangent
from .crun import RESERVE_BYTES, CRun, Job, _addr, _cut, _grown

__all__ = ["SENS_REASONS", "SensJob", "SensRun", "is_tangent", "sens_routines", "smooth_map_routine"]
SYMBOLIC_MAP = 3  # coordinates at most for the smooth step's tangent as one straight-line routine

# Why a grid step has no tangent: (C macro <MODEL>_WHY_<macro>, Result.sensitivity_breaks reason), in the
# order of the bits of W (vcigen.result.BREAK_REASONS, which the Python tracker's list is ordered by too).
SENS_REASONS = BREAK_REASONS
BASE_ROUTINES = ("d_segment", "d_contacts", "d_legendre", "d_restitution", "d_smooth", "d_jump")


def sens_routines(contact_names: tuple[str, ...]) -> list[str]:
    """The ``d_*`` routines the variant calls (vcigen.tangents)."""
    per = [f"d_{kind}_{c}" for c in contact_names for kind in ("contact_time", "jump_contact")]
    return [*BASE_ROUTINES, *per]


def smooth_map_routine(system: DiscreteSystem) -> Routine | None:
    """``sens_smooth_map(q0, v, tau, par, s) -> s1``: the tangent of a smooth grid step (46) as one CSE'd
    straight-line routine, ``S_k -> S_k+1`` (``s``, ``s1``: ``2n x K`` row-major), or ``None`` past
    :data:`SYMBOLIC_MAP` coordinates (then ``templates/sens_smooth.c.j2`` solves it numerically).

    The smooth residual is ``p-(q0, v, tau) - p0``, so with ``d_segment``'s partials
    ``dv = -J^-1 (dp-/dq0 dq - dp + dp-/dpar dpar)``, ``J = dp-/dv`` (its entries expanded, so that a
    constant diagonal mass is seen as one: then a division per row, else the adjugate over the
    determinant), ``dq1 = dq + tau dv``, ``dp1 = dp+/dq0 dq + dp+/dv dv + dp+/dpar dpar``; ``dpar/dz`` is
    ``I_P`` on the model's parameters (the time slot of a grid step is ``t_k``, fixed). The same algebra as
    the numeric path and ``vcigen.sensitivity.Tangents.smooth_map``, the solve done once symbolically.
    """
    n = system.n
    if n > SYMBOLIC_MAP or system.stages:  # internal points: the numeric path with (v, u) (sens_smooth.c.j2)
        return None
    d = system.routines["d_segment"]
    q0, v, tau, par = d.inputs
    npar, big_p = par.size, len(system.model.defaults)
    k = 2 * n + big_p
    s = Arg("s", tuple(sp.Dummy(f"s{i}", real=True) for i in range(2 * n * k)))
    smat = sp.Matrix(2 * n, k, list(s.symbols))
    dq, dp = smat[:n, :], smat[n:, :]
    dpar = sp.zeros(npar, k)
    for i in range(big_p):
        dpar[i, 2 * n + i] = 1
    dpm, dpp = d.output("dp_minus").expr, d.output("dp_plus").expr
    jac = expanded(dpm[:, n : 2 * n])
    rhs = dpm[:, :n] * dq - dp + dpm[:, 2 * n + 1 :] * dpar
    if jac.is_diagonal():
        dv = sp.Matrix(n, k, lambda i, j: -rhs[i, j] * sp.Pow(jac[i, i], -1))
    else:
        inv_det = sp.Pow(jac.det(method="berkowitz"), -1)
        dv = -(jac.adjugate(method="berkowitz") * rhs) * inv_det
    h = tau.symbols[0]
    s1 = (dq + h * dv).col_join(dpp[:, :n] * dq + dpp[:, n : 2 * n] * dv + dpp[:, 2 * n + 1 :] * dpar)
    return Routine(
        "sens_smooth_map",
        (q0, v, tau, par, s),
        (Output("s1", s1),),
        "The tangent of a smooth grid step (46), S_k -> S_k+1 (vcigen.backends.csens.smooth_map_routine).",
    )


class SensJob(Job):
    """``<model>_job_t`` of the variant: the fields of :class:`Job`, then the tangent's (model.h.j2)."""

    _fields_ = [
        ("s", ctypes.c_void_p),
        ("S", ctypes.c_void_p),
        ("W", ctypes.c_void_p),
        ("lost", ctypes.c_long),
    ]


def column_names(model: Any) -> list[str]:
    """The ``K`` columns ``q0[<coord>]..., v0[<coord>]..., <param>...`` (``Result.sensitivity_names``)."""
    coords = model.coordinate_names
    return [f"q0[{c}]" for c in coords] + [f"v0[{c}]" for c in coords] + [str(s) for s in model.defaults]


class SensRun(CRun):
    """A run of the variant's ``<model>_run``: a :class:`CRun` that also carries the tangent from ``s0``."""

    JOB = SensJob

    def __init__(
        self, kern: Any, par: np.ndarray, q0, v0, p0, steps: int, n_impacts, rooms, s0, names
    ) -> None:
        rows = max(RESERVE_BYTES // (8 * max(np.size(s0), 1)), 16)  # a run of unknown length: S reserves as Q
        super().__init__(kern, par, q0, v0, p0, steps, n_impacts, rooms, first_cap=rows)  # its own buffers
        self.s = np.ascontiguousarray(s0, dtype=float).copy()
        self.S = np.empty((self.cap + 1, *self.s.shape))
        self.S[0] = self.s
        self.W = np.zeros(max(self.cap, 1), dtype=np.uint32)
        self.names = names
        self.job.s, self.job.lost = _addr(self.s), -1

    def arm(self, chunk: int) -> SensJob:
        job = super().arm(chunk)
        if self.S.shape[0] < self.cap + 1:  # Q grew: so does S
            self.S = _grown(self.S, self.cap + 1)
            self.W = _grown(self.W, self.cap)
        job.S = _addr(self.S) + self.S.strides[0] * (self.done + 1)
        job.W = _addr(self.W) + self.W.strides[0] * self.done
        return job

    def result(self, t0: float, h: float, wall: float) -> Result:
        """:meth:`CRun.result` with ``sensitivity`` (``(N, 2n, K)``), its names and breaks."""
        s, S, W = self.done, self.S, self.W
        res = super().result(t0, h, wall)
        res.sensitivity = _cut(S, s + 1)
        res.sensitivity_names = list(self.names)
        rows = W[: s + 1 if self.rc else s]  # a failed step's breaks so far, as the Python stepper
        res.sensitivity_breaks = [
            (int(k), why) for k in np.flatnonzero(rows).tolist() for b, (_, why) in enumerate(SENS_REASONS)
            if rows[k] >> b & 1
        ]  # fmt: skip
        lost = int(self.job.lost)
        if lost >= 0:
            res.stats["sensitivity_lost"] = lost
        self.S = self.W = None  # type: ignore[assignment]
        return res
