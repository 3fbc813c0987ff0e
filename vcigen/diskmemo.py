"""The derivation remembered on disk: ``derive`` and ``tangent_routines`` of another process read back.

:mod:`vcigen.memo` keeps a derivation for the process that made it; this keeps it for the next one (a test
worker, a second session, a Dask worker) in ``<cache>/derive`` (``$VCIGEN_CACHE`` or ``~/.cache/vcigen``,
the compile cache's root), under a digest of what determines it and of the code that computes it: the
vcigen package's own source files, SymPy's and Python's versions, and

* ``derive``: the model's :func:`vcigen.memo.model_key` and the rule's name (only a built-in rule, whose
  code is in that digest; a model holding a ``Dummy`` prints differently in every process: not stored);
* ``tangent_routines``: the input routines themselves, encoded as below.

The derivation's symbols are ``Dummy``; their indices differ from one process to the next, so, as in
:mod:`vcigen.csememo`, a dummy is stored as its rank (in creation order): an input dummy (a tangent's
routines' own) is this process's dummy of that rank, a dummy the derivation made is created anew on
reading, in the order the derivation created it, so dummies compare as they did in the derivation. Every
expression is stored as its tree (each unique subtree once) and rebuilt without evaluation: the same
trees as computed, so the generated C does not depend on the cache (``tests/test_diskmemo.py``).
A cache that cannot be read or written is skipped: the result is computed as without it.
``VCIGEN_DERIVE_DISK=0`` turns it off (``VCIGEN_DERIVE_MEMO=0`` turns off both memos).
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
import pickle
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import sympy as sp

from .csememo import cache_root, rebuild

# bump when the stored form changes
FORMAT = 1

T = TypeVar("T")

# what a read may raise on a file that is not a stored result of this code (then it is computed anew)
_UNREADABLE = (OSError, pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, IndexError,
               KeyError, ImportError)  # fmt: skip


def enabled() -> bool:
    """Whether the disk memo is on (``VCIGEN_DERIVE_DISK`` and ``VCIGEN_DERIVE_MEMO`` are not ``0``)."""
    return all(os.environ.get(var, "1") != "0" for var in ("VCIGEN_DERIVE_DISK", "VCIGEN_DERIVE_MEMO"))


@functools.cache
def code_digest() -> str:
    """A digest of every ``.py`` file of the vcigen package (name and bytes), SymPy's and Python's version."""
    h = hashlib.sha256(f"{FORMAT}\0{sp.__version__}\0{sys.version}\0".encode())
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def _assumptions(d: sp.Dummy) -> dict:
    return dict(d._assumptions_orig)


class _Encoder(pickle.Pickler):
    """Pickles an object whose SymPy parts go to :attr:`nodes` (each unique subtree once): a dummy of
    ``rank`` as ``("D", rank)``, another as ``("N", dummy)`` (numbered by :meth:`finish`), every other atom
    as itself, an operation as its class and its arguments' node indices."""

    def __init__(self, fh: io.BytesIO, rank: dict[sp.Dummy, int]) -> None:
        super().__init__(fh, protocol=pickle.HIGHEST_PROTOCOL)
        self.rank = rank
        self.nodes: list[tuple] = []
        self.index: dict[sp.Basic, int] = {}
        self.new: dict[sp.Dummy, int] = {}  # a dummy not in rank -> its node

    def node(self, e: sp.Basic) -> int:
        got = self.index.get(e)
        if got is not None:
            return got
        if isinstance(e, sp.Dummy):
            item: tuple = ("D", self.rank[e]) if e in self.rank else ("N", e)
        elif e.is_Atom:
            item = ("A", e)
        else:
            item = ("F", e.func, tuple(self.node(a) for a in e.args))
        self.index[e] = len(self.nodes)
        if item[0] == "N":
            self.new[e] = len(self.nodes)
        self.nodes.append(item)
        return self.index[e]

    def persistent_id(self, obj: object) -> int | None:
        return self.node(obj) if isinstance(obj, sp.Basic) else None

    def finish(self) -> list[sp.Dummy]:
        """Number the new dummies after the ranked ones, in creation order; they, in that order."""
        new = sorted(self.new, key=lambda d: d.dummy_index)
        for k, d in enumerate(new, start=len(self.rank)):
            self.nodes[self.new[d]] = ("N", k, d.name, _assumptions(d))
        return new


def encode(
    obj: object, rank: dict[sp.Dummy, int], canonical: bool = False
) -> tuple[list[tuple], bytes, list[sp.Dummy]]:
    """``obj`` as nodes and the pickle of the rest (see :class:`_Encoder`), and its new dummies in order.

    ``canonical``: without pickle's memo, so that equal objects give equal bytes however they share parts
    (two equal strings, one object or two): for :func:`digest`; ``obj`` must then hold no cycle."""
    fh = io.BytesIO()
    enc = _Encoder(fh, rank)
    enc.fast = canonical
    enc.dump(obj)
    new = enc.finish()
    return enc.nodes, fh.getvalue(), new


def _text(item: tuple) -> str:
    if item[0] == "D":
        return f"D{item[1]}"
    if item[0] == "N":
        return f"N{item[1]}:{item[2]}:{sorted(item[3].items())}"
    if item[0] == "A":
        return sp.srepr(item[1])
    return f"F{item[1].__module__}.{item[1].__qualname__}{item[2]}"


def digest(nodes: list[tuple], payload: bytes) -> str:
    """A digest of an object :func:`encode`-d ``canonical``, stable across processes."""
    h = hashlib.sha256("\n".join(map(_text, nodes)).encode())
    h.update(b"\0" + payload)
    return h.hexdigest()


class _Decoder(pickle.Unpickler):
    def __init__(self, payload: bytes, built: list[sp.Basic]) -> None:
        super().__init__(io.BytesIO(payload))
        self.built = built

    def persistent_load(self, pid: object) -> sp.Basic:
        return self.built[pid]  # type: ignore[index]


def decode(nodes: list[tuple], payload: bytes, dummies: list[sp.Dummy]) -> object:
    """The object of :func:`encode`: ranked dummies from ``dummies``, new ones made now (in their order),
    every expression rebuilt without evaluation (the same trees)."""
    new = sorted((item for item in nodes if item[0] == "N"), key=lambda item: item[1])
    fresh = {item[1]: sp.Dummy(item[2], **item[3]) for item in new}
    built = rebuild(nodes, lambda item: dummies[item[1]] if item[0] == "D" else fresh[item[1]])
    return _Decoder(payload, built).load()


def _path(kind: str, key: str) -> Path:
    name = hashlib.sha256(f"{code_digest()}\0{kind}\0{key}".encode()).hexdigest()
    return cache_root() / "derive" / name[:2] / f"{name}.pickle"


def get_or_make(kind: str, key: str, make: Callable[[], T], dummies: list[sp.Dummy] | None = None) -> T:
    """``make()``, or what it returned for the same ``kind`` and ``key`` in any process, read from disk.

    ``dummies``: the inputs' dummies in creation order (what ``key`` names by rank); every other dummy of
    the result is one ``make`` created. What is computed is returned as computed."""
    dummies = dummies or []
    path = _path(kind, key)
    try:
        with path.open("rb") as fh:
            nodes, payload = pickle.load(fh)
        return decode(nodes, payload, dummies)  # type: ignore[return-value]
    except _UNREADABLE:
        pass
    value = make()
    try:
        nodes, payload, _ = encode(value, {d: i for i, d in enumerate(dummies)})
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".tmp", delete=False) as tmp:
            try:
                pickle.dump((nodes, payload), tmp, protocol=pickle.HIGHEST_PROTOCOL)
            except BaseException:
                os.unlink(tmp.name)
                raise
        Path(tmp.name).replace(path)  # atomic: concurrent writers of one key are harmless
    except (OSError, pickle.PicklingError, TypeError, AttributeError, KeyError, RecursionError):
        pass
    return value
