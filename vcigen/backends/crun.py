"""Runs of the generated C loop from Python: one :class:`CRun` per run holds its buffers, and
:func:`run_jobs` hands any number of them to ``<model>_run_many`` in one call.

A run's buffers (grid rows, impact records, lift-offs) grow geometrically: when ``<model>_run``
stops because one might overflow (a run of unknown length, ``n_impacts``, or many impacts), the
buffer doubles and the run resumes from ``(q, p, v)`` and its sustain state, which gives the same
trajectory as one call (the loop keeps no other state between steps). The impact log stays in the
C records and becomes a :class:`~vcigen.impacts.ImpactTable` at the end: no object per impact.

``simulate``'s grid buffers of 256 KB or more come from a :class:`Block` of the simulator's pool, lent
until the result's arrays are gone (no page faults per call); ``simulate_many`` makes a batch of runs
at once (:func:`batch_runs`, :func:`batch_results`): one allocation per buffer for the batch.
"""

from __future__ import annotations

import ctypes
import weakref
from dataclasses import MISSING, fields
from typing import Any

import numpy as np

from ..errors import PHASES, SolverError
from ..impacts import KINDS, RECORD_HEAD, Impacts
from ..result import Result
from ..stepper import done_fraction

MAX_STEPS = 50_000_000
# A run of unknown length (n_impacts) reserves this many bytes per grid buffer: address space, not
# memory (pages are touched only as the run writes them; the result's arrays are views of the rows
# written); past it, buffers double.
RESERVE_BYTES = 1 << 22
# The grid buffers of a simulate call needing at least this many bytes come from a Block of the
# simulator's pool (reused once its last result is gone; see Block), at most POOL_BLOCKS kept idle.
BLOCK_MIN_BYTES = 1 << 18
POOL_BLOCKS = 2
FIRST_CAP_MANY = 1024  # grid rows each run of simulate_many starts with (doubled as needed)
FIRST_RECORDS_MANY = 16  # impact records and lift-offs of each run of simulate_many beyond one step's room
FIRST_RECORDS = 256  # impact records and lift-offs beyond the room one step needs, doubled as needed


class Job(ctypes.Structure):
    """``<model>_job_t`` (model.h.j2): every field 8 bytes wide."""

    _fields_ = [
        *((name, ctypes.c_void_p) for name in ("par", "q", "p", "v", "Q", "P", "E", "A", "F", "FC")),
        *((name, ctypes.c_void_p) for name in ("impacts", "liftoffs", "sus", "err", "A0")),
        *(
            (name, ctypes.c_long)
            for name in (
                "fresh",
                "step0",
                "n_steps",
                "max_impacts",
                "impact_cap",
                "liftoff_cap",
                "steps_done",
                "impacts_done",
                "liftoffs_done",
                "rc",
            )
        ),
    ]


def _addr(a: np.ndarray) -> int:
    """The address of ``a``'s data (0 for an empty array, which C never reads); quicker than ``a.ctypes``."""
    return ctypes.addressof(ctypes.c_char.from_buffer(a)) if a.nbytes else 0


def _resize(a: np.ndarray, rows: int) -> np.ndarray:
    """``a`` (a buffer nobody else holds) with ``rows`` rows, in place where the allocator can (``realloc``:
    a large block is remapped, not copied); new rows are zero."""
    a.resize((rows, *a.shape[1:]), refcheck=False)
    return a


class _Lease:
    """The owner, as NumPy sees it, of the arrays a :class:`Block` lends one run: when the last of them
    (the result's ``q``, ``p``, ...) is gone, its finalizer puts the block back into the pool."""

    __slots__ = ("__array_interface__", "__weakref__", "raw")


class Block:
    """One allocation for the six grid buffers of a run (``Q, P, A``: ``cap + 1`` rows; ``E, F, FC``:
    ``cap``), kept in a simulator's pool and lent to one run at a time.

    Why: fresh buffers of a few MB fault their pages in on every call (~1 000 minor faults, ~2 us per
    impact on the particle's 1000-impact run), unless the C library's allocator happens to recycle
    them (it did for exactly sized buffers of ``t_end`` runs, not for a run of unknown length's
    reservation). A block's pages are touched once; it returns to the pool only when every array of
    the result it was lent to is gone (:class:`_Lease`), so no result's arrays alias a later run's.
    ``A, F, FC`` must read 0 where the C loop writes nothing (the glide): the rows a run may have
    written (``high``) are zeroed before the block is lent again.
    """

    def __init__(self, kern: Any, cap: int) -> None:
        self.cap, self.high = cap, 0
        self.layout, size = _layout(kern, cap)
        self.raw = np.zeros(size, dtype=np.uint8)
        self._own = self._carve(self.raw)  # views of raw itself: for clean()

    @staticmethod
    def nbytes(kern: Any, cap: int) -> int:
        """About the bytes of a block of ``cap`` rows (without the alignment; cheap: every call asks)."""
        n, m = kern.n, kern.m
        return 8 * (2 * (cap + 1) * n + cap * (1 + m + kern.nc)) + (cap + 1) * m

    def _carve(self, raw: np.ndarray) -> list[np.ndarray]:
        return [raw[at : at + size].view(dtype).reshape(shape) for at, size, dtype, shape in self.layout]

    def lend(self, pool: list[Block]) -> list[np.ndarray]:
        """``Q, P, E, A, F, FC``, whose owner returns this block to ``pool`` when they are all gone."""
        lease = _Lease()
        lease.raw = self.raw
        lease.__array_interface__ = {
            "shape": self.raw.shape, "typestr": "|u1", "data": (self.raw.ctypes.data, False), "version": 3,
        }  # fmt: skip
        weakref.finalize(lease, _give_back, pool, self).atexit = False
        return self._carve(np.asarray(lease))

    def clean(self) -> None:
        """Zero the rows of ``A, F, FC`` the last run may have written."""
        high = self.high
        _, _, _, a, f, fc = self._own
        a[: high + 1] = False
        f[:high] = 0.0
        fc[:high] = 0.0
        self.high = 0


def _layout(kern: Any, cap: int) -> tuple[list[tuple[int, int, Any, tuple[int, ...]]], int]:
    """``(offset, bytes, dtype, shape)`` of ``Q, P, E, A, F, FC`` in a block of ``cap`` rows, and its size."""
    n, m, nc = kern.n, kern.m, kern.nc
    out, at = [], 0
    for dtype, shape in (
        (np.float64, (cap + 1, n)),
        (np.float64, (cap + 1, n)),
        (np.float64, (cap,)),
        (np.bool_, (cap + 1, m)),
        (np.float64, (cap, m)),
        (np.float64, (cap, nc)),
    ):
        size = int(np.prod(shape)) * np.dtype(dtype).itemsize
        out.append((at, size, dtype, shape))
        at += -(-size // 64) * 64  # each buffer 64-byte aligned
    return out, max(at, 64)


def _give_back(pool: list[Block], block: Block) -> None:
    if len(pool) < POOL_BLOCKS:
        pool.append(block)


def _take(pool: list[Block], kern: Any, cap: int) -> Block:
    """A block of at least ``cap`` rows from ``pool`` (at most 4x that, not to pin much more than the run
    needs), cleaned; or a new one."""
    for block in list(pool):
        if cap <= block.cap <= 4 * cap:
            try:
                pool.remove(block)
            except ValueError:  # another thread took it meanwhile
                continue
            block.clean()
            return block
    return Block(kern, cap)


class CRun:
    """One run of ``<model>_run``: its state, buffers and counts, and its :class:`Job`."""

    JOB: type[Job] = Job  # the job struct of the library (the sensitivity variant's has more fields: csens)

    def __init__(
        self,
        kern: Any,
        par: np.ndarray,
        q0: np.ndarray,
        v0: np.ndarray,
        p0: np.ndarray,
        steps: int,
        n_impacts: int | None,
        rooms: tuple[int, int],
        par_at: int = 0,
        first_cap: int | None = None,
        pool: list[Block] | None = None,
    ) -> None:
        """``par_at``: the address of ``par`` when the caller has it (runs sharing one parameter vector);
        ``first_cap``: the grid rows a run of unknown length starts with (default: ``RESERVE_BYTES``);
        ``pool``: the simulator's :class:`Block` pool, for buffers of ``BLOCK_MIN_BYTES`` or more."""
        n, m = kern.n, kern.m
        self.kern, self.steps, self.n_impacts = kern, steps, n_impacts
        self.rec_room, self.lift_room = rooms  # the records one step may write (run stops short of it)
        self.par = par
        state = np.concatenate((q0, p0, v0))  # q, p, v: in/out of every call
        self.q, self.p, self.v = state[:n], state[n : 2 * n], state[2 * n :]
        if first_cap is None:
            first_cap = RESERVE_BYTES // (8 * max(n, m, kern.nc, 1))
        cap = steps if n_impacts is None else min(steps, first_cap)
        self.cap = cap
        self.block = None
        if pool is not None and Block.nbytes(kern, cap) >= BLOCK_MIN_BYTES:
            self.block = _take(pool, kern, cap)
            self.Q, self.P, self.E, self.A, self.F, self.FC = self.block.lend(pool)
        else:
            self.Q, self.P, self.E = np.empty((cap + 1, n)), np.empty((cap + 1, n)), np.empty(cap)
            self.A = np.zeros((cap + 1, m), dtype=np.bool_)  # rows the glide skips stay 0: nothing held
            self.F, self.FC = np.zeros((cap, m)), np.zeros((cap, kern.nc))
        self.Q[0], self.P[0] = q0, p0
        self.rec = self.lift = None  # given by lend() or made by arm(), when the run first needs them
        self.sus, self.err = kern.Sustain(), kern.Error()
        self.done = self.n_rec = self.n_lift = self.reflected = 0
        self.rc = 0
        self.started = False
        self.finished = steps == 0 or n_impacts == 0
        job = self.job = self.JOB()
        at = _addr(state)
        job.par, job.q, job.p, job.v = par_at or _addr(par), at, at + 8 * n, at + 16 * n
        job.sus, job.err = ctypes.addressof(self.sus), ctypes.addressof(self.err)
        self._rows()
        job.A0, job.fresh = self._aA, 1
        self.armed = False

    def _rows(self) -> None:
        """The addresses of the grid buffers (after they are (re)allocated)."""
        self._aQ, self._aP, self._aE = _addr(self.Q), _addr(self.P), _addr(self.E)
        self._aA, self._aF, self._aFC = _addr(self.A), _addr(self.F), _addr(self.FC)

    def arm(self, chunk: int) -> Job:
        """Point the job at the next ``chunk`` steps (at most), growing any buffer that lacks room."""
        if self.armed:  # batch_runs armed it for its first call (with chunk MAX_STEPS)
            self.armed = False
            if chunk == MAX_STEPS:
                return self.job
        if self._aQ is None:
            self._rows()
        n, m, nc = self.kern.n, self.kern.m, self.kern.nc
        if self.done >= self.cap:
            self.cap = cap = min(2 * self.cap, self.steps)
            for name, rows in (
                ("Q", cap + 1),
                ("P", cap + 1),
                ("E", cap),
                ("A", cap + 1),
                ("F", cap),
                ("FC", cap),
            ):
                setattr(self, name, _grown(getattr(self, name), rows))
            self.block = None  # a block's arrays were copied: it goes back to the pool
            self._rows()
        if self.rec is None:
            self.lend(np.empty((self.rec_room + FIRST_RECORDS, RECORD_HEAD + 1 + n)),
                      np.empty((self.lift_room + FIRST_RECORDS, 2)))  # fmt: skip
        if self.rec.shape[0] - self.n_rec <= self.rec_room:
            self.rec = _doubled(self.rec)
        if self.lift.shape[0] - self.n_lift <= self.lift_room:
            self.lift = _doubled(self.lift)
        d, job = self.done, self.job
        job.Q, job.P, job.E = self._aQ + 8 * n * (d + 1), self._aP + 8 * n * (d + 1), self._aE + 8 * d
        job.A, job.F, job.FC = self._aA + m * (d + 1), self._aF + 8 * m * d, self._aFC + 8 * nc * d
        job.impacts = _addr(self.rec) + 8 * self.rec.shape[1] * self.n_rec
        job.impact_cap = self.rec.shape[0] - self.n_rec
        job.liftoffs, job.liftoff_cap = _addr(self.lift) + 16 * self.n_lift, self.lift.shape[0] - self.n_lift
        job.step0, job.n_steps = d, min(chunk, self.cap - d, self.steps - d)
        if self.block is not None:  # the rows of A, F, FC the call may write (collect() narrows it)
            self._high = self.block.high
            self.block.high = max(self._high, d + job.n_steps)
        job.max_impacts = -1 if self.n_impacts is None else self.n_impacts - self.n_rec
        return job

    def lend(self, rec: np.ndarray, lift: np.ndarray) -> None:
        """Give the run its impact-record and lift-off buffers (views of a batch's block, or its own)."""
        self.rec, self.lift = rec, lift

    def collect(self) -> None:
        """Take in what the last call did; ``finished`` when the run is over (or failed: ``rc``)."""
        job = self.job
        fresh = self.started is False
        self.started = True  # run_many cleared job.fresh: the start is done once
        self.done += job.steps_done
        self.n_rec += job.impacts_done
        self.n_lift += job.liftoffs_done
        self.reflected += self.err.reflected
        self.rc = job.rc
        if self.block is not None and not job.rc:  # a run that went well wrote no row past its steps
            self.block.high = max(self._high, self.done)
        full = self.n_impacts is not None and self.n_rec >= self.n_impacts
        stuck = job.steps_done == 0 and job.n_steps > 0 and not fresh  # no room was lacking: nothing to do
        self.finished = bool(self.rc) or self.done >= self.steps or full or stuck

    def fraction(self) -> float:
        """How much of the run is done (steps, or impacts of ``n_impacts``)."""
        return done_fraction(self.done, self.steps, MAX_STEPS, self.n_rec, self.n_impacts)

    def result(self, t0: float, h: float, wall: float) -> Result:
        """The :class:`Result` of the steps done; its arrays are the buffers, cut to size."""
        kern, s = self.kern, self.done
        names = kern.contact_names
        if self.rec is None:  # never ran (no step to take)
            self.lend(np.empty((0, RECORD_HEAD + 1 + kern.n)), np.empty((0, 2)))
        if self.rc:
            keep = self.rec[: self.n_rec, 2] < s  # the run up to the last completed step
            rec = self.rec[: self.n_rec][keep]
            lifts = self.lift[: self.n_lift]
            lifts = lifts[lifts[:, 0] < t0 + s * h]
        else:
            rec = self.rec[: self.n_rec].copy() if self.n_rec else self.rec[:0]
            lifts = self.lift[: self.n_lift]
        t = np.arange(s + 1, dtype=float)
        t *= h
        t += t0  # t0 + h k, as the Python stepper's grid
        res = Result(
            t,
            _cut(self.Q, s + 1),
            _cut(self.P, s + 1),
            _cut(self.E, s),
            Impacts(records=rec, names=names),
            kern.coordinate_names,
            h,
            {},
            active=_cut(self.A, s + 1),
            contact_force=_cut(self.F, s),
            constraint_force=_cut(self.FC, s),
            liftoffs=[(float(t), names[int(j)]) for t, j in lifts.tolist()] if len(lifts) else [],
        )
        # the result owns the grid buffers; the records are copied: let them all go with this run
        self.Q = self.P = self.E = self.A = self.F = self.FC = self.rec = self.lift = None  # type: ignore[assignment]
        res.stats = self.stats(s, wall, len(res.liftoffs))
        return res

    def stats(self, s: int, wall: float, liftoffs: int) -> dict[str, float]:
        """``Result.stats`` of the run (``s`` steps done)."""
        stats = {"wall_time": wall, "steps": s, "seconds_per_step": wall / max(s, 1)}
        stats["grazing_reflected"] = self.reflected
        stats.update(zip(_KIND_KEYS, self.sus.kinds))
        stats["liftoffs"] = liftoffs
        stats["jump_fallbacks"] = self.sus.fallbacks
        stats["landing_friction_dropped"] = self.sus.friction_dropped
        stats["restitution_reduced"] = self.sus.restitution_reduced
        stats["least_splits"] = self.sus.least_splits
        stats["loads_passed"] = self.sus.passes
        stats["sticks_kept"] = self.sus.sticks_kept
        stats["lifts_kept"] = self.sus.lifts_kept
        stats["jams"] = self.sus.jams
        stats["halvings"] = self.sus.halvings
        stats["riders_cut"] = self.sus.riders_cut
        return stats

    def error(self, t0: float, h: float, wall: float) -> SolverError:
        """The :class:`SolverError` of a failed run, with the run up to its last completed step."""
        err = self.err
        error = SolverError(err.step, err.time, PHASES[err.phase], err.residual, err.reason.decode())
        error.result = self.result(t0, h, wall)
        return error


_KIND_KEYS = tuple(f"impacts_{kind}" for kind in KINDS)
# Result's fields with a plain default (the others are given by batch_results)
_RESULT_DEFAULTS = {f.name: f.default for f in fields(Result) if f.default is not MISSING}


def batch_results(runs: list[CRun], t0: float, h: float, wall: float) -> list[Result]:
    """The :class:`Result` of each finished run of a batch (none failed), as :meth:`CRun.result` makes
    it, cheaper: runs of the same length share one block of times (each ``t`` a row of it), and each
    result is filled without the dataclass ``__init__``."""
    kern = runs[0].kern
    names, coords = kern.contact_names, kern.coordinate_names
    empty_rec = np.empty((0, RECORD_HEAD + 1 + kern.n))
    lengths = [r.done for r in runs]
    times: dict[int, np.ndarray] = {}
    for s in set(lengths):
        t = np.arange(s + 1, dtype=float)
        t *= h
        t += t0  # t0 + h k, as the Python stepper's grid
        times[s] = np.empty((lengths.count(s), s + 1))
        times[s][:] = t
    used = dict.fromkeys(times, 0)
    out, new = [], object.__new__
    for r, s in zip(runs, lengths):
        k = used[s]
        used[s] = k + 1
        rec = r.rec[: r.n_rec].copy() if r.n_rec else empty_rec
        liftoffs = [(float(tl), names[int(j)]) for tl, j in r.lift[: r.n_lift].tolist()] if r.n_lift else []
        grid = (r.Q, r.P, r.E, r.A, r.F, r.FC)
        if r.cap != s:  # a run that stopped short of its rows (n_impacts): views of the rows written
            grid = (r.Q[: s + 1], r.P[: s + 1], r.E[:s], r.A[: s + 1], r.F[:s], r.FC[:s])
        res = new(Result)
        res.__dict__ = dict(
            _RESULT_DEFAULTS, t=times[s][k], q=grid[0], p=grid[1], energy=grid[2],
            impacts=Impacts(records=rec, names=names), coordinate_names=coords, h=h,
            stats=r.stats(s, wall, len(liftoffs)), active=grid[3], contact_force=grid[4],
            constraint_force=grid[5], liftoffs=liftoffs,
        )  # fmt: skip
        r.Q = r.P = r.E = r.A = r.F = r.FC = r.rec = r.lift = None  # type: ignore[assignment]
        out.append(res)
    return out


def _grown(a: np.ndarray, rows: int) -> np.ndarray:
    """A grid buffer with ``rows`` rows: resized in place if it owns its data, else (a :class:`Block`'s)
    a copy (new rows 0)."""
    if a.base is None:
        return _resize(a, rows)
    out = np.zeros((rows, *a.shape[1:]), dtype=a.dtype)
    out[: a.shape[0]] = a
    return out


def _doubled(a: np.ndarray) -> np.ndarray:
    """``a`` with twice the rows: in place if it owns its data, else (a view of a batch's block) a copy."""
    if a.base is None:
        return _resize(a, 2 * a.shape[0])
    out = np.empty((2 * a.shape[0], *a.shape[1:]))
    out[: a.shape[0]] = a
    return out


def _cut(a: np.ndarray, rows: int) -> np.ndarray:
    """The first ``rows`` rows of a buffer: a view, not a copy (a buffer grown by doubling wastes at most
    half its rows; shrinking it in place would copy whenever the allocator cannot shrink in place)."""
    return a if a.shape[0] == rows else a[:rows]


def batch_runs(
    kern: Any,
    state: np.ndarray,
    pars: list[tuple[np.ndarray, int]],
    steps: int,
    n_impacts: int | None,
    rooms: tuple[int, int],
    first_cap: int,
) -> list[CRun]:
    """The runs of ``simulate_many``'s batch, from ``state`` ``(B, 3n)`` (rows ``q0, p0, v0``) and each
    run's parameter vector and its address, as :class:`CRun` makes them one by one, cheaper: each buffer
    (grid rows, impact records, lift-offs) one allocation for the batch (run ``i``'s rows a view of it),
    the ``Job``, ``Sustain`` and ``Error`` structs one ctypes array each, and the jobs filled and armed
    for their first call (``arm(MAX_STEPS)``) as columns of an integer view of the ``Job`` array."""
    size, n, m, nc = state.shape[0], kern.n, kern.m, kern.nc
    cap = steps if n_impacts is None else min(steps, first_cap)
    Q, P = np.empty((size, cap + 1, n)), np.empty((size, cap + 1, n))
    Q[:, 0], P[:, 0] = state[:, :n], state[:, n : 2 * n]
    E = np.empty((size, cap))
    A = np.zeros((size, cap + 1, m), dtype=np.bool_)  # rows the glide skips stay 0: nothing held
    F, FC = np.zeros((size, cap, m)), np.zeros((size, cap, nc))
    sus, err, jobs = (kern.Sustain * size)(), (kern.Error * size)(), (Job * size)()
    finished = steps == 0 or n_impacts == 0
    width = RECORD_HEAD + 1 + n
    rec_rows, lift_rows = rooms[0] + FIRST_RECORDS_MANY, rooms[1] + FIRST_RECORDS_MANY
    rec = np.empty((size, rec_rows if not finished else 0, width))
    lift = np.empty((size, lift_rows if not finished else 0, 2))
    col = {name: k for k, (name, _) in enumerate(Job._fields_)}
    J = np.frombuffer(jobs, dtype=np.int64).reshape(size, len(Job._fields_))
    idx = np.arange(size, dtype=np.int64)

    def at(a: np.ndarray, extra: int = 0) -> np.ndarray:  # run i's address in a, plus extra bytes
        return _addr(a) + extra + a.strides[0] * idx if a.nbytes else np.zeros(size, dtype=np.int64)

    J[:, col["par"]] = [p[1] for p in pars]
    J[:, col["q"]] = at(state)
    J[:, col["p"]] = at(state, 8 * n)
    J[:, col["v"]] = at(state, 16 * n)
    J[:, col["sus"]] = ctypes.addressof(sus) + ctypes.sizeof(kern.Sustain) * idx
    J[:, col["err"]] = ctypes.addressof(err) + ctypes.sizeof(kern.Error) * idx
    J[:, col["A0"]] = at(A)
    J[:, col["fresh"]] = 1
    if not finished:  # arm(MAX_STEPS) of a run that has done nothing
        J[:, col["Q"]], J[:, col["P"]], J[:, col["E"]] = at(Q, 8 * n), at(P, 8 * n), at(E)
        J[:, col["A"]], J[:, col["F"]], J[:, col["FC"]] = at(A, m), at(F), at(FC)
        J[:, col["impacts"]], J[:, col["impact_cap"]] = at(rec), rec_rows
        J[:, col["liftoffs"]], J[:, col["liftoff_cap"]] = at(lift), lift_rows
        J[:, col["step0"]], J[:, col["n_steps"]] = 0, min(MAX_STEPS, cap, steps)
        J[:, col["max_impacts"]] = -1 if n_impacts is None else n_impacts
    new, runs = object.__new__, []
    base = {
        "kern": kern, "steps": steps, "n_impacts": n_impacts, "rec_room": rooms[0], "lift_room": rooms[1],
        "state": state, "cap": cap, "block": None, "done": 0, "n_rec": 0, "n_lift": 0, "reflected": 0,
        "rc": 0, "started": False, "finished": finished, "armed": not finished, "_aQ": None,
    }  # fmt: skip
    for i in range(size):
        r = new(CRun)
        d = r.__dict__
        d.update(base)
        d.update(
            par=pars[i][0], Q=Q[i], P=P[i], E=E[i], A=A[i], F=F[i], FC=FC[i], rec=rec[i], lift=lift[i],
            sus=sus[i], err=err[i], job=jobs[i],
        )  # fmt: skip
        runs.append(r)
    return runs


def run_jobs(kern: Any, tol: Any, h: float, t0: float, runs: list[CRun], chunk: int) -> None:
    """One call of ``<model>_run_many`` over ``runs`` (each at most ``chunk`` steps further)."""
    jobs = (ctypes.c_void_p * len(runs))(*(ctypes.addressof(r.arm(chunk)) for r in runs))
    kern.run_many(ctypes.byref(tol), h, t0, len(runs), jobs)
    for r in runs:
        r.collect()


def chunk_steps(rate: float | None, steps_left: int, seconds: float = 0.25) -> int:
    """Steps for the next call while a progress bar is on: about ``seconds`` at the measured ``rate``
    (seconds per step), 65536 before anything is measured."""
    if rate is None or rate <= 0:
        return min(steps_left, 65536)
    return max(1024, min(steps_left, int(seconds / rate)))
