"""High-accuracy references: closed-form particle, event-driven ODE, exact-flight star."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mpmath
import numpy as np
from scipy.integrate import DOP853, RK45, OdeSolver
from scipy.optimize import brentq, minimize_scalar

from bench.scenes import STAR_I, STAR_L, STAR_M, Contact, Scene, star

Array = np.ndarray
SOLVERS: dict[str, type[OdeSolver]] = {"DOP853": DOP853, "RK45": RK45}


@dataclass(frozen=True)
class Impact:
    """One impact: time, contact name, configuration at contact."""

    t: float
    contact: str
    q: Array


@dataclass
class Trajectory:
    """States on a time grid plus the impacts that happened up to its end."""

    t: Array
    q: Array
    v: Array
    energy: Array
    impacts: list[Impact]

    @property
    def impact_times(self) -> Array:
        return np.array([imp.t for imp in self.impacts])


def _energies(scene: Scene, q: Array, v: Array) -> Array:
    return np.array([scene.energy(qi, vi) for qi, vi in zip(q, v, strict=True)])


# ------------------------------------------------------------------ (a) particle


def particle_closed_form(t_eval: Array, q0=(0.0, 1.0), v0=(-2.0, 0.0), g: float = 9.81) -> Trajectory:
    """Exact elastic bouncing of a unit mass on the floor ``y = 0`` under linear gravity.

    At an impact time on the grid the post-impact velocity is returned.
    """
    t = np.asarray(t_eval, float)
    (x0, y0), (vx, vy) = q0, v0
    if y0 < 0 or (y0 == 0 and vy <= 0):
        raise ValueError("start must be above the floor or leaving it")
    u = math.sqrt(vy * vy + 2 * g * y0)  # speed at every impact
    t1 = (vy + u) / g
    period = 2 * u / g
    k = np.floor((t - t1) / period)
    s = t - t1 - k * period
    first = t < t1
    s = np.where(first, t, s)
    y = np.where(first, y0 + vy * s - g * s**2 / 2, u * s - g * s**2 / 2)
    w = np.where(first, vy - g * s, u - g * s)
    q = np.column_stack([x0 + vx * t, y])
    v = np.column_stack([np.full_like(t, vx), w])
    n_imp = int(max(0, k.max() + 1)) if t.size else 0
    impacts = [Impact(ti, "floor", np.array([x0 + vx * ti, 0.0])) for ti in (t1 + period * np.arange(n_imp))]
    energy = 0.5 * (q[:, 0] * 0 + vx**2 + w**2) + g * y
    return Trajectory(t, q, v, energy, impacts)


# ------------------------------------------------------------------ (b) event-driven


def _first_crossing(phi, ts: Array, ph: Array) -> tuple[float, float] | None:
    """Bracket ``[a, b]`` of the first crossing of ``phi`` below 0 among samples.

    ``ph[0] >= 0`` is assumed. A sampled local minimum that might hide a dip
    (value below the local second difference) is checked by bounded minimisation.
    """
    neg = np.flatnonzero(ph < 0)
    stop = neg[0] if neg.size else len(ph)
    for i in range(1, min(stop, len(ph) - 1)):
        b, a, c = ph[i], ph[i - 1], ph[i + 1]
        if b <= a and b <= c and b < a + c - 2 * b:
            r = minimize_scalar(
                phi, bounds=(ts[i - 1], ts[i + 1]), method="bounded", options={"xatol": 1e-14}
            )
            if r.fun < 0:
                return ts[i - 1], float(r.x)
    if neg.size:
        return ts[stop - 1], ts[stop]
    return None


def event_driven(
    scene: Scene,
    t_eval: Array,
    *,
    n_impacts: int | None = None,
    method: str = "DOP853",
    rtol: float = 1e-13,
    atol: float = 1e-13,
    max_step: float | None = None,
    n_samples: int = 8,
    q0: Array | None = None,
    v0: Array | None = None,
) -> Trajectory:
    """Smooth ODE from impact to impact, every contact checked inside every step.

    After each solver step ``phi`` is sampled at ``n_samples`` interior points of
    the dense output (and one point of the previous step), the first crossing is
    refined with ``brentq`` (time error ~1e-15 relative), and the elastic law is
    applied. Stops at ``t_eval[-1]`` or after ``n_impacts``; the grid is cut there.
    """
    t_eval = np.asarray(t_eval, float)
    n = scene.n
    q = np.array(scene.q0 if q0 is None else q0, float)
    v = np.array(scene.v0 if v0 is None else v0, float)
    max_step = 2 * scene.h if max_step is None else max_step
    solver_cls = SOLVERS[method]

    def rhs(_t: float, y: Array) -> Array:
        return np.concatenate([y[n:], scene.accel(y[:n], y[n:])])

    out_q = np.full((t_eval.size, n), np.nan)
    out_v = np.full((t_eval.size, n), np.nan)
    k_out = 0
    impacts: list[Impact] = []
    t = float(t_eval[0])
    t_stop = float(t_eval[-1])
    done = False
    while not done:
        solver = solver_cls(rhs, t, np.concatenate([q, v]), t_stop, rtol=rtol, atol=atol, max_step=max_step)
        prev = None  # (t, y, sol) of the last sample of the previous step
        hit = None
        while solver.status == "running" and hit is None:
            t_old = solver.t
            solver.step()
            if solver.status == "failed":
                raise RuntimeError(f"{method} failed at t={t_old}: {solver.message}")
            sol = solver.dense_output()
            ts = np.linspace(t_old, solver.t, n_samples + 2)
            if prev is not None:
                ts = np.concatenate([[prev[0]], ts])

            def state(tt: float, sol=sol, prev=prev, t_old=t_old) -> Array:
                return prev[1](tt) if (prev is not None and tt < t_old) else sol(tt)

            ys = sol(ts[-(n_samples + 2) :])
            if prev is not None:
                ys = np.column_stack([prev[1](prev[0]), ys])
            for c in scene.contacts:
                ph = np.asarray(c.phi(ys[:n]), float)
                ph[: 1 + (prev is not None)] = np.maximum(ph[: 1 + (prev is not None)], 0.0)

                def f(tt: float, c: Contact = c, state=state) -> float:
                    return float(c.phi(state(tt)[:n]))

                br = _first_crossing(f, ts, ph)
                if br is None:
                    continue
                normal = None
                if f(br[0]) < 0:  # leaving one kink branch into another: re-impact at once
                    tc, normal = br[0], c.grad_phi(state(br[1])[:n])
                else:
                    tc = brentq(f, br[0], br[1], xtol=1e-16, rtol=4 * np.finfo(float).eps)
                if hit is None or tc < hit[0]:
                    hit = (tc, c, state, normal)
            t_emit = hit[0] if hit else solver.t
            while k_out < t_eval.size and (
                t_eval[k_out] < t_emit or (hit is None and t_eval[k_out] <= t_emit)
            ):
                y = state(t_eval[k_out])
                out_q[k_out], out_v[k_out] = y[:n], y[n:]
                k_out += 1
            prev = (ts[-2], sol)
        if hit is None:
            break
        t, c, state, normal = hit
        y = state(t)
        q, v = y[:n], scene.reflect(y[:n], y[n:], c, normal)
        impacts.append(Impact(t, c.name, q.copy()))
        done = n_impacts is not None and len(impacts) >= n_impacts
    tt = t_eval[:k_out]
    return Trajectory(
        tt, out_q[:k_out], out_v[:k_out], _energies(scene, out_q[:k_out], out_v[:k_out]), impacts
    )


# ------------------------------------------------------------------ (c) star, exact flight


class _Flight:
    """Exact free flight of the linear-gravity star from a state, in float or mpmath."""

    def __init__(self, q, v, g: float, hp: bool):
        self.q, self.v, self.g, self.hp = q, v, g, hp
        self.sin = mpmath.sin if hp else math.sin
        self.cos = mpmath.cos if hp else math.cos

    def at(self, s):
        (x, y, th), (vx, vy, w), g = self.q, self.v, self.g
        return (x + vx * s, y + vy * s - g * s * s / 2, th + w * s), (vx, vy - g * s, w)

    def phi(self, s):
        (_, y, th), _ = self.at(s)
        return y - STAR_L / 2 * (abs(self.sin(th)) + abs(self.cos(th)))


def _star_reflect(q, v, hp: bool):
    th = q[2]
    s, c = (mpmath.sin(th), mpmath.cos(th)) if hp else (math.sin(th), math.cos(th))
    sg = lambda a: (a > 0) - (a < 0)
    n = (0, 1, -STAR_L / 2 * (sg(s) * c - sg(c) * s))
    minv_n = (0, n[1] / STAR_M, n[2] / STAR_I)
    lam = 2 * (n[1] * v[1] + n[2] * v[2]) / (n[1] * minv_n[1] + n[2] * minv_n[2])
    return tuple(vi - lam * mi for vi, mi in zip(v, minv_n, strict=True)), n


def _next_root(fl: _Flight, fresh: bool, tol: float = 1e-15) -> float:
    """First ``s > 0`` with ``phi = 0`` along the exact flight (branch and bound)."""
    f = _Flight(tuple(map(float, fl.q)), tuple(map(float, fl.v)), float(fl.g), False)
    w = f.v[2]
    big_k = f.g + STAR_L / math.sqrt(2) * w * w  # |phi''| bound between kinks
    y_rel = f.q[1] - STAR_L / 2
    s_up = (f.v[1] + math.sqrt(f.v[1] ** 2 + 2 * f.g * max(y_rel, 0.0))) / f.g + 1e-9
    kinks = []
    if w != 0:
        j0 = math.floor(f.q[2] / (math.pi / 2))
        j = j0 + (1 if w > 0 else 0)
        while True:
            sk = (j * math.pi / 2 - f.q[2]) / w
            if sk > s_up:
                break
            if sk > 0:
                kinks.append(sk)
            j += 1 if w > 0 else -1
    s0 = 0.0
    if fresh:  # phi(0) = 0, leaving: phi >= d0 s - K s^2/2 up to the first kink
        _, (_, vy, _) = f.at(0.0)
        sn, cs = math.sin(f.q[2]), math.cos(f.q[2])
        sg_s = np.sign(sn) if sn != 0 else np.sign(cs * w)  # branch just after s = 0
        sg_c = np.sign(cs) if cs != 0 else -np.sign(sn * w)
        d0 = vy - STAR_L / 2 * w * (sg_s * cs - sg_c * sn)
        if d0 <= 0:
            raise RuntimeError("star leaves the impact with non-positive normal velocity")
        s0 = min(d0 / big_k, kinks[0] if kinks else np.inf)
    knots = sorted({s0, s_up, *[k for k in kinks if k > s0], *np.arange(s0, s_up, 0.01)[1:]})
    stack = list(zip(knots[-2::-1], knots[:0:-1], strict=True))  # earliest on top
    cache: dict[float, float] = {}

    def ph(s: float) -> float:
        if s not in cache:
            cache[s] = f.phi(s)
        return cache[s]

    while stack:
        a, b = stack.pop()
        fa, fb = ph(a), ph(b)
        if fb < 0:
            return brentq(f.phi, a, b, xtol=tol, rtol=4 * np.finfo(float).eps)
        if min(fa, fb) - big_k * (b - a) ** 2 / 8 > 0 or b - a < tol:
            continue
        m = 0.5 * (a + b)
        stack += [(m, b), (a, m)]
    raise RuntimeError("no impact found along the flight")


def star_exact(
    t_eval: Array, *, n_impacts: int | None = None, dps: int | None = None, g: float = 9.81
) -> Trajectory:
    """Linear-gravity star: exact parabola + rotation, impacts by branch and bound.

    With ``dps`` the impact times are polished with mpmath at that many digits and
    the state is carried in mpmath (scan and bracketing stay in float).
    """
    sc = star()
    hp = dps is not None
    ctx = mpmath.workdps(dps) if hp else _Null()
    conv = mpmath.mpf if hp else float
    t_eval = np.asarray(t_eval, float)
    out_q = np.full((t_eval.size, 3), np.nan)
    out_v = np.full((t_eval.size, 3), np.nan)
    impacts: list[Impact] = []
    with ctx:
        t0 = conv(float(t_eval[0]))
        fl = _Flight(tuple(map(conv, sc.q0)), tuple(map(conv, sc.v0)), conv(g), hp)
        k, fresh = 0, False
        while True:
            s = _next_root(fl, fresh)
            if hp:
                s = mpmath.findroot(fl.phi, (conv(s) * (1 - 1e-12), conv(s) * (1 + 1e-12)), solver="anderson")
            t_imp = t0 + s
            last = n_impacts is not None and len(impacts) + 1 >= n_impacts
            while k < t_eval.size and t_eval[k] < float(t_imp):
                qq, vv = fl.at(conv(float(t_eval[k])) - t0)
                out_q[k], out_v[k] = [float(a) for a in qq], [float(a) for a in vv]
                k += 1
            if k == t_eval.size:
                break
            q, v = fl.at(s)
            v, _ = _star_reflect(q, v, hp)
            impacts.append(Impact(float(t_imp), "floor", np.array([float(a) for a in q])))
            if last:
                break
            fl, t0, fresh = _Flight(q, v, conv(g), hp), t_imp, True
    return Trajectory(t_eval[:k], out_q[:k], out_v[:k], _energies(sc, out_q[:k], out_v[:k]), impacts)


class _Null:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None
