"""The algorithm of MATH.md in position-momentum form, written once.

The state is ``(q_k, p_k)``. A grid step is a chain of *segments*
``(q_s, v_s, tau_s)``: the first starts at the grid point with momentum
``p_k`` (46)/(47); every later one starts at an impact point, where the
momentum jumps along the contact normal and the energy is kept (48), (78).
The last segment ends at the grid time; the others end on a contact.

The stepper only calls a small kernels interface (``smooth_step``, ``solve``,
``segment``, ``contacts``, ``legendre``), which each backend provides.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from .errors import SolverError
from .result import Impact, Result


class Kernels(Protocol):
    n: int
    m: int
    contact_names: tuple[str, ...]

    def smooth_step(self, q0, p0, tau, guess): ...
    def solve(self, name: str, guess, *args): ...
    def segment(self, q0, v, tau): ...
    def contacts(self, q): ...
    def legendre(self, q, v): ...


@dataclass(frozen=True)
class Tolerances:
    """Acceptance thresholds shared by both backends."""

    residual: float = 1e-9  # |res|_inf accepted, relative to 1 + the data's scale
    phi: float = 1e-12  # phi_end < -phi is a crossing; |phi| <= phi is "on" the contact
    admissible: float = 1e-9  # phi(q_k) >= -admissible at every grid point
    max_impacts_per_step: int = 64
    bracket_samples: int = 8


@dataclass
class _Seg:
    """The segment under construction: its start and incoming data."""

    q: np.ndarray  # start point
    t: float  # start time
    tau: float  # remaining duration of the grid step
    p_in: np.ndarray  # grid momentum (first) or incoming momentum p~- (after an impact)
    e_in: float  # energy kept across the impact (after an impact)
    nrm: np.ndarray | None  # contact normal at the start (after an impact)
    contact: int  # contact hit at the start, -1 for the first segment
    x: np.ndarray  # the segment's unknowns: v, or (w, mu) after an impact


class Stepper:
    """Runs the method of MATH.md on a set of kernels."""

    def __init__(self, kernels: Kernels, tol: Tolerances | None = None) -> None:
        self.k = kernels
        self.tol = tol or Tolerances()

    # -- public -----------------------------------------------------------------
    def simulate(
        self,
        q0,
        v0,
        h: float,
        t_end: float | None = None,
        n_impacts: int | None = None,
        t0: float = 0.0,
        max_steps: int = 50_000_000,
        progress: bool = False,
    ) -> Result:
        k = self.k
        q = np.array(q0, dtype=float)
        p = k.legendre(q, np.asarray(v0, dtype=float))[0]
        steps = _n_steps(h, t0, t_end, max_steps)
        n = k.n
        cap = steps if t_end is not None else 1024
        Q, P, E = np.empty((cap + 1, n)), np.empty((cap + 1, n)), np.empty(cap)
        Q[0], P[0] = q, p
        impacts: list[Impact] = []
        v = np.asarray(v0, dtype=float).copy()
        wall = time.perf_counter()
        step = 0
        next_report = wall + 5.0
        while step < steps:
            if n_impacts is not None and len(impacts) >= n_impacts:
                break
            if step >= cap:
                cap *= 2
                Q, P, E = _grow(Q, cap + 1), _grow(P, cap + 1), _grow(E, cap)
            t = t0 + step * h
            q, p, e, v = self.step(step, t, h, q, p, v, impacts)
            step += 1
            Q[step], P[step], E[step - 1] = q, p, e
            if progress and time.perf_counter() > next_report:
                next_report += 5.0
                print(f"  t = {t:.4g}, {step} steps, {len(impacts)} impacts", flush=True)
        else:
            if n_impacts is not None and t_end is None and len(impacts) < n_impacts:
                warnings.warn(
                    f"stopped after max_steps = {max_steps} with {len(impacts)} of {n_impacts} impacts",
                    RuntimeWarning,
                    stacklevel=2,
                )
        wall = time.perf_counter() - wall
        t_grid = t0 + h * np.arange(step + 1)
        stats = {"wall_time": wall, "steps": step, "seconds_per_step": wall / max(step, 1)}
        return Result(
            t_grid,
            Q[: step + 1].copy(),
            P[: step + 1].copy(),
            E[:step].copy(),
            impacts,
            [str(s) for s in range(n)],
            h,
            stats,
        )

    def step(
        self,
        step: int,
        t: float,
        h: float,
        q: np.ndarray,
        p: np.ndarray,
        guess: np.ndarray,
        impacts: list[Impact],
    ):
        """One grid step from ``(q_k, p_k)``; returns ``(q_k+1, p_k+1, E_d, v)``."""
        k = self.k
        v, res, p1, e, phi1 = k.smooth_step(q, p, h, guess)
        self._check(res, p, step, t, "smooth")
        if phi1.size == 0 or phi1.min() >= -self.tol.phi:
            return q + h * v, p1, e, v
        seg = _Seg(q=q, t=t, tau=h, p_in=p, e_in=math.nan, nrm=None, contact=-1, x=v)
        return self._impact_step(step, t, h, seg, phi1, impacts)

    # -- the impact step ---------------------------------------------------------
    def _impact_step(self, step, t_k, h, seg: _Seg, phi_end, impacts):
        """Chain of segments (47), (48), (78), (79) until one ends inside C at ``t_k + h``."""
        k, tol = self.k, self.tol
        n = k.n
        pending: Impact | None = None
        for _ in range(tol.max_impacts_per_step):
            # Earliest crossing over all crossed contacts (47)/(78).
            best = None
            for j in np.flatnonzero(phi_end < -tol.phi):
                x, s = self._contact_root(step, t_k, seg, int(j), phi_end[j])
                if best is None or s < best[1]:
                    best = (int(j), s, x)
            j, s, x = best
            if pending is not None:  # the impulse at the previous impact, re-solved with beta (78)
                impacts.append(replace(pending, impulse=float(x[n])))
            tau_c = s * seg.tau
            v_c = x[:n]
            q_c = seg.q + tau_c * v_c
            _, p_minus_c, e_c = k.segment(seg.q, v_c, tau_c)
            e_in = e_c if seg.contact < 0 else seg.e_in
            t_c = seg.t + tau_c
            seg = _Seg(
                q=q_c,
                t=t_c,
                tau=seg.tau - tau_c,
                p_in=p_minus_c,
                e_in=e_in,
                nrm=k.contacts(q_c)[1][j],
                contact=j,
                x=x,
            )
            # Jump (48): tangential momentum kept, the normal one jumps by mu grad phi; energy kept.
            seg.x = self._jump(step, t_k, seg, v_c)
            w = seg.x[:n]
            _, p_end, e_after = k.segment(seg.q, w, seg.tau)
            pending = Impact(
                t=t_c,
                contact=k.contact_names[j],
                q=q_c.copy(),
                alpha=(t_c - t_k) / h,
                impulse=float(seg.x[n]),
                step=step,
                energy_before=e_in,
                energy_after=e_after,
            )
            q_end = seg.q + seg.tau * w
            phi_end = k.contacts(q_end)[0]
            if phi_end.min() >= -tol.phi:
                impacts.append(pending)
                return q_end, p_end, e_in, w
        raise SolverError(
            step,
            t_k,
            "jump",
            0.0,
            f"more than {tol.max_impacts_per_step} impacts in one step (chattering toward rest?); reduce h",
        )

    def _jump(self, step, t_k, seg: _Seg, v_in) -> np.ndarray:
        """Solve (48) for ``(w, mu)`` from the reflected velocity; reject ``mu <= 0``."""
        k = self.k
        w0, mu0 = reflected_guess(k, seg.q, v_in, seg.nrm)
        x, res = k.solve("jump", np.append(w0, mu0), seg.q, seg.nrm, seg.p_in, seg.e_in, seg.tau)
        self._check(res, seg.p_in, step, t_k, "jump", seg.e_in)
        if not x[k.n] > 0:
            raise SolverError(
                step,
                t_k,
                "jump",
                res,
                f"non-physical root mu = {x[k.n]:.3e} <= 0 at the "
                f"impact on '{k.contact_names[seg.contact]}' (grazing contact?)",
            )
        return x

    def _args(self, seg: _Seg) -> tuple:
        if seg.contact < 0:
            return (seg.q, seg.p_in, seg.tau)
        return (seg.q, seg.nrm, seg.p_in, seg.e_in, seg.tau)

    def _contact_root(self, step, t_k, seg: _Seg, j: int, phi_end_j: float):
        """Earliest root ``s`` in ``[0, 1]`` of ``phi_j`` along the segment map; ``(x, s)``.

        Newton on the whole system (47) or (78) from an interpolated guess; if it
        fails or leaves the bracket, a safeguarded scalar root on ``s`` instead.
        """
        k, tol = self.k, self.tol
        first = seg.contact < 0
        name = ("contact_time_" if first else "jump_contact_") + k.contact_names[j]
        phase = "contact time" if first else "jump to contact"
        lo, x_lo = 0.0, seg.x
        phi_lo = k.contacts(seg.q)[0][j]
        if not first and phi_lo <= tol.phi:  # leaving the contact just hit: step off the trivial root
            lo, x_lo, phi_lo = self._leave(seg, j)
        s0 = lo + (1 - lo) * float(np.clip(phi_lo / (phi_lo - phi_end_j), 0.0, 1.0))
        x, res = k.solve(name, np.append(seg.x, s0), *self._args(seg))
        s = float(x[-1])
        ok = res <= self._scale(seg.p_in, seg.e_in) and lo - 1e-12 <= s <= 1 + 1e-12
        if ok and not first:
            ok = x[k.n] > 0 and (s > lo or lo == 0)
        if not ok:
            x, s, res = self._bracketed_root(step, t_k, seg, j, name, phase, lo, x_lo, phi_lo)
        self._check(res, seg.p_in, step, t_k, phase, seg.e_in)
        return x, min(max(s, 0.0), 1.0)

    def _sub_solve(self, seg: _Seg, s: float, guess) -> tuple[np.ndarray, float]:
        """The segment map at fraction ``s``: its unknowns and ``phi`` at its end."""
        k = self.k
        if seg.contact < 0:
            x, _ = k.solve("smooth", guess, seg.q, seg.p_in, s * seg.tau)
        else:
            x, _ = k.solve("jump", guess, seg.q, seg.nrm, seg.p_in, seg.e_in, s * seg.tau)
        return x, k.contacts(seg.q + s * seg.tau * x[: k.n])[0]

    def _leave(self, seg: _Seg, j: int):
        """After an impact on ``j``: a small fraction where ``phi_j > 0`` again."""
        for s in (1e-3, 1e-6, 1e-9):
            x, phi = self._sub_solve(seg, s, seg.x)
            if phi[j] > self.tol.phi:
                return s, x, phi[j]
        return 0.0, seg.x, 0.0

    def _bracketed_root(self, step, t_k, seg, j, name, phase, a, xa, ga):
        """Illinois regula falsi on ``g(s) = phi_j(q(s))``, then a Newton polish."""
        k = self.k
        b = 1.0
        xb, phib = self._sub_solve(seg, b, seg.x)
        gb = phib[j]
        if not (ga >= -self.tol.phi and gb < 0):
            raise SolverError(
                step,
                t_k,
                phase,
                abs(gb),
                f"no sign change of phi_{k.contact_names[j]} on [{a:.3g}, 1] (phi = {ga:.3e}, {gb:.3e})",
            )
        side = 0
        for _ in range(200):
            c = (a * gb - b * ga) / (gb - ga)
            if not a < c < b:
                c = 0.5 * (a + b)
            xc, phic = self._sub_solve(seg, c, xb)
            gc = phic[j]
            if gc < 0:
                b, gb, xb = c, gc, xc
                ga = ga / 2 if side == -1 else ga
                side = -1
            else:
                a, ga = c, gc
                gb = gb / 2 if side == 1 else gb
                side = 1
            if b - a < 4e-16 or gc == 0:
                break
        x, res = k.solve(name, np.append(xb, b), *self._args(seg))
        if not (a - 1e-12 <= x[-1] <= b + 1e-12):
            raise SolverError(
                step,
                t_k,
                phase,
                res,
                f"Newton polish of the contact on "
                f"'{k.contact_names[j]}' left the bracket [{a:.17g}, {b:.17g}]",
            )
        return x, float(x[-1]), res

    # -- checks --------------------------------------------------------------------
    def _scale(self, p, e=math.nan) -> float:
        scale = 1.0 + float(np.max(np.abs(p))) + (abs(e) if math.isfinite(e) else 0.0)
        return self.tol.residual * scale

    def _check(self, res, p, step, t, phase, e=math.nan) -> None:
        if not (res <= self._scale(p, e)):
            raise SolverError(
                step,
                t,
                phase,
                float(res),
                "Newton did not converge; reduce h or check "
                "that the Lagrangian is regular along the trajectory",
            )


def reflected_guess(k: Kernels, q: np.ndarray, v_in: np.ndarray, nrm: np.ndarray):
    """``v+ = v- - 2 (n.v-)/(n M^-1 n) M^-1 n`` and ``mu = -2 (n.v-)/(n M^-1 n)`` (MATH.md)."""
    mass = k.legendre(q, v_in)[1]
    minv_n = np.linalg.solve(mass, nrm)
    mu = -2.0 * float(nrm @ v_in) / float(nrm @ minv_n)
    return v_in + mu * minv_n, mu


def _grow(a: np.ndarray, rows: int) -> np.ndarray:
    out = np.empty((rows, *a.shape[1:]))
    out[: a.shape[0]] = a
    return out


def _n_steps(h: float, t0: float, t_end: float | None, max_steps: int) -> int:
    if t_end is None:
        return max_steps
    steps = math.ceil((t_end - t0) / h - 1e-9)
    if steps > max_steps:
        raise ValueError(f"t_end = {t_end} at h = {h} needs {steps} steps, more than max_steps = {max_steps}")
    return max(steps, 0)
