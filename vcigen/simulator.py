"""``vcigen.build`` and the simulator it returns (shared/API.md)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from functools import partial
from typing import Literal, NamedTuple

import numpy as np

from .backends import registry
from .booking import tangent_function, work_function
from .derive import DiscreteSystem, derive
from .errors import SolverError
from .model import Model
from .progress import Progress
from .result import Result
from .rules import Rule
from .stepper import (
    Stepper,
    Tolerances,
    warn_friction_dropped,
    warn_reflected,
    warn_restitution_reduced,
    warn_sticks_kept,
)
from .velocity import LegendreInverse
from .work import friction_work, step_work

Backend = Literal["casadi", "c"]
BACKENDS = ("casadi", "c")  # the built-in backends (vcigen.backends.registry.names() has any others)
ErrorMode = Literal["raise", "return"]
ERROR_MODES = ("raise", "return")
CONSTRAINT_TOL = 1e-9  # |g(q0)| and |grad g . v0| accepted at the start (bilateral constraints)
MAX_CONDITION = 1e12  # cond(d2L/dqdot2) accepted at the start


class Start(NamedTuple):
    """One run of ``simulate_many``, checked: its start, its ``params`` and what they resolve to."""

    q0: np.ndarray
    v0: np.ndarray
    p0: np.ndarray  # dL/dqdot(q0, v0)
    params: Mapping[object, float] | None
    par: list[float]  # the kernels' parameter vector
    mu_f: list[float]  # each contact's friction coefficient


class ManyStarts:
    """The runs of ``simulate_many``, checked: ``q``, ``v``, ``p0`` as ``(K, n)`` arrays and each run's
    ``params``, parameter vector ``par`` and ``mu_f`` in lists; ``starts[i]``: run ``i``'s :class:`Start`."""

    def __init__(self, q, v, p0, params: list, par: list[list[float]], mu_f: list[list[float]]) -> None:
        self.q, self.v, self.p0, self.params, self.par, self.mu_f = q, v, p0, params, par, mu_f

    def __len__(self) -> int:
        return len(self.par)

    def __getitem__(self, i: int) -> Start:
        return Start(self.q[i], self.v[i], self.p0[i], self.params[i], self.par[i], self.mu_f[i])

    def __iter__(self):
        return (self[i] for i in range(len(self)))


class Simulator:
    """A model compiled for one backend and rule; call :meth:`simulate` or :meth:`simulate_many`."""

    def __init__(self, system: DiscreteSystem, kernels, tol: Tolerances | None = None) -> None:
        self.system = system
        self.model: Model = system.model
        self.kernels = kernels
        self.tol = tol or Tolerances()
        self._work = work_function(system)
        self._friction = tangent_function(system)
        self._inverse: LegendreInverse | None = None  # built when a Result's v is first read
        self._tangents = None  # vcigen.sensitivity.Tangents, built on the first simulate(sensitivities=True)
        self._defaults: tuple[list[float], list[float]] | None = None  # _parameters(None)
        self._coordinate_names = tuple(self.model.coordinate_names)
        self._constraint_names = tuple(self.model.constraint)  # (a property that builds a dict)

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
        progress: bool = True,
        sensitivities: bool = False,
    ) -> Result:
        """Integrate from ``(q0, v0)`` with step ``h`` until ``t_end`` or ``n_impacts``.

        ``progress``: a progress bar on stderr (``vcigen.progress``) for a run projected to take more than
        2 s; nothing for shorter runs, nothing at all with ``progress=False``.

        ``sensitivities``: also ``res.sensitivity`` ``(N, 2n, 2n + P)``, the exact ``d(q_k, p_k)/d(q0, v0,
        params)`` (:mod:`vcigen.sensitivity`), its column names ``res.sensitivity_names``, and the steps no
        tangent goes through, ``res.sensitivity_breaks`` (NaN after the first, ``stats["sensitivity_lost"]``).
        """
        q0a, v0a = self._start_vectors(q0, v0)
        h = self._validate(h, t_end, n_impacts, t0)
        par, mu_f = self._parameters(params, t0)
        kern = self.kernels.bind(par)
        p0 = self._check_start(kern, q0a, v0a)
        with Progress(1.0, f"simulate {self.model.name}", enabled=progress) as bar:
            try:
                run = self._run_sensitive if sensitivities else self._run
                res = run(kern, q0a, v0a, p0, h, t_end, n_impacts, t0, bar)
            except SolverError as err:
                if err.result is not None:
                    self._finish(err.result, mu_f, par)
                raise
        self._finish(res, mu_f, par)
        warn_reflected(res.stats.get("grazing_reflected", 0))
        warn_friction_dropped(res.stats.get("landing_friction_dropped", 0))
        warn_restitution_reduced(res.stats.get("restitution_reduced", 0))
        warn_sticks_kept(res.stats.get("sticks_kept", 0), res.stats.get("jams", 0))
        return res

    def simulate_many(
        self,
        q0s: Sequence[Sequence[float]],
        v0s: Sequence[Sequence[float]],
        h: float,
        t_end: float | None = None,
        n_impacts: int | None = None,
        params: Mapping[object, float] | Sequence[Mapping[object, float] | None] | None = None,
        t0: float = 0.0,
        progress: bool = True,
        errors: ErrorMode = "raise",
        threads: int = 1,
        sensitivities: bool = False,
    ) -> list[Result | SolverError]:
        """``K`` runs from ``q0s[i], v0s[i]`` (shape ``(K, n)``), each equal to ``simulate`` with the same
        arguments; ``params`` is one mapping for all runs or a sequence of ``K`` (``None``: the defaults).

        A run that raises :class:`~vcigen.SolverError`: with ``errors="raise"`` (default) the first such
        run's error is raised once all runs are done, its message starting ``run i:``, with ``.run = i``,
        ``.result`` (that run up to its last completed step) and ``.results`` (the list, that error in
        run ``i``'s place); with ``errors="return"`` the list holds the error in place of the result.
        Bad input (any run's) raises ``ValueError`` naming the run before anything runs. ``threads``: the
        C backend splits the runs over that many threads (results identical); the CasADi backend runs
        them one after another. ``sensitivities``: each run with its tangent, as ``simulate(...,
        sensitivities=True)``; the runs then go one after another on both backends (each one call of the C
        tangent loop; ``threads`` is not used).
        """
        if errors not in ERROR_MODES:
            raise ValueError(f"errors = {errors!r}; use one of {list(ERROR_MODES)}")
        if int(threads) != threads or threads < 1:
            raise ValueError(f"threads = {threads!r} must be a whole number >= 1")
        h = self._validate(h, t_end, n_impacts, t0)
        starts = self._starts(*self._many_starts(q0s, v0s, params), t0)
        if sensitivities:
            out = self._each_run(starts, h, t_end, n_impacts, t0, progress, sensitivities=True)
        else:
            out = self._run_many(starts, h, t_end, n_impacts, t0, progress, int(threads))
        return _many_outcome(out, errors)

    def _starts(self, q: np.ndarray, v: np.ndarray, per_run: list, t0: float) -> ManyStarts:
        """Each run of ``simulate_many`` checked as ``simulate`` checks its start; the first bad run is a
        ``ValueError`` starting ``run i:``. ``params`` resolved once per mapping object."""
        starts, resolved = [], {}
        for i, (q0, v0, par_i) in enumerate(zip(q, v, per_run)):
            try:
                if id(par_i) not in resolved:
                    resolved[id(par_i)] = self._parameters(par_i, t0)
                    self.kernels.bind(resolved[id(par_i)][0])
                elif i and par_i is not starts[-1].params:
                    self.kernels.bind(resolved[id(par_i)][0])
                par, mu_f = resolved[id(par_i)]
                p0 = self._check_start(self.kernels, q0, v0)
            except ValueError as exc:
                raise ValueError(f"run {i}: {exc}") from None
            starts.append(Start(q0, v0, p0, par_i, par, mu_f))
        cols = list(zip(*starts)) if starts else [[]] * 6
        n = self.model.n
        p0 = np.array(cols[2]).reshape(-1, n)
        return ManyStarts(q.reshape(-1, n), v.reshape(-1, n), p0, *map(list, cols[3:]))

    def _run_many(self, starts, h, t_end, n_impacts, t0, progress, threads) -> list[Result | SolverError]:
        """One ``simulate`` per run, after one another (the Python stepper)."""
        return self._each_run(starts, h, t_end, n_impacts, t0, progress)

    def _each_run(
        self, starts, h, t_end, n_impacts, t0, progress, sensitivities: bool = False
    ) -> list[Result | SolverError]:
        """One ``simulate`` per run, after one another, each failed run's ``SolverError`` in its place."""
        out: list[Result | SolverError] = []
        with Progress(len(starts), f"simulate_many {self.model.name}", enabled=progress) as bar:
            for i, st in enumerate(starts):
                try:
                    out.append(
                        self.simulate(st.q0, st.v0, h, t_end, n_impacts, st.params, t0, False, sensitivities)
                    )
                except SolverError as err:
                    out.append(err)
                bar.update(i + 1)
        return out

    def _finish(self, res: Result, mu_f: list[float], par: list[float]) -> None:
        """What ``simulate`` adds to a run: the work (``vcigen.work``), names, the Legendre inverse."""
        res.contact_names = self.system.contact_names
        res.friction_work = friction_work(res, self._friction, mu_f, par)
        res.work = step_work(res, self._work, par) + res.friction_work
        res.energy_at_end = bool(self.model.force)
        res.coordinate_names = list(self._coordinate_names)
        res.velocity_of = partial(self._velocity, par=par)

    def _finish_many(self, results: list[Result], pars: list[list[float]], mu_fs: list[list[float]]) -> None:
        """:meth:`_finish` of each run of ``simulate_many``; without forces or friction (work 0) the zero
        work arrays of runs of one length are rows of one block."""
        if self._work is not None or self._friction is not None:
            for res, par, mu_f in zip(results, pars, mu_fs):
                self._finish(res, mu_f, par)
            return
        lengths = [res.energy.size for res in results]
        zeros = {s: np.zeros((2, lengths.count(s), s)) for s in set(lengths)}
        used = dict.fromkeys(zeros, 0)
        coords, contacts, at_end = self._coordinate_names, self.system.contact_names, bool(self.model.force)
        velocity, inverses = self._velocity, {}  # one Legendre inverse per parameter vector
        for res, par, s in zip(results, pars, lengths):
            k = used[s]
            used[s] = k + 1
            d = res.__dict__
            d["friction_work"], d["work"] = zeros[s][0, k], zeros[s][1, k]
            d["energy_at_end"], d["coordinate_names"], d["contact_names"] = at_end, list(coords), contacts
            if id(par) not in inverses:
                inverses[id(par)] = partial(velocity, par=par)
            d["velocity_of"] = inverses[id(par)]

    def _velocity(self, q: np.ndarray, p: np.ndarray, par: list[float]) -> np.ndarray:
        if self._inverse is None:
            self._inverse = LegendreInverse(self.system)
        return self._inverse(q, p, par)

    def _parameters(
        self, params: Mapping[object, float] | None, t0: float = 0.0
    ) -> tuple[list[float], list[float]]:
        """The parameter vector of the kernels at ``params`` (checked) and each contact's ``mu_f``."""
        if params is None and self._defaults is not None:
            par, mu_f = self._defaults
        else:
            par = self.model.resolve_params(params)
            self.model.restitution_values(par)  # each in [0, 1] at these parameters, or a ValueError
            mu_f = self.model.friction_values(par)  # each >= 0, or a ValueError
            # the slots the stepper sets: friction in sustained contact (0 at the start), then the time a
            # segment starts at (Kernels.at), last
            slots = len(self.system.params) - len(par) - self.system.timed
            par = par + [0.0] * slots
            if params is None:
                self._defaults = par, mu_f
        return (par + [float(t0)] if self.system.timed else par), mu_f

    def _run(self, kern, q0, v0, p0, h, t_end, n_impacts, t0, progress) -> Result:
        return Stepper(kern, self.tol).simulate(
            q0, v0, h, t_end=t_end, n_impacts=n_impacts, t0=t0, progress=progress
        )

    def _run_sensitive(self, kern, q0, v0, p0, h, t_end, n_impacts, t0, progress) -> Result:
        """:meth:`_run` with the tangent (:mod:`vcigen.sensitivity`): the Python stepper on these kernels
        (a backend with its own tangent propagation overrides this)."""
        if self._tangents is None:
            from .sensitivity import Tangents  # CasADi Functions of the d_* routines, made on first use

            self._tangents = Tangents(self.system)
        from .sensitivity import Tracker

        return Stepper(kern, self.tol, tangent=Tracker(self._tangents, kern)).simulate(
            q0, v0, h, t_end=t_end, n_impacts=n_impacts, t0=t0, progress=progress
        )

    # -- validation ------------------------------------------------------------------
    def _start_vectors(self, q0, v0) -> tuple[np.ndarray, np.ndarray]:
        n = self.model.n
        return _vector("q0", q0, n), _vector("v0", v0, n)

    def _validate(self, h, t_end, n_impacts, t0) -> float:
        """``h`` as a float, once ``h``, ``t_end``, ``n_impacts`` and ``t0`` are checked."""
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
        return h

    def _many_starts(self, q0s, v0s, params) -> tuple[np.ndarray, np.ndarray, list[Mapping | None]]:
        """``q0s, v0s`` as ``(K, n)`` arrays and each run's ``params`` (shapes checked; the rest per run)."""
        n = self.model.n
        q = _matrix("q0s", q0s, n)
        v = _matrix("v0s", v0s, n)
        if q.shape[0] != v.shape[0]:
            raise ValueError(f"q0s has {q.shape[0]} runs but v0s has {v.shape[0]}")
        if params is None or isinstance(params, Mapping):
            per_run = [params] * q.shape[0]
        else:
            per_run = list(params)
            if len(per_run) != q.shape[0]:
                raise ValueError(f"params has {len(per_run)} entries but there are {q.shape[0]} runs")
        return q, v, per_run

    def _check_start(self, kern, q0, v0) -> np.ndarray:
        """A ``ValueError`` if ``(q0, v0)`` is no admissible start; else ``p0 = dL/dqdot(q0, v0)``."""
        phi, _ = kern.contacts(q0)
        for name, val in zip(self.system.contact_names, phi):
            if not val >= -self.tol.admissible:
                raise ValueError(
                    f"q0 violates contact '{name}' (phi = {val:.6g} < 0); start inside the admissible set"
                )
        if kern.r and self._constraint_names:
            psi, grad, _ = kern.rows(q0, v0)
            for r in range(kern.r):
                i = kern.row_constraint[r]
                if i < 0:
                    continue
                name = self._constraint_names[i]
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
        p0, mass = kern.legendre(q0, v0)
        cond = _condition(mass)
        if not cond <= MAX_CONDITION:
            raise ValueError(
                f"d2L/dqdot2 is singular or not finite at (q0, v0) (cond = {cond:.3g}); "
                "the Lagrangian must be regular where the model is used"
            )
        return p0


def _finite(name: str, x: object) -> float:
    try:
        val = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    if not math.isfinite(val):
        raise ValueError(f"{name} = {val} is not finite")
    return val


def _condition(mass: np.ndarray) -> float:
    """The 2-norm condition number of the symmetric ``mass`` (inf if singular or not finite): ``|lambda|``
    largest over smallest, in closed form for ``n <= 2`` (the start of every run pays for it)."""
    n = mass.shape[0]
    if n == 1:
        a = abs(float(mass[0, 0]))
        return 1.0 if 0.0 < a < math.inf else math.inf
    if n == 2:
        a, b, d = float(mass[0, 0]), 0.5 * float(mass[0, 1] + mass[1, 0]), float(mass[1, 1])
        mid, rad = 0.5 * (a + d), math.hypot(0.5 * (a - d), b)
        lo, hi = sorted((abs(mid - rad), abs(mid + rad)))
        return hi / lo if lo > 0.0 and math.isfinite(hi) else math.inf
    if not np.isfinite(mass).all():
        return math.inf
    lam = np.abs(np.linalg.eigvalsh(0.5 * (mass + mass.T)))
    return float(lam.max() / lam.min()) if lam.min() > 0 else math.inf


def conditions(mass: np.ndarray) -> np.ndarray:
    """:func:`_condition` of each of ``K`` matrices ``(K, n, n)``, vectorised (the same formulas; the
    scalar function has the last word where this one is near the bound: ``simulate_many``'s starts)."""
    k, n = mass.shape[0], mass.shape[1]
    out = np.full(k, np.inf)
    with np.errstate(all="ignore"):
        if n == 1:
            a = np.abs(mass[:, 0, 0])
            out[(a > 0.0) & (a < np.inf)] = 1.0
        elif n == 2:
            a, b, d = mass[:, 0, 0], 0.5 * (mass[:, 0, 1] + mass[:, 1, 0]), mass[:, 1, 1]
            mid, rad = 0.5 * (a + d), np.hypot(0.5 * (a - d), b)
            lo = np.minimum(np.abs(mid - rad), np.abs(mid + rad))
            hi = np.maximum(np.abs(mid - rad), np.abs(mid + rad))
            ok = (lo > 0.0) & np.isfinite(hi)
            out[ok] = hi[ok] / lo[ok]
        else:
            fin = np.isfinite(mass).all(axis=(1, 2))
            lam = np.abs(np.linalg.eigvalsh(0.5 * (mass[fin] + mass[fin].transpose(0, 2, 1))))
            lo, hi = lam.min(axis=1), lam.max(axis=1)
            out[np.flatnonzero(fin)[lo > 0]] = (hi / lo)[lo > 0]
    return out


def _matrix(name: str, x, n: int) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of shape (K, {n}), got {x!r}") from None
    if arr.ndim != 2 or arr.shape[1] != n:
        raise ValueError(f"{name} has shape {arr.shape}; it must be (K, {n}), one row per run")
    bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if bad.size:
        raise ValueError(f"{name}[{bad[0]}] = {arr[bad[0]].tolist()} contains a non-finite number")
    return arr


def _many_outcome(out: list[Result | SolverError], errors: str) -> list[Result | SolverError]:
    """``simulate_many``'s list, or its first failed run's error raised (``errors="raise"``)."""
    for i, r in enumerate(out):
        if isinstance(r, SolverError):
            r.run = i  # type: ignore[attr-defined]
            if errors == "raise":
                r.args = (f"run {i}: {r.args[0]}",)
                r.results = out  # type: ignore[attr-defined]
                raise r
    return out


def _vector(name: str, x: Sequence[float], n: int) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a sequence of {n} numbers, got {x!r}") from None
    if arr.size != n:
        raise ValueError(f"{name} has {arr.size} entries but the model has {n} coordinates")
    if not all(map(math.isfinite, arr.tolist())):
        raise ValueError(f"{name} = {arr.tolist()} contains a non-finite number")
    return arr


def build(
    model: Model,
    backend: Backend = "casadi",
    rule: str | Rule = "trapezoid",
    tol: Tolerances | None = None,
    **options,
) -> Simulator:
    """Derive ``model`` under ``rule`` and compile it for ``backend`` (``vcigen.backends.registry``)."""
    if not isinstance(model, Model):
        raise ValueError(f"build() needs a vcigen.Model, got {type(model).__name__}")
    make = registry.factory(backend)  # a ValueError listing the backends, before any work
    return make(derive(model, rule), tol=tol or Tolerances(), **options)
