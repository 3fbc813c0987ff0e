"""The compiled model through ctypes: the stepper's kernels, and a simulator whose loop runs in C.

:class:`CKernels` gives the kernels interface of :mod:`vcigen.stepper` (so the Python
stepper can also run on the C kernels, for debugging); :class:`CSimulator` calls
``<model>_run``, which takes whole chunks of grid steps (46)-(79) in C and resumes
from ``(q, p)`` (plus the Newton guess ``v``), so runs of unknown length
(``n_impacts``) grow their buffers chunk by chunk.
"""

from __future__ import annotations

import ctypes
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..derive import DiscreteSystem, set_rows
from ..errors import PHASES, SolverError
from ..held import Held
from ..result import KINDS, Impact, Result
from ..simulator import Simulator
from ..stepper import Tolerances, _n_steps, _result
from ..sustained import SustainLog, held_contacts, rattle_segment
from .slots import ParameterSlots

_D = ctypes.POINTER(ctypes.c_double)
IMPACT_CAP = 4096
MAX_STEPS = 50_000_000


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
        ("reason", ctypes.c_char * 256),
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
            ("events", ctypes.c_int),
            ("slip", ctypes.c_double * max(nf, 1)),
            ("ref", ctypes.c_double * max(nf, 1)),
            ("branch", ctypes.c_double * max(nb, 1)),
            ("held_rows", ctypes.c_ulong * max(nf, 1)),
        ]

    return _Sustain


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
        self._segment = getattr(self.lib, f"{pre}_eval_segment")
        self._segment.argtypes = [_D, _D, ctypes.c_double, _D, _D, _D, _D]
        self._contacts = getattr(self.lib, f"{pre}_eval_contacts")
        self._smooth = getattr(self.lib, f"{pre}_eval_smooth_step")
        self._smooth.argtypes = [_D, _D, ctypes.c_double, _D, _D, _D, _D, _D, _D, _D, _D, _D, _D]
        self._rest = getattr(self.lib, f"{pre}_eval_restitution")
        self.explicit_path = bool(ctx["structure"]["explicit_path"])
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
        self.held = bool(ctx.get("held"))  # the held grid step (vcigen.held)
        if self.held:
            self._held = getattr(self.lib, f"{pre}_eval_held_step")
            self._held.argtypes = [_D, ctypes.c_double, ctypes.c_double, ctypes.c_double] + [_D] * 9
            self._held.restype = ctypes.c_int
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
        self.run.restype = ctypes.c_int
        self.start = getattr(self.lib, f"{pre}_start")
        self.start.argtypes = [_D, ctypes.POINTER(_Tol), ctypes.c_double, _D, _D, ctypes.c_void_p]
        self.nc = len(system.model.constraint)
        self.Sustain = sustain_struct(self.r, self.m, self.nc, len(self.frictional), sum(self.branch_count))

    def bind(self, par) -> CKernels:
        """Fix the parameter values for the next simulation."""
        self.par = _vec(par, len(self.system.params)) if len(par) else np.zeros(1)
        return self

    def legendre(self, q, v):
        n = self.n
        mom, mass = np.empty(n), np.empty(n * n)
        self._legendre(_ptr(_vec(q, n)), _ptr(_vec(v, n)), _ptr(self.par), _ptr(mom), _ptr(mass))
        return mom, mass.reshape(n, n)

    def segment(self, q0, v, tau):
        n = self.n
        pm, pp, e = np.empty(n), np.empty(n), np.empty(1)
        self._segment(
            _ptr(_vec(q0, n)), _ptr(_vec(v, n)), float(tau), _ptr(self.par), _ptr(pm), _ptr(pp), _ptr(e)
        )
        return pm, pp, float(e[0])

    def contacts(self, q):
        n, m = self.n, self.m
        phi, grad = np.empty(max(m, 1)), np.empty(max(m, 1) * n)
        self._contacts(_ptr(_vec(q, n)), _ptr(self.par), _ptr(phi), _ptr(grad))
        return phi[:m], grad[: m * n].reshape(m, n)

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
        """``vcigen.held.held_step``, by the C loop's own ``<model>_held_step``."""
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
            _ptr(acts), _ptr(lam), _ptr(lam1), _ptr(q1), _ptr(p1), _ptr(v), _ptr(e),
        )  # fmt: skip
        return Held(q1, p1, v, lam, lam1, float(e[0])) if ok else None

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


def _grow(a: np.ndarray, rows: int) -> np.ndarray:
    out = np.empty((rows, *a.shape[1:]))
    out[: a.shape[0]] = a
    return out


class CSimulator(Simulator):
    """A :class:`~vcigen.simulator.Simulator` whose time loop is ``<model>_run`` in C."""

    def _run(self, kern: CKernels, q0, v0, h, t_end, n_impacts, t0, progress) -> Result:
        n = kern.n
        steps = _n_steps(h, t0, t_end, MAX_STEPS)
        cap = steps if t_end is not None else 1024
        Q, P, E = np.empty((cap + 1, n)), np.empty((cap + 1, n)), np.empty(max(cap, 1))
        q, v = _vec(q0, n).copy(), _vec(v0, n).copy()
        p = kern.legendre(q, v)[0].copy()
        Q[0], P[0] = q, p
        m = kern.m
        impact_cap = max(IMPACT_CAP, 2 * self.tol.max_impacts_per_step * (max(m, 1) + max(kern.r, 1)))
        rec = np.empty((impact_cap, 8 + n))
        sus = kern.Sustain()
        tol = _tol_struct(self.tol)
        kern.start(_ptr(kern.par), ctypes.byref(tol), h, _ptr(q), _ptr(v), ctypes.byref(sus))
        lift_buf = np.empty((max(IMPACT_CAP, 4 * self.tol.max_impacts_per_step * max(kern.r, 1)), 2))
        sus.liftoffs, sus.liftoff_cap = _ptr(lift_buf), lift_buf.shape[0]
        log = SustainLog(kern, cap)  # the C loop writes its rows (active, forces) in place
        log.active[0] = held_contacts(kern, list(sus.act)[: kern.r])
        liftoffs: list[tuple[float, str]] = []
        err, sdone, idone = _Err(), ctypes.c_long(0), ctypes.c_long(0)
        impacts: list[Impact] = []
        done = reflected = 0
        wall = time.perf_counter()
        while done < steps and (n_impacts is None or len(impacts) < n_impacts):
            if done >= cap:
                cap *= 2
                Q, P, E = _grow(Q, cap + 1), _grow(P, cap + 1), _grow(E, cap)
                log.grow(cap)
            chunk = min(cap - done, steps - done, 100_000 if progress else steps)
            sus.n_liftoffs = 0
            left = -1 if n_impacts is None else n_impacts - len(impacts)
            rc = kern.run(
                _ptr(kern.par),
                ctypes.byref(tol),
                h,
                t0,
                done,
                chunk,
                left,
                _ptr(q),
                _ptr(p),
                _ptr(v),
                _ptr(Q[done + 1 :]),
                _ptr(P[done + 1 :]),
                _ptr(E[done:]),
                _ptr(rec),
                impact_cap,
                ctypes.byref(sdone),
                ctypes.byref(idone),
                ctypes.byref(err),
                ctypes.byref(sus),
                log.active[done + 1 :].ctypes.data_as(ctypes.c_void_p),
                _ptr(log.force[done:]),
                _ptr(log.cforce[done:]),
            )
            impacts += [_impact(r, kern.contact_names) for r in rec[: idone.value]]
            liftoffs += [(float(t), kern.contact_names[int(j)]) for t, j in lift_buf[: sus.n_liftoffs]]
            done += sdone.value
            reflected += err.reflected
            if rc != 0:
                error = SolverError(err.step, err.time, PHASES[err.phase], err.residual, err.reason.decode())
                kept = [im for im in impacts if im.step < done]  # the run up to the last completed step
                error.result = _result(t0, h, done, Q, P, E, kept, n, time.perf_counter() - wall)
                log.attach(error.result, done, [lo for lo in liftoffs if lo[0] < t0 + done * h])
                raise error
            if progress:
                print(f"  t = {t0 + done * h:.4g}, {done} steps, {len(impacts)} impacts", flush=True)
            if sdone.value == 0:
                break
        if n_impacts is not None and t_end is None and len(impacts) < n_impacts and done >= steps:
            warnings.warn(
                f"stopped after max_steps = {MAX_STEPS} with {len(impacts)} of {n_impacts} impacts",
                RuntimeWarning,
                stacklevel=3,
            )
        res = _result(t0, h, done, Q, P, E, impacts, n, time.perf_counter() - wall)
        res.stats["grazing_reflected"] = reflected
        log.attach(res, done, liftoffs)
        res.stats.update({f"impacts_{kind}": int(sus.kinds[i]) for i, kind in enumerate(KINDS)})
        res.stats["liftoffs"] = len(liftoffs)
        res.stats["jump_fallbacks"] = int(sus.fallbacks)
        return res


def _impact(r: np.ndarray, names: tuple[str, ...]) -> Impact:
    """One C impact record ``t, contact, step, alpha, impulse, E_before, E_after, q..., kind``."""
    return Impact(
        t=float(r[0]),
        contact=names[int(r[1])],
        q=r[7:-1].copy(),
        alpha=float(r[3]),
        impulse=float(r[4]),
        step=int(r[2]),
        energy_before=float(r[5]),
        energy_after=float(r[6]),
        kind=KINDS[int(r[-1])],
    )
