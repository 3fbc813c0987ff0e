"""Benchmark scenes as plain data: mass matrix, potential, contacts, start state.

Every function of ``q`` accepts ``q`` of shape ``(n,)``; ``phi`` also accepts
``(n, k)`` (a batch of ``k`` configurations, one per column) and returns ``(k,)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

Array = np.ndarray
G = 9.81


@dataclass(frozen=True)
class Contact:
    """A unilateral constraint ``phi(q) >= 0`` with (a selection of) its gradient."""

    name: str
    phi: Callable[[Array], Any]
    grad_phi: Callable[[Array], Array]


@dataclass(frozen=True)
class Scene:
    """A mechanical system ``L = 1/2 v^T M(q) v - V(q)`` with contacts.

    ``dmass(q)`` returns ``dM[i, j, k] = dM_ij/dq_k`` (``None``: ``M`` is constant).
    """

    name: str
    n: int
    mass: Callable[[Array], Array]
    potential: Callable[[Array], float]
    grad_potential: Callable[[Array], Array]
    contacts: tuple[Contact, ...]
    q0: Array
    v0: Array
    h: float
    model_factory: Callable[[], Any] = field(repr=False)
    dmass: Callable[[Array], Array] | None = None
    description: str = ""

    @property
    def constant_mass(self) -> bool:
        """True when ``M`` does not depend on ``q``."""
        return self.dmass is None

    def energy(self, q: Array, v: Array) -> float:
        """Continuous energy ``1/2 v^T M v + V``."""
        return 0.5 * float(v @ self.mass(q) @ v) + float(self.potential(q))

    def accel(self, q: Array, v: Array) -> Array:
        """Free-flight acceleration from the Euler–Lagrange equations."""
        rhs = -self.grad_potential(q)
        if self.dmass is not None:
            dm = self.dmass(q)
            rhs = rhs - np.einsum("ijk,k,j->i", dm, v, v) + 0.5 * np.einsum("ijk,i,j->k", dm, v, v)
        return np.linalg.solve(self.mass(q), rhs)

    def reflect(self, q: Array, v: Array, contact: Contact, n: Array | None = None) -> Array:
        """Elastic impact law ``v+ = v- - 2 (n.v)/(n.M^-1 n) M^-1 n``, ``n = grad phi(q)``."""
        n = contact.grad_phi(q) if n is None else n
        minv_n = np.linalg.solve(self.mass(q), n)
        return v - 2.0 * (n @ v) / (n @ minv_n) * minv_n

    def vcigen_model(self) -> Any:
        """The same scene as a ``vcigen.Model`` (imports vcigen lazily)."""
        return self.model_factory()


# ---------------------------------------------------------------- particle


def _example_model(name: str) -> Any:
    """The model of ``examples/<name>.py``: the bench runs the very scene the examples run."""
    from vcigen.cli import load_example

    return load_example(Path(__file__).resolve().parents[1] / "examples" / f"{name}.py").model()


def _particle_model() -> Any:
    return _example_model("particle")


def particle() -> Scene:
    """Paper §4.1: unit mass under gravity above the floor ``y = 0``."""
    floor = Contact("floor", lambda q: q[1], lambda q: np.array([0.0, 1.0]))
    return Scene(
        name="particle",
        n=2,
        mass=lambda q: np.eye(2),
        potential=lambda q: G * q[1],
        grad_potential=lambda q: np.array([0.0, G]),
        contacts=(floor,),
        q0=np.array([0.0, 1.0]),
        v0=np.array([-2.0, 0.0]),
        h=0.01,
        model_factory=_particle_model,
        description="m=1, g=9.81, floor y=0",
    )


# ---------------------------------------------------------------- star

STAR_L = 1.0
STAR_M = 1.0
STAR_I = 29.0 / 192.0 * STAR_M * STAR_L**2
STAR_R = 5.0  # radius of the nonlinear gravity V = -m g R^2 / (R + y)


def star_phi(q: Array) -> Any:
    """Height of the lowest vertex, eq. (81): ``y - L/2 (|sin th| + |cos th|)``."""
    return q[1] - STAR_L / 2 * (np.abs(np.sin(q[2])) + np.abs(np.cos(q[2])))


def star_grad_phi(q: Array) -> Array:
    """Gradient of eq. (81), branch chosen by ``np.sign`` (0 at a kink)."""
    s, c = np.sin(q[2]), np.cos(q[2])
    return np.array([0.0, 1.0, -STAR_L / 2 * (np.sign(s) * c - np.sign(c) * s)])


def _star_model(nonlinear: bool) -> Any:
    if not nonlinear:
        return _example_model("star")
    import sympy as sp

    import vcigen

    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    m, g, ell, R = sp.symbols("m g L R", positive=True)
    inertia = sp.Rational(29, 192) * m * ell**2
    return vcigen.Model(
        name="star_nonlinear",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 + m * g * R**2 / (R + y),
        contacts={"floor": y - ell / 2 * (sp.Abs(sp.sin(th)) + sp.Abs(sp.cos(th)))},
        params={m: STAR_M, g: G, ell: STAR_L, R: STAR_R},
    )


def star(nonlinear: bool = False) -> Scene:
    """Paper §4.3 four-point star; ``nonlinear`` uses ``V = -m g R^2/(R+y)``, R=5.

    The paper's Fig. 5 only says "a nonlinear gravity"; this ``V`` is our choice
    (it tends to ``m g y`` for ``y << R``, up to a constant).
    """
    mass = np.diag([STAR_M, STAR_M, STAR_I])
    if nonlinear:
        k = STAR_M * G * STAR_R**2

        def pot(q: Array) -> float:
            return -k / (STAR_R + q[1])

        def grad(q: Array) -> Array:
            return np.array([0.0, k / (STAR_R + q[1]) ** 2, 0.0])

    else:

        def pot(q: Array) -> float:
            return STAR_M * G * q[1]

        def grad(q: Array) -> Array:
            return np.array([0.0, STAR_M * G, 0.0])

    return Scene(
        name="star_nonlinear" if nonlinear else "star",
        n=3,
        mass=lambda q: mass,
        potential=pot,
        grad_potential=grad,
        contacts=(Contact("floor", star_phi, star_grad_phi),),
        q0=np.array([0.0, 3.5, 0.0]),
        v0=np.array([-2.0, 0.0, 5.0]),
        h=0.005,
        model_factory=lambda: _star_model(nonlinear),
        description="m=1, L=1, I=29/192 m L^2, " + ("V=-m g R^2/(R+y), R=5" if nonlinear else "V=m g y"),
    )


def star_nonlinear() -> Scene:
    """The star under the nonlinear gravity ``V = -m g R^2/(R+y)``, R=5."""
    return star(nonlinear=True)


# ---------------------------------------------------------------- pendulum

PW_M1 = PW_M2 = 1.0
PW_L1 = PW_L2 = 1.0
PW_WALL = 1.2


def _pw_mass(q: Array) -> Array:
    c = PW_M2 * PW_L1 * PW_L2 * np.cos(q[0] - q[1])
    return np.array([[(PW_M1 + PW_M2) * PW_L1**2, c], [c, PW_M2 * PW_L2**2]])


def _pw_dmass(q: Array) -> Array:
    s = -PW_M2 * PW_L1 * PW_L2 * np.sin(q[0] - q[1])  # d/dth1 of M12
    dm = np.zeros((2, 2, 2))
    dm[0, 1, 0] = dm[1, 0, 0] = s
    dm[0, 1, 1] = dm[1, 0, 1] = -s
    return dm


def _pw_pot(q: Array) -> float:
    return -(PW_M1 + PW_M2) * G * PW_L1 * np.cos(q[0]) - PW_M2 * G * PW_L2 * np.cos(q[1])


def _pw_grad(q: Array) -> Array:
    return np.array([(PW_M1 + PW_M2) * G * PW_L1 * np.sin(q[0]), PW_M2 * G * PW_L2 * np.sin(q[1])])


def _pw_model() -> Any:
    import sympy as sp

    import vcigen

    t1, t2, w1, w2 = sp.symbols("theta1 theta2 omega1 omega2")
    m1, m2, l1, l2, g, d = sp.symbols("m1 m2 l1 l2 g d", positive=True)
    kin = (m1 + m2) / 2 * l1**2 * w1**2 + m2 / 2 * l2**2 * w2**2
    kin += m2 * l1 * l2 * sp.cos(t1 - t2) * w1 * w2
    pot = -(m1 + m2) * g * l1 * sp.cos(t1) - m2 * g * l2 * sp.cos(t2)
    return vcigen.Model(
        name="pendulum_wall",
        q=[t1, t2],
        qdot=[w1, w2],
        lagrangian=kin - pot,
        contacts={"wall": d - (l1 * sp.sin(t1) + l2 * sp.sin(t2))},
        params={m1: PW_M1, m2: PW_M2, l1: PW_L1, l2: PW_L2, g: G, d: PW_WALL},
    )


def pendulum_wall() -> Scene:
    """Double pendulum (angles from the downward vertical), tip against the wall ``x = 1.2``."""
    wall = Contact(
        "wall",
        lambda q: PW_WALL - (PW_L1 * np.sin(q[0]) + PW_L2 * np.sin(q[1])),
        lambda q: -np.array([PW_L1 * np.cos(q[0]), PW_L2 * np.cos(q[1])]),
    )
    return Scene(
        name="pendulum_wall",
        n=2,
        mass=_pw_mass,
        potential=_pw_pot,
        grad_potential=_pw_grad,
        contacts=(wall,),
        q0=np.array([0.0, 0.0]),
        v0=np.array([6.0, 8.0]),
        h=0.005,
        model_factory=_pw_model,
        dmass=_pw_dmass,
        description="m1=m2=1, l1=l2=1, g=9.81, wall x=1.2 right of the pivot",
    )


SCENES: dict[str, Callable[[], Scene]] = {
    "particle": particle,
    "star": star,
    "star_nonlinear": star_nonlinear,
    "pendulum_wall": pendulum_wall,
}


def get(name: str) -> Scene:
    """Scene by name."""
    try:
        return SCENES[name]()
    except KeyError:
        raise ValueError(f"unknown scene {name!r}; known: {sorted(SCENES)}") from None
