"""In-process memos of the symbolic derivation: a model derived again, its tangents derived again.

A process often derives the same model several times: a test session builds one scene for both backends
and for several test modules, a script builds it for two rules or twice. :func:`vcigen.derive.derive` and
:func:`vcigen.tangents.tangent_routines` are pure functions of their inputs, so their results are kept
here (the last :data:`SIZE` of each) and handed out again:

* ``derive``: keyed by :func:`model_key` (the ``srepr`` of every attribute of the
  :class:`~vcigen.model.Model`: equal keys mean structurally equal models, symbols with their assumptions
  and floats with their precision) and the rule object. A hit is the same routines in a new dict with copied
  output matrices and the caller's own model, so a caller that mutates what it got cannot change what the next
  one gets; the expressions (immutable) are shared, and so are SymPy's caches of their derivatives.
* ``tangent_routines``: keyed by the identity of every input symbol and output entry of the routines it
  differentiates (held by the memo, so the identities stay valid): the same expressions, however the
  matrices holding them were copied.

What is handed out is exactly what the first derivation computed, so every backend's result is the same
as without the memo (the generated C byte for byte, ``tests/test_memo.py``). ``VCIGEN_DERIVE_MEMO=0``
turns both off. What a memo misses is read from disk when another process derived it
(:mod:`vcigen.diskmemo`; ``VCIGEN_DERIVE_DISK=0`` turns that off).
"""

from __future__ import annotations

import os
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import replace
from typing import TypeVar

import sympy as sp

SIZE = 32  # entries kept per memo (least recently used dropped)

T = TypeVar("T")


def enabled() -> bool:
    """Whether the memos are on (``VCIGEN_DERIVE_MEMO`` is not ``0``)."""
    return os.environ.get("VCIGEN_DERIVE_MEMO", "1") != "0"


class Lru:
    """A small least-recently-used map; :meth:`get_or_make` computes a missing value (outside the lock:
    two threads missing the same key at once both compute it, and the first stored is kept)."""

    def __init__(self, size: int = SIZE) -> None:
        self.size = size
        self._items: OrderedDict[Hashable, object] = OrderedDict()
        self._lock = threading.Lock()

    def get_or_make(self, key: Hashable, make: Callable[[], T]) -> T:
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]  # type: ignore[return-value]
        value = make()
        with self._lock:
            value = self._items.setdefault(key, value)
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return value  # type: ignore[return-value]

    def clear(self) -> None:
        with self._lock:
            self._items.clear()

    def __len__(self) -> int:
        return len(self._items)


def model_key(model) -> str:
    """The ``srepr`` of every attribute of ``model`` (by name) and its class: equal keys mean equal models,
    whatever attribute a later :func:`vcigen.derive.derive` reads (an attribute that does not print the same
    twice, e.g. a function's address, only makes the memo miss)."""
    return sp.srepr((type(model).__module__, type(model).__qualname__, sorted(vars(model).items())))


def copy_routines(routines: dict) -> dict:
    """``routines`` in a new dict, each routine (and its head) with copied output matrices."""
    done: dict[int, object] = {}

    def copy(r):
        if r is None:
            return None
        if id(r) not in done:
            outputs = tuple(replace(o, expr=o.expr.copy()) for o in r.outputs)
            done[id(r)] = replace(r, outputs=outputs, head=copy(r.head))
        return done[id(r)]

    return {name: copy(r) for name, r in routines.items()}


def routines_key(routines: dict) -> tuple[tuple, list]:
    """The identity of every input symbol and output entry of ``routines``, by name (see the module), and
    those objects (to be kept with the key: an identity is unique only while its object lives)."""
    key, held = [], []
    for name, r in routines.items():
        ins = [a.symbols for a in r.inputs]
        outs = [list(o.expr) for o in r.outputs]
        held.append((ins, outs))
        key.append(
            (
                name,
                tuple((a.name, tuple(map(id, s))) for a, s in zip(r.inputs, ins)),
                tuple((o.name, o.expr.shape, tuple(map(id, e))) for o, e in zip(r.outputs, outs)),
            )
        )
    return tuple(key), held
