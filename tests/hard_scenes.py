"""Hard-case scenes (MATH.md, *Hard cases*; issue 4) and their references.

Models: a particle in a corner / a box, a particle between two close walls (free, or on an
oscillator), the double pendulum striking a wall, a stiff dumbbell bouncing on a floor, a
particle grazing a ceiling, the paper's star (``examples/star.py``).

References: closed forms where they exist (reflections in a box by unfolding, an oscillator
between walls); otherwise :func:`event_reference`, scipy's DOP853 at rtol 1e-12, atol 1e-14
with event location and the elastic law ``v+ = v- - 2 (n.v-)/(n.M^-1 n) M^-1 n``.

Backends: every test is parametrized over :data:`BACKENDS`; the C one is skipped only when
:func:`c_backend_problem` finds it missing or unable to build a trial model.
"""

from __future__ import annotations

import importlib.util
import math
import shutil
from functools import cache

import numpy as np
import pytest
import sympy as sp
from scenes import load_example
from scipy.integrate import solve_ivp

import vcigen

RULES = ["trapezoid", "midpoint"]
G = 9.81


# ------------------------------------------------------------------ backends


@cache
def c_backend_problem() -> str | None:
    """Why the C backend cannot run here (no C compiler), or ``None`` when it can (checked once). Only the
    compiler's absence skips: with ``cc`` on PATH a build that fails is the test's failure (a trial build
    that skipped every C test on any error would hide a template that does not compile)."""
    if importlib.util.find_spec("vcigen.backends.c") is None:
        return "C backend not available: vcigen.backends.c does not exist yet"
    if shutil.which("cc") is None:
        return "C backend not available: no C compiler (cc) on PATH"
    return None


def backend_param(name: str):
    """``pytest.param(name)``, skipped for ``"c"`` when the C backend cannot run."""
    if name != "c":
        return pytest.param(name, id=name)
    problem = c_backend_problem()
    return pytest.param(name, id=name, marks=pytest.mark.skipif(problem is not None, reason=problem or ""))


@cache
def simulator(
    scene: str, backend: str = "casadi", rule: str = "trapezoid", tol: vcigen.Tolerances | None = None
) -> vcigen.Simulator:
    """Build each scene once per session (``scene`` is a factory name of this module)."""
    return vcigen.build(MAKERS[scene](), backend=backend, rule=rule, tol=tol)


# ------------------------------------------------------------------ models


def box(order: tuple[str, ...] = ("left", "right", "bottom", "top"), lossy: bool = False) -> vcigen.Model:
    """A unit particle in the box ``0 <= x <= W``, ``0 <= y <= H`` under gravity ``g`` (default 0).

    ``order`` fixes the order of the contacts dict (the answer must not depend on it);
    ``lossy``: every wall has the coefficient of restitution ``e`` (a parameter, 1 by default).
    """
    x, y, xd, yd = sp.symbols("x y xd yd")
    W, H, g = sp.symbols("W H g", positive=True)
    e = sp.Symbol("e")
    walls = {"left": x, "right": W - x, "bottom": y, "top": H - y}
    return vcigen.Model(
        name="box_lossy" if lossy else "box",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={k: walls[k] for k in order},
        params={W: 1.0, H: 1.0, g: 0.0, **({e: 1.0} if lossy else {})},
        restitution=dict.fromkeys(order, e) if lossy else {},
    )


def corner(order: tuple[str, ...] = ("left", "bottom")) -> vcigen.Model:
    """A unit particle in the quadrant ``x >= 0``, ``y >= 0`` under gravity ``g`` (default 0)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g = sp.symbols("g", positive=True)
    walls = {"left": x, "bottom": y}
    return vcigen.Model(
        name="corner",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={k: walls[k] for k in order},
        params={g: 0.0},
    )


def walls() -> vcigen.Model:
    """A unit particle between the walls ``x = 0`` and ``x = d`` (d = 0.01), gravity ``g`` along y."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    d, g = sp.symbols("d g", positive=True)
    return vcigen.Model(
        name="walls",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"near": x, "far": d - x},
        params={d: 0.01, g: G},
    )


def walls_oscillator() -> vcigen.Model:
    """``x'' = -w^2 x`` between the walls ``x = -a`` and ``x = a``: a nonlinear flow, closed form."""
    x, xd = sp.symbols("x xd")
    w, a = sp.symbols("w a", positive=True)
    return vcigen.Model(
        name="walls_osc",
        q=[x],
        qdot=[xd],
        lagrangian=xd**2 / 2 - w**2 * x**2 / 2,
        contacts={"left": x + a, "right": a - x},
        params={w: 4.0, a: 0.05},
    )


def double_pendulum() -> vcigen.Model:
    """Point masses m1 = m2 = 1 on rods l1 = l2 = 1, angles from the downward vertical, wall x = 1.2."""
    t1, t2, w1, w2 = sp.symbols("theta1 theta2 omega1 omega2")
    m1, m2, l1, l2, g, xw = sp.symbols("m1 m2 l1 l2 g x_w", positive=True)
    kinetic = (
        (m1 + m2) / 2 * l1**2 * w1**2 + m2 / 2 * l2**2 * w2**2 + m2 * l1 * l2 * w1 * w2 * sp.cos(t1 - t2)
    )
    potential = -(m1 + m2) * g * l1 * sp.cos(t1) - m2 * g * l2 * sp.cos(t2)
    return vcigen.Model(
        name="double_pendulum",
        q=[t1, t2],
        qdot=[w1, w2],
        lagrangian=kinetic - potential,
        contacts={"wall": xw - (l1 * sp.sin(t1) + l2 * sp.sin(t2))},
        params={m1: 1.0, m2: 1.0, l1: 1.0, l2: 1.0, g: G, xw: 1.2},
    )


def dumbbell() -> vcigen.Model:
    """Two unit masses joined by a stiff spring, gravity, floor y = 0.

    The spring is ``k/8 (r^2 - l0^2)^2 / l0^2`` (stiffness ``k = 1e4`` at the rest length
    ``l0 = 1``; polynomial, so the derivation stays fast); the stretching mode has
    ``omega = sqrt(2 k) ~ 141``.
    """
    x1, y1, x2, y2 = sp.symbols("x1 y1 x2 y2")
    u1, v1, u2, v2 = sp.symbols("u1 v1 u2 v2")
    k, l0, g = sp.symbols("k l0 g", positive=True)
    stretch = ((x1 - x2) ** 2 + (y1 - y2) ** 2 - l0**2) / (2 * l0)
    return vcigen.Model(
        name="dumbbell",
        q=[x1, y1, x2, y2],
        qdot=[u1, v1, u2, v2],
        lagrangian=(u1**2 + v1**2 + u2**2 + v2**2) / 2 - k / 2 * stretch**2 - g * (y1 + y2),
        contacts={"floor1": y1, "floor2": y2},
        params={k: 1e4, l0: 1.0, g: G},
    )


def stiff_pendulum() -> vcigen.Model:
    """A unit particle on a stiff spring (k = 1e4) hung from the origin, gravity, wall ``x = 0.5``.

    The spring is ``k/8 (r^2 - l0^2)^2 / l0^2``, stiffness ``k`` at the rest length ``l0 = 1``;
    the radial mode has ``omega ~ sqrt(k) = 100``, the swing ``omega ~ 3``.
    """
    x, y, xd, yd = sp.symbols("x y xd yd")
    k, l0, g, xw = sp.symbols("k l0 g x_w", positive=True)
    stretch = (x**2 + y**2 - l0**2) / (2 * l0)
    return vcigen.Model(
        name="stiff_pendulum",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - k / 2 * stretch**2 - g * y,
        contacts={"wall": xw - x},
        params={k: 1e4, l0: 1.0, g: G, xw: 0.5},
    )


def ceiling() -> vcigen.Model:
    """A unit particle under gravity below the ceiling ``y = c`` (c = 1)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    c, g = sp.symbols("c g", positive=True)
    return vcigen.Model(
        name="ceiling",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"ceiling": c - y},
        params={c: 1.0, g: G},
    )


def ball(elastic: bool = False) -> vcigen.Model:
    """A unit ball under gravity on the floor ``y = 0`` with restitution ``e`` (a parameter, 0.5)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    e = sp.Symbol("e")
    return vcigen.Model(
        name="ball",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y},
        params={e: 0.5},
        restitution={} if elastic else {"floor": e},
    )


def zeno_time(e: float, height: float = 1.0) -> float:
    """When a ball dropped from ``height`` with restitution ``e`` comes to rest: t_1 + 2 e v_1/(g (1 - e))."""
    v1 = math.sqrt(2 * G * height)
    return v1 / G + 2 * e * v1 / (G * (1 - e))


def star() -> vcigen.Model:
    """The paper's star with ``Abs`` in phi (eq. 81), from ``examples/star.py``."""
    return load_example("star").model()


MAKERS = {
    "box": box,
    "box_reversed": lambda: box(("top", "bottom", "right", "left")),
    "box_lossy": lambda: box(lossy=True),
    "corner": corner,
    "corner_reversed": lambda: corner(("bottom", "left")),
    "walls": walls,
    "walls_oscillator": walls_oscillator,
    "double_pendulum": double_pendulum,
    "dumbbell": dumbbell,
    "stiff_pendulum": stiff_pendulum,
    "ceiling": ceiling,
    "star": star,
    "ball": ball,
    "ball_elastic": lambda: ball(elastic=True),
}

BACKENDS = [backend_param("casadi"), backend_param("c")]


# ------------------------------------------------------------------ closed forms


def unfold(x0: float, v: float, lo: float, hi: float, t):
    """Free motion in ``[lo, hi]`` with elastic walls: unfold onto a circle of length ``2 (hi - lo)``."""
    width = hi - lo
    s = np.mod(x0 - lo + v * np.asarray(t, float), 2 * width)
    return lo + np.where(s <= width, s, 2 * width - s)


def unfold_velocity(x0: float, v: float, lo: float, hi: float, t):
    """Velocity of :func:`unfold` (the sign flips at every wall)."""
    width = hi - lo
    s = np.mod(x0 - lo + v * np.asarray(t, float), 2 * width)
    return np.where(s <= width, v, -v)


def walls_oscillator_exact(t, amplitude: float, w: float, a: float):
    """``x'' = -w^2 x`` from ``x(0) = 0``, ``x'(0) = amplitude w > 0`` between walls at ``+-a < amplitude``.

    ``x = A sin(w s(t))`` with ``s`` a triangle wave of half-period ``t1 = asin(a/A)/w``:
    each wall sends the particle back along the time-reversed arc.
    """
    t1 = np.arcsin(a / amplitude) / w
    tp = np.mod(np.asarray(t, float) + t1, 4 * t1)
    s = np.where(tp <= 2 * t1, tp - t1, 3 * t1 - tp)
    return amplitude * np.sin(w * s)


def parabola(q0, v0, t, g: float = G):
    """Free flight of a unit particle under gravity ``-g e_y``: ``(x(t), y(t))`` rows."""
    t = np.asarray(t, float)
    return np.column_stack([q0[0] + v0[0] * t, q0[1] + v0[1] * t - g * t**2 / 2])


# ------------------------------------------------------------------ event-driven reference


class EventReference:
    """DOP853 (rtol 1e-12, atol 1e-14) on the Euler-Lagrange equations of a smooth ``Model``.

    Contacts are located as events; at each impact the elastic law
    ``v+ = v- - 2 (n.v-)/(n.M^-1 n) M^-1 n``, ``n = grad phi``, is applied.
    """

    def __init__(self, model: vcigen.Model, params: dict | None = None) -> None:
        q, qd = list(model.coordinates), list(model.velocities)
        values = dict(model.defaults)
        for key, val in (params or {}).items():
            values[next(s for s in values if s == key or s.name == str(key))] = val
        lag = model.L.subs(values)
        mass = sp.hessian(lag, qd)
        p = sp.Matrix([sp.diff(lag, v) for v in qd])
        # M qdd = dL/dq - (d/dq dL/dqdot) qdot
        force = sp.Matrix([sp.diff(lag, c) for c in q]) - p.jacobian(q) * sp.Matrix(qd)
        energy = (p.T * sp.Matrix(qd))[0] - lag
        phis = [e.subs(values) for e in model.phi.values()]
        self.names = list(model.phi)
        self.n = len(q)
        self._mass = sp.lambdify([q, qd], mass, "numpy")
        self._force = sp.lambdify([q, qd], force, "numpy")
        self._energy = sp.lambdify([q, qd], energy, "numpy")
        self._phi = [sp.lambdify([q], e, "numpy") for e in phis]
        self._grad = [sp.lambdify([q], [sp.diff(e, c) for c in q], "numpy") for e in phis]

    def mass(self, q) -> np.ndarray:
        return np.array(self._mass(q, np.zeros(self.n)), float)

    def energy(self, q, v) -> float:
        return float(self._energy(q, v))

    def _rhs(self, _t, y):
        q, v = y[: self.n], y[self.n :]
        acc = np.linalg.solve(np.array(self._mass(q, v), float), np.array(self._force(q, v), float).ravel())
        return np.concatenate([v, acc])

    def reflect(self, q, v, j: int) -> np.ndarray:
        nrm = np.array(self._grad[j](q), float)
        minv_n = np.linalg.solve(self.mass(q), nrm)
        return v - 2.0 * (nrm @ v) / (nrm @ minv_n) * minv_n

    def run(self, q0, v0, t_end: float, t_eval=None, max_impacts: int = 10_000):
        """States at ``t_eval`` (default: ``t_end`` only) and impact times/contacts up to ``t_end``."""
        t_eval = np.atleast_1d(np.asarray([t_end] if t_eval is None else t_eval, float))
        n = self.n
        events = []
        for j in range(len(self._phi)):

            def ev(_t, y, j=j):
                return float(self._phi[j](y[:n]))

            ev.terminal, ev.direction = True, -1
            events.append(ev)
        t, y = 0.0, np.concatenate([np.asarray(q0, float), np.asarray(v0, float)])
        out = np.full((t_eval.size, 2 * n), np.nan)
        impacts: list[tuple[float, str]] = []
        while True:
            sol = solve_ivp(
                self._rhs, (t, t_end), y, method="DOP853", rtol=1e-12, atol=1e-14,
                events=events, dense_output=True,
            )  # fmt: skip
            hits = [(te[0], j) for j, te in enumerate(sol.t_events) if te.size and te[0] > t]
            t_hit = min(hits)[0] if hits else t_end
            inside = (t_eval >= t) & (t_eval <= t_hit)
            if inside.any():
                out[inside] = sol.sol(t_eval[inside]).T
            if not hits or len(impacts) >= max_impacts:
                break
            t_hit, j = min(hits)
            y = sol.sol(t_hit)
            y[n:] = self.reflect(y[:n], y[n:], j)
            impacts.append((float(t_hit), self.names[j]))
            t = t_hit
        return out[:, :n], out[:, n:], impacts


# ------------------------------------------------------------------ checks shared by the tests


def min_phi(sim: vcigen.Simulator, res: vcigen.Result, params: dict | None = None) -> float:
    """The smallest ``phi_j(q_k)`` over every grid point and contact."""
    model = sim.model
    values = dict(model.defaults)
    for key, val in (params or {}).items():
        values[next(s for s in values if s == key or s.name == str(key))] = val
    f = sp.lambdify([list(model.coordinates)], [e.subs(values) for e in model.phi.values()], "numpy")
    vals = f(res.q.T)
    return float(min(np.min(np.broadcast_to(v, res.q.shape[:1])) for v in vals))


def impact_energy_jumps(res: vcigen.Result) -> np.ndarray:
    """``|E_after - E_before|`` of every impact."""
    return np.array([abs(im.energy_after - im.energy_before) for im in res.impacts])
