"""What a simulation returns: the grid trajectory and the impact log."""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .impacts import KINDS, Impact, Impacts, ImpactTable

__all__ = ["BREAK_REASONS", "KINDS", "Impact", "ImpactTable", "Impacts", "Result", "ordered_breaks"]

# Why a grid step has no tangent (Result.sensitivity_breaks' reasons; vcigen.sensitivity), each with its C
# macro <MODEL>_WHY_<macro> (the bits of the C variant's per-step W, in this order). Both backends list a
# step's reasons once each, in this order (ordered_breaks).
BREAK_REASONS: tuple[tuple[str, str], ...] = (
    ("HELD_STEP", "held step (sustained contact)"),
    ("SINGULAR_HELD", "a singular Jacobian in the tangent of held"),
    ("SINGULAR_LIFTOFF", "a singular Jacobian in the tangent of liftoff"),
    ("SINGULAR_EVENT", "a singular Jacobian in the tangent of event"),
    ("SIMULTANEOUS_IMPACT", "simultaneous impact"),
    ("SINGULAR_CONTACT", "a singular Jacobian in the tangent of contact"),
    ("FRICTION_AT_AN_IMPACT", "friction at an impact"),
    ("PLASTIC_IMPACT", "plastic impact"),
    ("SINGULAR_PLASTIC", "a singular Jacobian in the tangent of plastic"),
    ("GRAZING_IMPACT", "grazing impact"),
    ("SINGULAR_JUMP", "a singular Jacobian in the tangent of jump"),
    ("RESTART", "restart (continuous law where (78) has no root)"),
    ("SINGULAR_JUMP_END", "a singular Jacobian in the tangent of jump_end"),
    ("A_PHASE_WITHOUT_A_TANGENT", "a phase without a tangent"),
    ("NONFINITE_TANGENT", "a non-finite tangent (singular Jacobian)"),
    ("FRICTION_SWITCH", "friction switch in a held step"),
    ("LOAD_PASSED", "load passed to a riding row"),
    ("ONTO_ROWS", "start moved onto the held rows"),
    ("HALVED", "held segment halved"),
    ("PROJECTED", "held rows projected at an event's start"),
    ("PRESSED_LIFT", "lift-off while a stick rides"),
    ("MET_BACK", "a lift-off met again moving away"),
    ("SINKS_FREE", "a lift-off sinking at once"),
)
_BREAK_ORDER = {why: i for i, (_, why) in enumerate(BREAK_REASONS)}


def ordered_breaks(breaks) -> list[tuple[int, str]]:
    """``(step, reason)`` pairs once each, by step, a step's reasons in :data:`BREAK_REASONS`' order (the C
    variant's bits; the Python tracker meets them in the stepper's order, some several times a step)."""
    return sorted(set(breaks), key=lambda b: (b[0], _BREAK_ORDER.get(b[1], len(_BREAK_ORDER)), b[1]))


@dataclass
class Result:
    """Grid trajectory ``t_k = t0 + k h`` with momenta, energies and impacts."""

    t: np.ndarray
    q: np.ndarray
    p: np.ndarray
    energy: np.ndarray
    impacts: Sequence[Impact]  # a list (Python stepper) or Impacts, made from impact_table on access (C)
    coordinate_names: list[str]
    h: float
    stats: dict[str, float] = field(default_factory=dict)
    active: np.ndarray | None = None  # (N, m) bool: contact j in sustained contact at grid point k
    contact_force: np.ndarray | None = None  # (N-1, m): mean multiplier lambda_j >= 0 over each grid step
    constraint_force: np.ndarray | None = None  # (N-1, n_constraints): the bilateral multipliers
    liftoffs: list[tuple[float, str]] = field(default_factory=list)  # (t, contact) per release
    work: np.ndarray | None = None  # (N-1,): discrete work of the forces over each grid step (vcigen.work)
    friction_work: np.ndarray | None = None  # (N-1,): the part of work done by friction in sustained contact
    energy_at_end: bool = False  # energy[k] is the energy at the end of step k (forces), else E_d entering it
    contact_names: tuple[str, ...] = ()  # the model's contacts (ImpactTable.contact indexes them)
    # simulate(..., sensitivities=True) (vcigen.sensitivity): (N, 2n, 2n + P) d(q_k, p_k)/d(q0, v0, params),
    # the names of its columns, and (step, reason) of each step no tangent goes through (NaN from the first)
    sensitivity: np.ndarray | None = field(default=None, repr=False, compare=False)
    sensitivity_names: list[str] = field(default_factory=list, repr=False, compare=False)
    sensitivity_breaks: list[tuple[int, str]] = field(default_factory=list, repr=False, compare=False)
    # (q (N, n), p (N, n)) -> (N, n): the continuous Legendre transform inverted (Result.v); set by simulate
    velocity_of: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = field(
        default=None, repr=False, compare=False
    )
    _table: ImpactTable | None = field(default=None, init=False, repr=False, compare=False)
    _v: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def n_impacts(self) -> int:
        return len(self.impacts)

    @property
    def impact_table(self) -> ImpactTable:
        """The impact log as arrays (:class:`~vcigen.impacts.ImpactTable`), one entry per impact."""
        if isinstance(self.impacts, Impacts):
            return self.impacts.table
        if self._table is None or len(self._table) != len(self.impacts):
            names = self.contact_names or tuple(dict.fromkeys(im.contact for im in self.impacts))
            self._table = ImpactTable.from_impacts(self.impacts, names, self.q.shape[1])
        return self._table

    @property
    def v(self) -> np.ndarray:
        """``(N, n)``: the velocity of each grid momentum, ``dL/dqdot(q_k, v_k) = p_k`` solved for ``v_k``
        (the continuous Legendre transform inverted at ``(q_k, p_k)``; ``vcigen.velocity``)."""
        if self._v is None:
            if self.velocity_of is None:
                raise ValueError(
                    "this Result does not know its model's Legendre transform (not from simulate)"
                )
            self._v = self.velocity_of(self.q, self.p)
        return self._v

    def __getstate__(self) -> dict:
        """For pickling (``vcigen.sweep``): ``v`` computed, the model's Legendre inverse left behind."""
        if self.velocity_of is not None and self._v is None:
            self._v = self.velocity_of(self.q, self.p)
        return {**self.__dict__, "velocity_of": None}

    def max_energy_deviation(self) -> float:
        """``max |E_k - E_0| / |E_0|`` over the run (absolute if ``E_0 == 0``)."""
        if self.energy.size == 0:
            return 0.0
        e0 = self.energy[0]
        scale = abs(e0) if e0 != 0 else 1.0
        return float(np.max(np.abs(self.energy - e0)) / scale)

    def energy_balance(self) -> np.ndarray:
        """``(N-1,)``: ``E_k - E_0 - sum_{i=1..k} W_i + (restitution and plastic losses up to step k)``.

        Zero but for the method's own bounded O(h^2) energy error, with or without forces (MATH.md,
        *Forcing*): with forces ``energy`` is the energy at the end of each step and ``work`` the work
        over it.
        """
        e = self.energy
        if e.size == 0:
            return e.copy()
        work = np.zeros(e.size) if self.work is None else np.asarray(self.work, dtype=float)
        fric = np.zeros(e.size) if self.friction_work is None else np.asarray(self.friction_work, dtype=float)
        work = work - fric  # the forces' part: booked per step; friction in sustained contact: per middle
        lost = np.zeros(e.size)
        shift = 0 if self.energy_at_end else 1  # without forces an impact step reports E_d before its impacts
        tab = self.impact_table
        at = tab.step + shift
        inside = at < e.size
        np.add.at(lost, at[inside], (tab.energy_before - tab.energy_after)[inside])
        if self.energy_at_end:  # forces: E_k is the energy at the end of step k
            acc = np.cumsum(work) - work[0]
        else:  # E_d of a step is its energy half-way: the work between the middles of the steps
            acc = _mid_sum(work)
        acc = acc + _mid_sum(fric)  # RATTLE's E_d does not hold friction's half step: middle to middle
        return e - e[0] - acc + np.cumsum(lost) - lost[0]

    def to_csv(self, path: str | Path) -> Path:
        """Write ``t, q..., p..., energy`` per grid point (energy of the step that starts there)."""
        path = Path(path)
        names = self.coordinate_names
        header = ["t", *names, *(f"p_{c}" for c in names), "energy"]
        energy = np.append(self.energy, np.nan)
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            for k in range(self.t.size):
                w.writerow(
                    [
                        repr(float(self.t[k])),
                        *map(repr, self.q[k].tolist()),
                        *map(repr, self.p[k].tolist()),
                        repr(float(energy[k])),
                    ]
                )
        return path

    def impacts_to_csv(self, path: str | Path) -> Path:
        """Write the impact log: ``t, contact, step, alpha, impulse, E_before, E_after, q..., kind``."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(
                [
                    "t",
                    "contact",
                    "step",
                    "alpha",
                    "impulse",
                    "energy_before",
                    "energy_after",
                    *self.coordinate_names,
                    "kind",
                ]
            )
            for im in self.impacts:
                w.writerow(
                    [
                        repr(im.t),
                        im.contact,
                        im.step,
                        repr(im.alpha),
                        repr(im.impulse),
                        repr(im.energy_before),
                        repr(im.energy_after),
                        *map(repr, im.q.tolist()),
                        im.kind,
                    ]
                )
        return path


def _mid_sum(work: np.ndarray) -> np.ndarray:
    """``sum_{i=1..k} (W_{i-1} + W_i) / 2``: the work from the middle of step 0 to the middle of step k."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (work[:-1] + work[1:]))])
