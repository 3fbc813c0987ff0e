"""The impact log: one :class:`Impact` per impact, held as arrays (:class:`ImpactTable`) and made into
objects only when asked for (:class:`Impacts`, the sequence ``Result.impacts``)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, fields
from functools import cached_property
from typing import overload

import numpy as np

KINDS = ("elastic", "restitution", "plastic", "grazing")  # Impact.kind (MATH.md, Sustained contact)
# the C stepper's impact record: t, contact, step, alpha, impulse, E_before, E_after, q (n), kind
RECORD_HEAD = 7


@dataclass(frozen=True, eq=False)
class Impact:
    """One impact: time, contact name, impact point, step fraction, impulse.

    ``alpha`` is ``(t - t_k)/h`` within the grid step ``k``; ``impulse`` is the
    multiplier ``mu >= 0`` of (76) (the paper's ``lambda`` is ``-mu``).
    ``energy_before``/``energy_after`` are ``E_d`` of the segments either side (48a):
    equal for an elastic contact, apart by the loss of (39) with restitution ``e < 1``
    (for a plastic impact, or one during sustained contact: apart by the kinetic energy lost).
    ``kind`` says which law resolved it (MATH.md, *Sustained contact*).
    """

    t: float
    contact: str
    q: np.ndarray
    alpha: float
    impulse: float
    step: int
    energy_before: float
    energy_after: float
    kind: str = "elastic"  # "elastic", "restitution", "plastic" (starts sustained contact) or "grazing"

    def __eq__(self, other: object) -> bool:
        """Every attribute equal (``q`` entry by entry)."""
        if not isinstance(other, Impact):
            return NotImplemented
        return all(
            np.array_equal(getattr(self, f.name), getattr(other, f.name))
            if f.name == "q"
            else getattr(self, f.name) == getattr(other, f.name)
            for f in fields(Impact)
        )

    __hash__ = None  # type: ignore[assignment]  # q is an array


@dataclass(frozen=True, eq=False)
class ImpactTable:
    """The impact log as arrays, one entry per impact in the order they happened.

    ``contact`` indexes ``contact_names`` and ``kind`` indexes :data:`KINDS`; the other columns are
    the attributes of :class:`Impact` of the same names (``q`` is ``(K, n)``).
    """

    t: np.ndarray
    contact: np.ndarray
    step: np.ndarray
    q: np.ndarray
    alpha: np.ndarray
    impulse: np.ndarray
    energy_before: np.ndarray
    energy_after: np.ndarray
    kind: np.ndarray
    contact_names: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.t.size)

    @classmethod
    def from_records(cls, rec: np.ndarray, names: Sequence[str]) -> ImpactTable:
        """From the C stepper's records ``(K, 8 + n)``: ``t, contact, step, alpha, impulse, E_before,
        E_after, q..., kind`` (the columns are views of ``rec``: pass a copy the table may keep)."""
        return cls(
            t=rec[:, 0],
            contact=rec[:, 1].astype(np.intp),
            step=rec[:, 2].astype(np.intp),
            q=rec[:, RECORD_HEAD:-1],
            alpha=rec[:, 3],
            impulse=rec[:, 4],
            energy_before=rec[:, 5],
            energy_after=rec[:, 6],
            kind=rec[:, -1].astype(np.intp),
            contact_names=tuple(names),
        )

    @classmethod
    def from_impacts(cls, impacts: Sequence[Impact], names: Sequence[str], n: int) -> ImpactTable:
        """From :class:`Impact` objects (the Python stepper's log)."""
        index = {c: i for i, c in enumerate(names)}
        col = {f: np.array([getattr(im, f) for im in impacts], dtype=float) for f in _FLOATS}
        return cls(
            contact=np.array([index[im.contact] for im in impacts], dtype=np.intp),
            step=np.array([im.step for im in impacts], dtype=np.intp),
            q=np.array([im.q for im in impacts], dtype=float).reshape(len(impacts), n),
            kind=np.array([KINDS.index(im.kind) for im in impacts], dtype=np.intp),
            contact_names=tuple(names),
            **col,
        )

    def impact(self, i: int) -> Impact:
        """Entry ``i`` as an :class:`Impact` (its ``q`` a copy). Filled through ``__dict__``: a frozen
        dataclass's ``__init__`` sets each field through ``object.__setattr__``, several times slower."""
        t, contact, step, alpha, impulse, e_before, e_after, kind = self._columns
        im = object.__new__(Impact)
        im.__dict__.update(
            t=t[i],
            contact=self.contact_names[contact[i]],
            q=self.q[i].copy(),
            alpha=alpha[i],
            impulse=impulse[i],
            step=step[i],
            energy_before=e_before[i],
            energy_after=e_after[i],
            kind=KINDS[kind[i]],
        )
        return im

    @cached_property
    def _columns(self) -> tuple[list, ...]:
        """The scalar columns as Python lists (made once, on the first object asked for)."""
        return tuple(
            getattr(self, c).tolist()
            for c in ("t", "contact", "step", "alpha", "impulse", "energy_before", "energy_after", "kind")
        )

    def select(self, keep: np.ndarray) -> ImpactTable:
        """The entries where ``keep`` (a mask or indices)."""
        return ImpactTable(
            **{f.name: getattr(self, f.name)[keep] for f in fields(self) if f.name != "contact_names"},
            contact_names=self.contact_names,
        )


_FLOATS = ("t", "alpha", "impulse", "energy_before", "energy_after")


class Impacts(Sequence):
    """``Result.impacts`` of a run whose log is an :class:`ImpactTable`: a read-only sequence of
    :class:`Impact`, each made from the arrays when it is read (equal, not identical, on each read)."""

    def __init__(
        self, table: ImpactTable | None = None, records: np.ndarray | None = None, names: Sequence[str] = ()
    ) -> None:
        """From a table, or from C records ``(K, 8 + n)`` (kept; the table is made when first read)."""
        if (table is None) == (records is None):
            raise ValueError("Impacts needs a table or records, not both")
        self._table, self._records, self._names = table, records, tuple(names)

    @property
    def table(self) -> ImpactTable:
        """The arrays (:class:`ImpactTable`)."""
        if self._table is None:
            self._table = ImpactTable.from_records(self._records, self._names)
            self._records = None
        return self._table

    def __len__(self) -> int:
        return len(self._table) if self._table is not None else self._records.shape[0]

    @overload
    def __getitem__(self, i: int) -> Impact: ...
    @overload
    def __getitem__(self, i: slice) -> list[Impact]: ...
    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self.table.impact(k) for k in range(*i.indices(len(self)))]
        k = int(i)
        size = len(self)
        if not -size <= k < size:
            raise IndexError(f"impact index {i} out of range ({size} impacts)")
        return self.table.impact(k % size if k < 0 else k)

    def __iter__(self) -> Iterator[Impact]:
        table = self.table
        for k in range(len(table)):
            yield table.impact(k)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Sequence) or isinstance(other, str):
            return NotImplemented
        return len(self) == len(other) and all(a == b for a, b in zip(self, other))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"Impacts({len(self)} impacts)" if len(self) > 6 else repr(list(self))
