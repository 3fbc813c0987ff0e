"""``vcigen.build`` and the simulator it returns (shared/API.md)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np

from .derive import DiscreteSystem, derive
from .errors import SolverError
from .model import Model
from .result import Result
from .rules import Rule
from .stepper import Stepper, Tolerances, warn_reflected
from .work import friction_work, step_work, tangent_function, work_function

Backend = Literal["casadi", "c"]
BACKENDS = ("casadi", "c")
CONSTRAINT_TOL = 1e-9  # |g(q0)| and |grad g . v0| accepted at the start (bilateral constraints)


class Simulator:
    """A model compiled for one backend and rule; call :meth:`simulate`."""

    def __init__(self, system: DiscreteSystem, kernels, tol: Tolerances | None = None) -> None:
        self.system = system
        self.model: Model = system.model
        self.kernels = kernels
        self.tol = tol or Tolerances()
        self._work = work_function(system)
        self._friction = tangent_function(system)

    @property
    def backend(self) -> str:
        return self.kernels.backend

    def simulate(
        self,
        q0: Sequence[float],
        v0: Sequence[float],
        h: float,
        t_end: float | None = None,
        n_impacts: int | None = None,
        params: Mapping[object, float] | None = None,
        t0: float = 0.0,
        progress: bool = False,
    ) -> Result:
        """Integrate from ``(q0, v0)`` with step ``h`` until ``t_end`` or ``n_impacts``."""
        q0a, v0a, h = self._validate(q0, v0, h, t_end, n_impacts, t0)
        par = self.model.resolve_params(params)
        self.model.restitution_values(par)  # each in [0, 1] at these parameters, or a ValueError
        mu_f = self.model.friction_values(par)  # each >= 0, or a ValueError
        # the slots the stepper sets: friction in sustained contact (0 at the start), then the time a segment
        # starts at (Kernels.at), last
        slots = len(self.system.params) - len(par) - self.system.timed
        par = par + [0.0] * slots + ([float(t0)] if self.system.timed else [])
        kern = self.kernels.bind(par)
        self._check_start(kern, q0a, v0a)
        try:
            res = self._run(kern, q0a, v0a, h, t_end, n_impacts, t0, progress)
        except SolverError as err:
            if err.result is not None:
                self._book_work(err.result, mu_f, par)
            raise
        self._book_work(res, mu_f, par)
        res.coordinate_names = self.model.coordinate_names
        warn_reflected(res.stats.get("grazing_reflected", 0))
        return res

    def _book_work(self, res: Result, mu_f: list[float], par: list[float]) -> None:
        """``res.work`` (forces, friction in sustained contact: ``vcigen.work``) and what its energy means."""
        res.friction_work = friction_work(res, self._friction, mu_f, par)
        res.work = step_work(res, self._work, par) + res.friction_work
        res.energy_at_end = bool(self.model.force)

    def _run(self, kern, q0, v0, h, t_end, n_impacts, t0, progress) -> Result:
        return Stepper(kern, self.tol).simulate(
            q0, v0, h, t_end=t_end, n_impacts=n_impacts, t0=t0, progress=progress
        )

    # -- validation ------------------------------------------------------------------
    def _validate(self, q0, v0, h, t_end, n_impacts, t0):
        n = self.model.n
        q0a = _vector("q0", q0, n)
        v0a = _vector("v0", v0, n)
        h = _finite("h", h)
        if h <= 0:
            raise ValueError(f"h = {h} must be > 0")
        _finite("t0", t0)
        if t_end is None and n_impacts is None:
            raise ValueError("give t_end, n_impacts, or both, to say when to stop")
        if t_end is not None and _finite("t_end", t_end) < t0:
            raise ValueError(f"t_end = {t_end} is before t0 = {t0}")
        if n_impacts is not None and (int(n_impacts) != n_impacts or n_impacts < 0):
            raise ValueError(f"n_impacts = {n_impacts!r} must be a whole number >= 0")
        return q0a, v0a, h

    def _check_start(self, kern, q0, v0) -> None:
        phi, _ = kern.contacts(q0)
        for name, val in zip(self.system.contact_names, phi):
            if not val >= -self.tol.admissible:
                raise ValueError(
                    f"q0 violates contact '{name}' (phi = {val:.6g} < 0); start inside the admissible set"
                )
        if kern.r and self.model.constraint:
            psi, grad, _ = kern.rows(q0, v0)
            for r in range(kern.r):
                i = kern.row_constraint[r]
                if i < 0:
                    continue
                name = list(self.model.constraint)[i]
                if not abs(psi[r]) <= CONSTRAINT_TOL:
                    raise ValueError(
                        f"q0 violates constraint '{name}' (g = {psi[r]:.6g}); start on every constraint "
                        f"(|g| <= {CONSTRAINT_TOL:g})"
                    )
                rate = float(grad[r] @ v0)
                if not abs(rate) <= CONSTRAINT_TOL * (1.0 + float(np.abs(grad[r]).max() * np.abs(v0).max())):
                    raise ValueError(
                        f"v0 is not tangent to constraint '{name}' (dg/dt = {rate:.6g}); give a velocity "
                        "with grad g . v0 = 0"
                    )
        _, mass = kern.legendre(q0, v0)
        if not np.all(np.isfinite(mass)) or np.linalg.cond(mass) > 1e12:
            raise ValueError(
                f"d2L/dqdot2 is singular or not finite at (q0, v0) (cond = {np.linalg.cond(mass):.3g}); "
                "the Lagrangian must be regular where the model is used"
            )


def _finite(name: str, x: object) -> float:
    try:
        val = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    if not math.isfinite(val):
        raise ValueError(f"{name} = {val} is not finite")
    return val


def _vector(name: str, x: Sequence[float], n: int) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a sequence of {n} numbers, got {x!r}") from None
    if arr.size != n:
        raise ValueError(f"{name} has {arr.size} entries but the model has {n} coordinates")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} = {arr.tolist()} contains a non-finite number")
    return arr


def build(
    model: Model,
    backend: Backend = "casadi",
    rule: str | Rule = "trapezoid",
    tol: Tolerances | None = None,
    **options,
) -> Simulator:
    """Derive ``model`` under ``rule`` and compile it for ``backend``."""
    if not isinstance(model, Model):
        raise ValueError(f"build() needs a vcigen.Model, got {type(model).__name__}")
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {list(BACKENDS)}")
    system = derive(model, rule)
    if backend == "casadi":
        from .backends.casadi import CasadiKernels

        return Simulator(system, CasadiKernels(system), tol)
    from .backends.c import build_c

    return build_c(system, tol=tol or Tolerances(), **options)
