"""The compiled model through ctypes: the stepper's kernels, and a simulator whose loop runs in C.

:class:`CKernels` gives the kernels interface of :mod:`vcigen.stepper` (so the Python
stepper can also run on the C kernels, for debugging); :class:`CSimulator` calls
``<model>_run_many`` (through :mod:`vcigen.backends.crun`), which takes whole runs of grid steps
(46)-(79) in C, one run or many per call, and resumes a run from ``(q, p)`` (plus the Newton guess
``v``) when one of its buffers must grow (geometrically).
"""

from __future__ import annotations

import ctypes
import gc
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..derive import DiscreteSystem, set_rows
from ..errors import REASON_LEN, SolverError
from ..held_step import Held
from ..progress import Progress
from ..result import Result
from ..simulator import MAX_CONDITION, ManyStarts, Simulator, conditions
from ..stepper import Tolerances, _n_steps, warn_reflected
from ..sustained import rattle_segment
from ..tangents import is_tangent, tangent_routines
from .crun import (
    FIRST_CAP_MANY,
    MAX_STEPS,
    Block,
    CRun,
    batch_results,
    batch_runs,
    chunk_steps,
    run_jobs,
)
from .csens import SensRun, column_names
from .slots import ParameterSlots

_D = ctypes.POINTER(ctypes.c_double)
IMPACT_CAP = 4096  # impact records of one call in bench/c_speed.py's raw runner


class _Tol(ctypes.Structure):
    _fields_ = [
        ("residual", ctypes.c_double),
        ("phi", ctypes.c_double),
        ("admissible", ctypes.c_double),
        ("max_impacts_per_step", ctypes.c_int),
        ("bracket_samples", ctypes.c_int),
        ("dip", ctypes.c_double),
        ("simultaneous", ctypes.c_double),
        ("grazing_reflect", ctypes.c_int),
        ("grazing_contact", ctypes.c_int),
        ("rest", ctypes.c_double),
    ]


class _Err(ctypes.Structure):
    _fields_ = [
        ("step", ctypes.c_long),
        ("time", ctypes.c_double),
        ("phase", ctypes.c_int),
        ("residual", ctypes.c_double),
        ("reason", ctypes.c_char * REASON_LEN),
        ("reflected", ctypes.c_long),
    ]


def sustain_struct(r: int, m: int, nc: int, nf: int = 0, nb: int = 0) -> type[ctypes.Structure]:
    """The ``<model>_sustain_t`` of a model with ``r`` rows, ``m`` contacts, ``nc`` constraints, ``nf``
    frictional contacts."""

    class _Sustain(ctypes.Structure):
        _fields_ = [
            ("act", ctypes.c_int * max(r, 1)),
            ("lam", ctypes.c_double * max(r, 1)),
            ("force", ctypes.c_double * max(m, 1)),
            ("cforce", ctypes.c_double * max(nc, 1)),
            ("liftoffs", _D),
            ("liftoff_cap", ctypes.c_long),
            ("n_liftoffs", ctypes.c_long),
            ("kinds", ctypes.c_long * 4),
            ("fallbacks", ctypes.c_long),
            ("friction_dropped", ctypes.c_long),
            ("restitution_reduced", ctypes.c_long),
            ("least_splits", ctypes.c_long),
            ("passes", ctypes.c_long),
            ("sticks_kept", ctypes.c_long),
            ("lifts_kept", ctypes.c_long),
            ("jams", ctypes.c_long),
            ("halvings", ctypes.c_long),
            ("riders_cut", ctypes.c_long),
            ("events", ctypes.c_int),
            ("jammed", ctypes.c_int),
            ("law_why", ctypes.c_int),
            ("slip", ctypes.c_double * max(nf, 1)),
            ("ref", ctypes.c_double * max(nf, 1)),
            ("branch", ctypes.c_double * max(nb, 1)),
            ("held_rows", ctypes.c_ulong * max(nf, 1)),
            ("ride", ctypes.c_int * max(nf, 1)),
            ("on_rows", ctypes.c_int * max(r, 1)),
            ("bounces", ctypes.c_int * max(r, 1)),
            ("left_step", ctypes.c_long * max(r, 1)),
            ("sunk", ctypes.c_long * max(r, 1)),
            ("sunk_at", ctypes.c_double * max(r, 1)),
            ("sunk_open", ctypes.c_int * max(r, 1)),
        ]

    return _Sustain


def _par_array(par) -> np.ndarray:
    """The parameter vector as C reads it (one unused entry for a model without parameters)."""
    return np.array(par, dtype=float) if len(par) else np.zeros(1)


def _ptr(a: np.ndarray) -> Any:
    return a.ctypes.data_as(_D)


def _vec(x, size: int) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(x, dtype=float).reshape(size))


class CKernels(ParameterSlots):
    """The stepper's kernels (``smooth_step``, ``solve``, ``segment``, ``contacts``, ``legendre``) in C."""

    backend = "c"

    def __init__(self, system: DiscreteSystem, library: Path, ctx: dict[str, Any]) -> None:
        self.system = system
        self.library = Path(library)
        self.n, self.m = system.n, system.m
        self.contact_names = system.contact_names
        self.par = np.array([float(v) for v in system.model.defaults.values()] + [0.0] * system.timed)
        self.timed, self.t = system.timed, 0.0
        self._ids = {r["name"]: (r["id"], r["nx"]) for r in ctx["residuals"]}
        self.lib = ctypes.CDLL(str(self.library))
        pre = ctx["prefix"]
        self._legendre = getattr(self.lib, f"{pre}_eval_legendre")
        self._legendre.argtypes = [ctypes.c_void_p] * 5
        self._segment = getattr(self.lib, f"{pre}_eval_segment")
        self._segment.argtypes = [_D, _D, ctypes.c_double, _D, _D, _D, _D]
        self._rattle_end = getattr(
            self.lib, f"{pre}_eval_rattle_end", None
        )  # only with internal points, rows
        if self._rattle_end is not None:
            self._rattle_end.argtypes = [_D, _D, ctypes.c_double, _D, _D, _D, _D, _D, _D]
        self._start_energy = getattr(self.lib, f"{pre}_eval_start_energy", None)  # only with forces
        if self._start_energy is not None:
            self._start_energy.argtypes = [_D, _D, ctypes.c_double, _D, _D]
        self._contacts = getattr(self.lib, f"{pre}_eval_contacts")
        self._contacts.argtypes = [ctypes.c_void_p] * 4
        # scratch for legendre and contacts (the start of every run): q, v, p, M, phi, grad phi
        size = max(self.m, 1)
        self._scratch = [np.empty(k) for k in (self.n, self.n, self.n, self.n * self.n, size, size * self.n)]
        self._at = [a.__array_interface__["data"][0] for a in self._scratch]
        self._smooth = getattr(self.lib, f"{pre}_eval_smooth_step")
        self._smooth.argtypes = [_D, _D, ctypes.c_double, _D, _D, _D, _D, _D, _D, _D, _D, _D, _D]
        self._rest = getattr(self.lib, f"{pre}_eval_restitution")
        self.structure = system.structure  # the object the render context read (vcigen.structure)
        self.explicit_path = self.structure.explicit_path
        if self.explicit_path:
            self._path = getattr(self.lib, f"{pre}_eval_contact_path")
            self._path.argtypes = [ctypes.c_int, ctypes.c_double, _D, _D, ctypes.c_double, _D, _D, _D, _D]
        self._quad = getattr(self.lib, f"{pre}_eval_jump_quadratic", None)
        if self._quad is not None:
            self._quad.argtypes = [_D, _D, _D, ctypes.c_double, ctypes.c_double, _D, _D, _D, _D]
        set_rows(self, system)
        if self.r:
            self._rows = getattr(self.lib, f"{pre}_eval_rows")
            self._dynamics = getattr(self.lib, f"{pre}_eval_dynamics")
        self.held = self.structure.held  # the held grid step (vcigen.held)
        if self.held:
            self._held = getattr(self.lib, f"{pre}_eval_held_step")
            self._held.argtypes = [_D, ctypes.c_double, ctypes.c_double, ctypes.c_double] + [_D] * 9
            self._held.restype = ctypes.c_int
            self._circle = getattr(self.lib, f"{pre}_eval_held_circle_step", None)  # vcigen.held_circle
            if self._circle is not None:
                self._circle.argtypes = [_D, ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_int]
                self._circle.argtypes += [_D] * 10
                self._circle.restype = ctypes.c_int
            self._closed = getattr(self.lib, f"{pre}_eval_held_closed_step", None)  # held_step.closed_carried
            if self._closed is not None:
                self._closed.argtypes = [_D, ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_int]
                self._closed.argtypes += [_D] * 10
                self._closed.restype = ctypes.c_int
        self.held_circle = list(self.structure.held_circle) if getattr(self, "_circle", None) else []
        self.closed_carried = getattr(self, "_closed", None) is not None  # closed_step with w (HeldSteps)
        self.held_closed = list(self.structure.held_closed)
        self._solve = getattr(self.lib, f"{pre}_solve")
        self._solve.argtypes = [ctypes.c_int, _D, _D, _D, _D]
        self.run = getattr(self.lib, f"{pre}_run")
        self.run.argtypes = [
            _D,
            ctypes.POINTER(_Tol),
            ctypes.c_double,
            ctypes.c_double,
            ctypes.c_long,
            ctypes.c_long,
            ctypes.c_long,
            _D,
            _D,
            _D,
            _D,
            _D,
            _D,
            _D,
            ctypes.c_long,
            ctypes.POINTER(ctypes.c_long),
            ctypes.POINTER(ctypes.c_long),
            ctypes.POINTER(_Err),
            ctypes.c_void_p,
            ctypes.c_void_p,
            _D,
            _D,
        ]
        self.sens = bool(ctx.get("sens"))  # the sensitivity variant (vcigen.backends.csens)
        if self.sens:  # run's tangent: s, S, W, lost; and S_0
            self.run.argtypes += [_D, _D, ctypes.c_void_p, ctypes.POINTER(ctypes.c_long)]
            self.sens_start = getattr(self.lib, f"{pre}_eval_sens_start")
            self.sens_start.argtypes = [_D, _D, _D, _D]
            self.K = 2 * self.n + len(system.model.defaults)
        self.run.restype = ctypes.c_int
        self.run_many = getattr(self.lib, f"{pre}_run_many")
        self.run_many.argtypes = [
            ctypes.POINTER(_Tol),
            ctypes.c_double,
            ctypes.c_double,
            ctypes.c_long,
            ctypes.c_void_p,
        ]
        self.run_many.restype = None
        self.Error = _Err
        self.coordinate_names = list(system.model.coordinate_names)
        self.start = getattr(self.lib, f"{pre}_start")
        self.start.argtypes = [_D, ctypes.POINTER(_Tol), ctypes.c_double, _D, _D, ctypes.c_void_p]
        self.nc = len(system.model.constraint)
        self.Sustain = sustain_struct(self.r, self.m, self.nc, len(self.frictional), sum(self.branch_count))

    def bind(self, par) -> CKernels:
        """Fix the parameter values for the next simulation."""
        self.par = _par_array(par)
        return self

    def legendre(self, q, v):
        sq, sv, smom, smass = self._scratch[:4]
        sq[:], sv[:] = q, v
        at = self._at
        self._legendre(at[0], at[1], self.par.__array_interface__["data"][0], at[2], at[3])
        return smom.copy(), smass.reshape(self.n, self.n).copy()

    def segment(self, q0, v, tau):
        n = self.n
        pm, pp, e = np.empty(n), np.empty(n), np.empty(1)
        self._segment(
            _ptr(_vec(q0, n)), _ptr(_vec(v, n)), float(tau), _ptr(self.par), _ptr(pm), _ptr(pp), _ptr(e)
        )
        return pm, pp, float(e[0])

    def rattle_end(self, q0, v, tau, u, lm, act):
        """``(p+, E_d)`` of a constrained segment with its internal points held (routine ``rattle_end``)."""
        n, pp, e = self.n, np.empty(self.n), np.empty(1)
        ns, nl = self.system.stages, self.r * self.system.rule.stages
        self._rattle_end(
            _ptr(_vec(q0, n)), _ptr(_vec(v, n)), float(tau), _ptr(_vec(u, ns)), _ptr(_vec(lm, nl)),
            _ptr(_vec(np.asarray(act, dtype=float), self.r)), _ptr(self.par), _ptr(pp), _ptr(e),
        )  # fmt: skip
        return pp, float(e[0])

    def start_energy(self, q0, v, tau) -> float:
        """The energy at the segment's start (``E_d - f_d- . v``); without forces ``E_d`` itself."""
        if self._start_energy is None:
            return self.segment(q0, v, tau)[2]
        n, e = self.n, np.empty(1)
        self._start_energy(_ptr(_vec(q0, n)), _ptr(_vec(v, n)), float(tau), _ptr(self.par), _ptr(e))
        return float(e[0])

    def contacts(self, q):
        n, m = self.n, self.m
        sq, sphi, sgrad = self._scratch[0], self._scratch[4], self._scratch[5]
        sq[:] = q
        at = self._at
        self._contacts(at[0], self.par.__array_interface__["data"][0], at[4], at[5])
        return sphi[:m].copy(), sgrad[: m * n].reshape(m, n).copy()

    def smooth_step(self, q0, p0, tau, guess):
        """``(v, |res|, p1, E_d, phi(q0), phi(q1), d0, d1)``, as the CasADi kernels."""
        n, m = self.n, self.m
        v, res, p1, e = np.empty(n), np.empty(1), np.empty(n), np.empty(1)
        phi0, phi1, d0, d1 = (np.empty(max(m, 1)) for _ in range(4))
        self._smooth(
            _ptr(_vec(q0, n)),
            _ptr(_vec(p0, n)),
            float(tau),
            _ptr(_vec(guess, n)),
            _ptr(self.par),
            _ptr(v),
            _ptr(res),
            _ptr(p1),
            _ptr(e),
            _ptr(phi0),
            _ptr(phi1),
            _ptr(d0),
            _ptr(d1),
        )
        return v, float(res[0]), p1, float(e[0]), phi0[:m], phi1[:m], d0[:m], d1[:m]

    def contact_path(self, j: int, s: float, q0, p0, tau: float):
        """``(g, g', v)`` of contact ``j`` along the explicit segment map at fraction ``s`` (47)."""
        n = self.n
        g, dg, v = np.empty(1), np.empty(1), np.empty(n)
        q, p = _vec(q0, n), _vec(p0, n)
        self._path(int(j), float(s), _ptr(q), _ptr(p), float(tau), _ptr(self.par), _ptr(g), _ptr(dg), _ptr(v))
        return float(g[0]), float(dg[0]), v

    def rattle_segment(self, q, p, tau, x0, act):
        """A constrained segment and the evaluations at its end (``vcigen.sustained.rattle_segment``)."""
        return rattle_segment(self, q, p, tau, x0, act)

    def held_step(self, q, p, lam_in, act, h: float, residual: float, phi_tol: float) -> Held | None:
        """``vcigen.held_step.held_step``, by the C loop's own ``<model>_held_step``."""
        n, r = self.n, self.r
        lam, lam1, q1, p1, v, e = (
            np.array(lam_in, dtype=float),  # a copy: the C step writes Lam into it
            np.empty(r),
            np.empty(n),
            np.empty(n),
            np.empty(n),
            np.empty(1),
        )
        acts = _vec(np.asarray(act, dtype=float), r)
        ok = self._held(
            _ptr(self.par), float(h), float(residual), float(phi_tol), _ptr(_vec(q, n)), _ptr(_vec(p, n)),
            _ptr(acts), _ptr(lam), _ptr(lam1), _ptr(q1), _ptr(p1), _ptr(v),
            _ptr(e),
        )  # fmt: skip
        return Held(q1, p1, v, lam, lam1, float(e[0])) if ok else None

    def circle_step(self, q, p, w, row: int, act, h: float, residual: float, phi_tol: float):
        """``vcigen.held_circle.circle_step``, by the C loop's own ``<model>_held_circle_one``: ``(Held, w1)``
        or ``None``; ``w`` ``None`` forms it (``held_circle_start``)."""
        return self._carried(self._circle, 2, q, p, w, row, act, h, residual, phi_tol)

    def closed_step(self, q, p, w, row: int, act, h: float, residual: float, phi_tol: float):
        """``vcigen.held_step.closed_carried``, by the C loop's own ``<model>_held_closed_one``:
        ``(Held, w1)`` or ``None``; ``w`` ``None`` starts from ``(p, 0)``."""
        return self._carried(self._closed, self.n + 1, q, p, w, row, act, h, residual, phi_tol)

    def _carried(self, step, size: int, q, p, w, row: int, act, h: float, residual: float, phi_tol: float):
        """One step of a closed loop's C kernel ``step`` (``<model>_eval_held_circle_step`` or
        ``<model>_eval_held_closed_step``) with its carry ``w`` of ``size`` values (NaN: formed by it)."""
        n, r = self.n, self.r
        wio = np.full(size, np.nan) if w is None else np.array(w, dtype=float)
        lam, lam1, q1, p1, v, e = np.empty(r), np.empty(r), np.empty(n), np.empty(n), np.empty(n), np.empty(1)
        acts = _vec(np.asarray(act, dtype=float), r)
        ok = step(
            _ptr(self.par), float(h), float(residual), float(phi_tol), int(row), _ptr(_vec(q, n)),
            _ptr(_vec(p, n)), _ptr(acts), _ptr(wio), _ptr(lam), _ptr(lam1), _ptr(q1), _ptr(p1), _ptr(v),
            _ptr(e),
        )  # fmt: skip
        return (Held(q1, p1, v, lam, lam1, float(e[0])), wio) if ok else None

    def rows(self, q, u):
        """``(psi, grad psi, u . Hess psi . u)`` of every row (vcigen.rows)."""
        n, r = self.n, self.r
        psi, grad, curv = np.empty(r), np.empty(r * n), np.empty(r)
        self._rows(_ptr(_vec(q, n)), _ptr(_vec(u, n)), _ptr(self.par), _ptr(psi), _ptr(grad), _ptr(curv))
        return psi, grad.reshape(r, n), curv

    def dynamics(self, q, u):
        """``(rhs, curv)``: ``M qddot = rhs`` without constraints, and each contact's curvature."""
        n, m = self.n, self.m
        rhs, curv = np.empty(n), np.empty(max(m, 1))
        self._dynamics(_ptr(_vec(q, n)), _ptr(_vec(u, n)), _ptr(self.par), _ptr(rhs), _ptr(curv))
        return rhs, curv[:m]

    def restitution(self) -> np.ndarray:
        """Coefficient of restitution of each contact at the bound parameters."""
        e = np.empty(max(self.m, 1))
        self._rest(_ptr(self.par), _ptr(e))
        return e[: self.m]

    def jump_quadratic(self, qc, nrm, p_in, e_in, tau):
        """``((a, b, c), w0, dw)`` of the jump (48) as a quadratic in ``mu``, or ``None``."""
        if self._quad is None:
            return None
        n = self.n
        coef, w0, dw = np.empty(3), np.empty(n), np.empty(n)
        self._quad(
            _ptr(_vec(qc, n)),
            _ptr(_vec(nrm, n)),
            _ptr(_vec(p_in, n)),
            float(e_in),
            float(tau),
            _ptr(self.par),
            _ptr(coef),
            _ptr(w0),
            _ptr(dw),
        )
        return (float(coef[0]), float(coef[1]), float(coef[2])), w0, dw

    def solve(self, name: str, guess, *args):
        """The C Newton on residual routine ``name`` from ``guess``; ``(x, |res|_inf)``."""
        rid, nx = self._ids[name]
        x = _vec(guess, nx).copy()
        flat = np.concatenate([np.atleast_1d(np.asarray(a, dtype=float)) for a in args])
        res = np.empty(1)
        self._solve(rid, _ptr(x), _ptr(flat), _ptr(self.par), _ptr(res))
        return x, float(res[0])


def _tol_struct(tol: Tolerances) -> _Tol:
    return _Tol(
        tol.residual,
        tol.phi,
        tol.admissible,
        tol.max_impacts_per_step,
        tol.bracket_samples,
        tol.dip,
        tol.simultaneous,
        int(tol.grazing == "reflect"),
        int(tol.grazing == "contact"),
        tol.rest,
    )


class CSimulator(Simulator):
    """A :class:`~vcigen.simulator.Simulator` whose time loop is ``<model>_run_many`` in C (``crun``)."""

    def __init__(
        self,
        system: DiscreteSystem,
        kernels: CKernels,
        tol: Tolerances | None = None,
        build: dict[str, Any] | None = None,
    ) -> None:
        """``build``: ``build_library``'s options (``cc``, ``cache``), for the sensitivity variant."""
        super().__init__(system, kernels, tol)
        self._tol: tuple[Tolerances, _Tol] | None = None
        self._pool: list[Block] = []  # grid buffers of simulate's longer runs, reused (crun.Block)
        self._build = dict(build or {})
        self._sens: CKernels | None = None  # the sensitivity variant, built on first use (csens)

    def _tol_struct(self) -> _Tol:
        """The C tolerances of ``self.tol``, made once (again if ``tol`` is replaced)."""
        if self._tol is None or self._tol[0] is not self.tol:
            self._tol = (self.tol, _tol_struct(self.tol))
        return self._tol[1]

    def _starts(self, q: np.ndarray, v: np.ndarray, per_run: list, t0: float) -> ManyStarts:
        """``Simulator._starts`` with the kernels called for all runs in one loop into preallocated rows
        and the checks made on the arrays (``p0`` the same bits); a run that fails or nears a bound is
        checked again by ``Simulator._check_start``, whose ``ValueError`` names it. Models with bilateral
        constraints take the per-run path."""
        kern = self.kernels
        if kern.r and self._constraint_names:
            return super()._starts(q, v, per_run, t0)
        resolved: dict[int, tuple[list[float], list[float], int]] = {}
        arrays, runs, bad_par = [], [], None
        for i, par_i in enumerate(per_run):  # the parameters of each run, up to the first bad ones
            if id(par_i) not in resolved:
                try:
                    par, mu_f = self._parameters(par_i, t0)
                except ValueError as exc:
                    bad_par = ValueError(f"run {i}: {exc}")
                    break
                arrays.append(_par_array(par))
                resolved[id(par_i)] = (par, mu_f, arrays[-1].ctypes.data)
            runs.append(resolved[id(par_i)])
        k, n, mm = len(runs), kern.n, max(kern.m, 1)
        q, v = np.ascontiguousarray(q[:k]), np.ascontiguousarray(v[:k])
        p0, mass, phi, grad = np.empty((k, n)), np.empty((k, n, n)), np.empty((k, mm)), np.empty((k, mm * n))
        aq, av, ap, am, aphi, agrad = (a.ctypes.data for a in (q, v, p0, mass, phi, grad))
        contacts, legendre = kern._contacts, kern._legendre
        for i, (_, _, at) in enumerate(runs):
            contacts(aq + 8 * n * i, at, aphi + 8 * mm * i, agrad + 8 * mm * n * i)
            legendre(aq + 8 * n * i, av + 8 * n * i, at, ap + 8 * n * i, am + 8 * n * n * i)
        ok = (phi[:, : kern.m] >= -self.tol.admissible).all(axis=1)
        ok &= conditions(mass) <= 0.5 * MAX_CONDITION
        for i in np.flatnonzero(~ok).tolist():  # the scalar check decides, and names the problem
            kern.bind(runs[i][0])
            try:
                self._check_start(kern, q[i], v[i])
            except ValueError as exc:
                raise ValueError(f"run {i}: {exc}") from None
        if bad_par is not None:
            raise bad_par
        return ManyStarts(q, v, p0, per_run[:k], [r[0] for r in runs], [r[1] for r in runs])

    def _rooms(self, kern: CKernels) -> tuple[int, int]:
        """The impact records and lift-offs one grid step may write (``<model>_run`` keeps that room)."""
        per = self.tol.max_impacts_per_step
        return per * (max(kern.m, 1) + max(kern.r, 1)), per * max(kern.r, 1)

    def _run(self, kern: CKernels, q0, v0, p0, h, t_end, n_impacts, t0, progress) -> Result:
        steps = _n_steps(h, t0, t_end, MAX_STEPS)
        run = CRun(kern, kern.par, q0, v0, p0, steps, n_impacts, self._rooms(kern), pool=self._pool)
        return self._drive(kern, run, h, t_end, n_impacts, t0, progress)

    def _drive(self, kern: CKernels, run: CRun, h, t_end, n_impacts, t0, progress) -> Result:
        """Calls of ``<model>_run_many`` until ``run`` is done (in chunks sized for the progress bar)."""
        steps = run.steps
        tol = self._tol_struct()
        wall = time.perf_counter()
        rate = None
        while not run.finished:
            chunk = chunk_steps(rate, steps - run.done) if progress.enabled else steps
            start, before = time.perf_counter(), run.done
            run_jobs(kern, tol, h, t0, [run], chunk)
            if run.done > before:
                rate = (time.perf_counter() - start) / (run.done - before)
            progress.update(run.fraction())
        wall = time.perf_counter() - wall
        if run.rc:
            raise run.error(t0, h, wall)
        _warn_short(run, t_end, n_impacts, stacklevel=5)
        return run.result(t0, h, wall)

    def sens_kernels(self) -> CKernels:
        """The kernels of the sensitivity variant (:mod:`vcigen.backends.csens`): the model with its ``d_*``
        routines (:func:`vcigen.tangents.tangent_routines`) rendered with the tangent in the loop, compiled
        (cached by source hash like the plain library) on the first call, kept for the next."""
        if self._sens is None:
            from .c import LIBRARY_TEMPLATES, build_library, render
            from .ccontext import render_context

            system = self.system
            if not any(is_tangent(name) for name in system.routines):
                system = replace(system, routines={**system.routines, **tangent_routines(system.routines)})
            ctx = render_context(system, None, self.tol, sensitivities=True)
            lib = build_library(render(ctx, LIBRARY_TEMPLATES), ctx["model"], **self._build)
            self._sens = CKernels(system, lib, ctx)
        return self._sens

    def _run_sensitive(self, kern, q0, v0, p0, h, t_end, n_impacts, t0, progress) -> Result:
        """:meth:`_run` on the sensitivity variant: the tangent carried inside the C loop (``SensRun``)."""
        sk = self.sens_kernels()
        sk.par = kern.par  # the bound parameters (and slots) of this call
        n = sk.n
        s0 = np.empty((2 * n, sk.K))
        sk.sens_start(_ptr(sk.par), _ptr(_vec(q0, n)), _ptr(_vec(v0, n)), _ptr(s0))
        steps = _n_steps(h, t0, t_end, MAX_STEPS)
        run = SensRun(sk, sk.par, q0, v0, p0, steps, n_impacts, self._rooms(sk), s0, column_names(self.model))
        return self._drive(sk, run, h, t_end, n_impacts, t0, progress)

    def _run_many(self, starts, h, t_end, n_impacts, t0, progress, threads) -> list[Result | SolverError]:
        """All runs through ``<model>_run_many``: in batches (of runs) sized for the progress bar, each
        batch in one call per thread until its runs are done (a run whose buffer filled resumes)."""
        kern, tol, rooms = self.kernels, self._tol_struct(), self._rooms(self.kernels)
        steps = _n_steps(h, t0, t_end, MAX_STEPS)
        pars: dict[int, tuple[np.ndarray, int]] = {}  # one C parameter vector per distinct params
        n = kern.n

        def make(first: int, last: int) -> list[CRun]:
            for par in starts.par[first:last]:
                if id(par) not in pars:
                    arr = _par_array(par)
                    pars[id(par)] = (arr, arr.ctypes.data)
            state = np.empty((last - first, 3 * n))
            state[:, :n] = starts.q[first:last]
            state[:, n : 2 * n] = starts.p0[first:last]
            state[:, 2 * n :] = starts.v[first:last]
            return batch_runs(kern, state, [pars[id(p)] for p in starts.par[first:last]], steps, n_impacts,
                              rooms, FIRST_CAP_MANY)  # fmt: skip

        gc_was_on = gc.isenabled()
        gc.disable()  # thousands of new objects and no cycle among them: no collection passes meanwhile
        try:
            return self._batches(starts, make, tol, h, t_end, n_impacts, t0, progress, threads)
        finally:
            if gc_was_on:
                gc.enable()

    def _batches(
        self, starts, make, tol, h, t_end, n_impacts, t0, progress, threads
    ) -> list[Result | SolverError]:
        kern = self.kernels
        out: list[Result | SolverError] = []
        size = len(starts) if not progress else 8
        reflected = 0
        with Progress(len(starts), f"simulate_many {self.model.name}", enabled=progress) as bar:
            first = 0
            while first < len(starts):
                start = time.perf_counter()
                batch = make(first, min(first + size, len(starts)))  # buffers made batch by batch
                _run_batch(kern, tol, h, t0, batch, threads)
                took = time.perf_counter() - start
                last = first + len(batch)
                if any(run.rc for run in batch):
                    results = [run.error(t0, h, took / len(batch)) if run.rc else None for run in batch]
                    good = [run for run in batch if not run.rc]
                else:
                    results, good = [None] * len(batch), batch
                made = iter(batch_results(good, t0, h, took / len(batch)) if good else ())
                done = [next(made) if r is None else r for r in results]
                self._finish_many(
                    [r.result if isinstance(r, SolverError) else r for r in done],
                    starts.par[first:last],
                    starts.mu_f[first:last],
                )
                for run in batch:
                    if not run.rc:
                        _warn_short(run, t_end, n_impacts, stacklevel=5)
                        reflected += run.reflected
                out += done
                first += len(batch)
                bar.update(first)
                if progress:  # about a quarter second per batch, growing at most 8-fold
                    size = max(1, min(8 * size, int(0.25 * len(batch) / max(took, 1e-9))))
        warn_reflected(reflected, stacklevel=3)
        return out


def _run_batch(kern: CKernels, tol: _Tol, h: float, t0: float, runs: list[CRun], threads: int) -> None:
    """``runs`` to their end: calls of ``<model>_run_many`` (one per thread, ctypes releases the GIL)
    until none is left unfinished (a run stops early only when one of its buffers must grow)."""
    pending = [r for r in runs if not r.finished]
    while pending:
        if threads > 1 and len(pending) > 1:
            step = -(-len(pending) // threads)  # contiguous parts: no two threads write one cache line
            parts = [pending[i : i + step] for i in range(0, len(pending), step)]
            with ThreadPoolExecutor(threads) as pool:
                list(pool.map(lambda part: run_jobs(kern, tol, h, t0, part, MAX_STEPS), parts))
        else:
            run_jobs(kern, tol, h, t0, pending, MAX_STEPS)
        pending = [r for r in pending if not r.finished]


def _warn_short(run: CRun, t_end, n_impacts, stacklevel: int) -> None:
    """An ``n_impacts`` run without ``t_end`` that reached ``max_steps`` first says so."""
    if n_impacts is not None and t_end is None and run.n_rec < n_impacts and run.done >= run.steps:
        warnings.warn(
            f"stopped after max_steps = {MAX_STEPS} with {run.n_rec} of {n_impacts} impacts",
            RuntimeWarning,
            stacklevel=stacklevel,
        )
