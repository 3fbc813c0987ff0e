"""``vcigen.sweep``: many runs of one model on Dask (``dask.distributed``), shared/API.md *Many runs*.

    results = vcigen.sweep(model, [{"q0": q, "v0": v, "h": 0.005, "t_end": 20.0} for q, v in starts],
                           backend="c", reduce=lambda res: res.t[-1])

The runs are cut into batches, one Dask task per batch. A worker builds the simulator of
``(model, backend, rule, tol, options)`` the first time a task needs it (the C library comes
from the compile cache, ``~/.cache/vcigen``, when another worker or an earlier session built it)
and keeps it for every later batch; each run is then one ``sim.simulate(**run)`` on the worker,
and ``reduce(result)``, when given, runs there too, so only its value travels back. Results come
back in the order of ``runs`` and are the results a serial loop of ``simulate`` gives: the same
simulator code runs on the same input.

A run whose step cannot be solved (``SolverError``): with ``errors="raise"`` (the default) the
sweep stops, cancels what is left and raises that run's ``SolverError``, its message starting
``sweep run i:``, with ``.run = i`` and the failed run's partial result in ``.result`` (as
``simulate_many`` does); with ``errors="return"`` the ``SolverError`` takes the run's place in the
list (``.run`` and ``.result`` set; ``reduce`` is not applied to it). A run with bad input
raises ``ValueError`` naming its index (keywords that ``simulate`` does not take are caught
before anything starts); a ``reduce`` that raises gives a ``RuntimeError`` naming the run.

Dask is optional (``pip install 'vcigen[dask]'``); it is imported only when ``sweep`` runs.
"""

from __future__ import annotations

import hashlib
import inspect
import math
import os
import pickle
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, Literal

from .errors import SolverError
from .model import Model
from .progress import Progress
from .rules import RULES, Rule
from .simulator import BACKENDS, Simulator, build
from .stepper import Tolerances

OnError = Literal["raise", "return"]
ON_ERROR = ("raise", "return")
BATCHES_PER_THREAD = 8  # default batching: about this many tasks per worker thread
WORKER_CACHE = 8  # simulators kept per worker process (least recently used dropped)
SIMULATE_KEYWORDS = tuple(p for p in inspect.signature(Simulator.simulate).parameters if p != "self")


def sweep(
    model: Model,
    runs: Iterable[Mapping[str, Any]],
    backend: str = "c",
    rule: str | Rule = "trapezoid",
    client: Any = None,
    reduce: Callable[[Any], Any] | None = None,
    *,
    tol: Tolerances | None = None,
    errors: OnError = "raise",
    batch_size: int | None = None,
    workers: int | None = None,
    progress: bool = True,
    **build_options: Any,
) -> list[Any]:
    """Run ``simulate(**run)`` for every ``run`` on Dask; the results (or ``reduce`` values) in order.

    ``client``: ``None`` starts a local cluster of ``workers`` processes (default: the number of
    cores), one thread each, and closes it at the end; a ``distributed.Client`` runs the batches
    there (and stays open); a string is a scheduler address to connect to. ``batch_size`` runs
    go in one task (default: about ``BATCHES_PER_THREAD`` tasks per worker thread). ``errors``:
    what a ``SolverError`` in one run does (module docstring). ``progress`` shows a bar
    (``vcigen.progress``) for sweeps longer than ~2 s. ``tol`` and ``build_options`` go to
    ``vcigen.build`` on the workers.
    """
    if not isinstance(model, Model):
        raise ValueError(f"sweep() needs a vcigen.Model, got {type(model).__name__}")
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {list(BACKENDS)}")
    if isinstance(rule, str) and rule not in RULES:
        raise ValueError(f"unknown rule {rule!r}; choose one of {sorted(RULES)}")
    if errors not in ON_ERROR:
        raise ValueError(f"errors = {errors!r}; choose one of {list(ON_ERROR)}")
    if reduce is not None and not callable(reduce):
        raise ValueError(f"reduce must be a function of one Result, got {type(reduce).__name__}")
    if batch_size is not None and (int(batch_size) != batch_size or batch_size < 1):
        raise ValueError(f"batch_size = {batch_size!r} must be a whole number >= 1")
    todo = [_check_run(i, run) for i, run in enumerate(runs)]
    if not todo:
        return []
    distributed = _import_distributed()
    spec = SimulatorSpec(model, backend, rule, tol, build_options)
    own = None
    if client is None:
        own = client = _local_client(distributed, workers)
    elif isinstance(client, str):
        own = client = distributed.Client(client)
    elif not isinstance(client, distributed.Client):
        raise ValueError(
            f"client must be None, a distributed.Client or a scheduler address, got {type(client).__name__}"
        )
    try:
        size = batch_size or _batch_size(len(todo), _threads(client))
        return _run(distributed, client, spec, todo, int(size), reduce, errors, progress)
    finally:
        if own is not None:
            _close(own)


# -- the client side ----------------------------------------------------------------------


def _check_run(index: int, run: Mapping[str, Any]) -> dict[str, Any]:
    """``run`` as a dict of ``simulate`` keywords (``progress`` off on the worker), or a ``ValueError``."""
    if not isinstance(run, Mapping):
        raise ValueError(f"sweep run {index} is a {type(run).__name__}; give a dict of simulate() keywords")
    unknown = [k for k in run if k not in SIMULATE_KEYWORDS]
    if unknown:
        raise ValueError(
            f"sweep run {index} has keyword(s) {unknown} that simulate() does not take; "
            f"it takes {list(SIMULATE_KEYWORDS)}"
        )
    return {"progress": False, **run}


class SimulatorSpec:
    """What a worker needs to build the simulator, and a key naming it in the worker's cache."""

    def __init__(self, model: Model, backend: str, rule, tol, options: Mapping[str, Any]) -> None:
        self.model, self.backend, self.rule, self.tol = model, backend, rule, tol
        self.options = dict(options)
        blob = pickle.dumps((model, backend, rule, tol, sorted(self.options.items())))
        self.key = hashlib.sha256(blob).hexdigest()

    def build(self) -> Simulator:
        return build(self.model, backend=self.backend, rule=self.rule, tol=self.tol, **self.options)


def _import_distributed():
    try:
        import distributed
    except ImportError as exc:
        raise ImportError(
            "vcigen.sweep needs dask.distributed: pip install 'dask[distributed]' (or 'vcigen[dask]')"
        ) from exc
    return distributed


def _local_client(distributed, workers: int | None):
    """A local cluster of ``workers`` processes with one thread each, and its client."""
    n = workers if workers is not None else (os.cpu_count() or 1)
    if int(n) != n or n < 1:
        raise ValueError(f"workers = {workers!r} must be a whole number >= 1")
    cluster = distributed.LocalCluster(
        n_workers=int(n), threads_per_worker=1, processes=True, dashboard_address=None
    )
    return distributed.Client(cluster)


def _close(client) -> None:
    cluster = client.cluster
    client.close()
    if cluster is not None:
        cluster.close()


def _threads(client) -> int:
    return max(1, sum(client.nthreads().values()))


def _batch_size(n_runs: int, threads: int) -> int:
    return max(1, math.ceil(n_runs / (BATCHES_PER_THREAD * threads)))


def _run(distributed, client, spec: SimulatorSpec, todo, size: int, reduce, errors: OnError, progress: bool):
    indexed = list(enumerate(todo))
    batches = [indexed[i : i + size] for i in range(0, len(indexed), size)]
    futures = [
        client.submit(run_batch, spec, batch, reduce, errors == "raise", pure=False) for batch in batches
    ]
    out: list[Any] = [None] * len(todo)
    done = 0
    with Progress(len(todo), desc="sweep", enabled=progress) as bar:
        try:
            for fut in distributed.as_completed(futures):
                for index, kind, value in fut.result():
                    out[index] = _settle(index, todo[index], kind, value, errors)
                    done += 1
                bar.update(done)
        except BaseException:
            client.cancel(futures)
            raise
    return out


def _settle(index: int, run: Mapping[str, Any], kind: str, value: Any, errors: OnError) -> Any:
    """The value of one run on the client: its result, or its error raised or put in place."""
    if kind == "ok":
        return value
    if kind == "value":
        raise ValueError(f"sweep run {index} ({_describe(run)}): {value}")
    if kind == "reduce":
        raise RuntimeError(f"sweep run {index}: reduce raised {value}")
    err, result = value
    err.result, err.run = result, index
    if errors == "raise":
        err.args = (f"sweep run {index}: {err.args[0]}",)
        raise err
    return err


def _describe(run: Mapping[str, Any]) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in run.items() if k != "progress")[:200]


# -- the worker side ----------------------------------------------------------------------

_SIMULATORS: OrderedDict[str, Simulator] = OrderedDict()
_LOCK = threading.Lock()


def worker_simulator(spec: SimulatorSpec) -> Simulator:
    """The simulator of ``spec`` in this process: built the first time, then kept."""
    with _LOCK:
        sim = _SIMULATORS.get(spec.key)
        if sim is None:
            sim = _SIMULATORS[spec.key] = spec.build()
            while len(_SIMULATORS) > WORKER_CACHE:
                _SIMULATORS.popitem(last=False)
        _SIMULATORS.move_to_end(spec.key)
        return sim


def run_batch(
    spec: SimulatorSpec, batch: Sequence[tuple[int, dict]], reduce, stop_at_error: bool
) -> list[tuple[int, str, Any]]:
    """On a worker: ``(index, "ok", result or reduce(result))`` per run; a failed run gives
    ``(index, "solver", (err, err.result))``, ``(index, "value", message)`` (bad input) or
    ``(index, "reduce", message)`` (``reduce`` raised); the batch ends at a bad input, a failing
    ``reduce``, and, with ``stop_at_error``, at a ``SolverError``."""
    sim = worker_simulator(spec)
    out = []
    for index, run in batch:
        try:
            res = sim.simulate(**run)
        except SolverError as err:
            out.append((index, "solver", (err, err.result)))
            if stop_at_error:
                break
            continue
        except ValueError as err:
            out.append((index, "value", str(err)))
            break
        if reduce is None:
            out.append((index, "ok", res))
            continue
        try:
            out.append((index, "ok", reduce(res)))
        except Exception as err:  # noqa: BLE001 - the user's function: its error goes back named
            out.append((index, "reduce", f"{type(err).__name__}: {err}"))
            break
    return out
