"""SymPy's common-subexpression elimination, remembered on disk.

``sympy.cse`` with its ``basic`` pre-optimisations (``factor_terms``) is a large part of a build: tens of
seconds for the derived tangent routines of a double pendulum under ``lobatto3``. It is a pure function of
its expressions, so its result is kept in ``<cache>/cse`` (``$VCIGEN_CACHE`` or ``~/.cache/vcigen``, the
compile cache's root) under a digest of the expressions, the options and SymPy's version: a second build of
the same model (another process, another session, a Dask worker) reads it back.

The derivation's own symbols are ``Dummy`` (no clash with the user's); their indices differ from one
process to the next, so the digest names each by its rank among the expressions' dummies (in creation
order) and the stored result holds those ranks, rebuilt with this process's dummies, without evaluation
(SymPy would otherwise distribute ``(1/2)*(a + b)``: the same trees as computed, so the generated code
does not depend on the cache). Equal digests mean equal expressions up to that renaming, so what is read
back is a valid elimination of them.
A cache that cannot be read or written is skipped: the result is computed as without it.
``VCIGEN_CSE_MEMO=0`` turns the memo off.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import sympy as sp

# bump when the digest or the stored form changes
FORMAT = 4

Result = tuple[list[tuple[sp.Symbol, sp.Expr]], list[sp.Expr]]


def cache_root() -> Path:
    """``$VCIGEN_CACHE`` or ``~/.cache/vcigen``."""
    env = os.environ.get("VCIGEN_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "vcigen"


def _assumptions(s: sp.Symbol) -> str:
    return ",".join(f"{k}={v}" for k, v in sorted(s.assumptions0.items()))


def _encode(exprs: Sequence[sp.Basic], rank: dict[sp.Dummy, int]) -> tuple[list[tuple], list[int]]:
    """``exprs`` as a list of nodes (each unique subtree once) and the indices of the roots: dummies by
    ``rank``, every other atom as itself, an operation as its class and its arguments' indices."""
    nodes: list[tuple] = []
    index: dict[sp.Basic, int] = {}

    def node(e: sp.Basic) -> int:
        got = index.get(e)
        if got is not None:
            return got
        if isinstance(e, sp.Dummy):
            item: tuple = ("D", rank[e])
        elif e.is_Atom:
            item = ("A", e)
        else:
            item = ("F", e.func, tuple(node(a) for a in e.args))
        index[e] = len(nodes)
        nodes.append(item)
        return index[e]

    return nodes, [node(e) for e in exprs]


def digest(exprs: Sequence[sp.Basic], rank: dict[sp.Dummy, int]) -> str:
    """A digest of ``exprs`` stable across processes: their :func:`_encode` nodes as text (a dummy by its
    rank and assumptions, a symbol by its name and assumptions, an operation by its class and arguments)."""
    nodes, roots = _encode(exprs, rank)
    dummies = {r: d for d, r in rank.items()}

    def text(item: tuple) -> str:
        if item[0] == "D":
            return f"D{item[1]}:{_assumptions(dummies[item[1]])}"
        if item[0] == "A":
            atom = item[1]
            return f"S{atom.name}:{_assumptions(atom)}" if isinstance(atom, sp.Symbol) else sp.srepr(atom)
        return f"F{item[1].__name__}{item[2]}"

    body = "\n".join(map(text, nodes)) + f"\n{roots}"
    return hashlib.sha256(body.encode()).hexdigest()


def rebuild(nodes: list[tuple], leaf: Callable[[tuple], sp.Basic]) -> list[sp.Basic]:
    """Every node of an encoding (:func:`_encode`; :mod:`vcigen.diskmemo`'s) rebuilt without evaluation (the
    same trees, so that a result read back prints as the one computed): an atom as stored (``"A"``), a
    function of the nodes before it, and any other node (a dummy) as ``leaf(node)``."""
    built: list[sp.Basic] = []
    for item in nodes:
        if item[0] == "A":
            built.append(item[1])
        elif item[0] != "F":
            built.append(leaf(item))
        else:
            args = [built[i] for i in item[2]]
            try:
                built.append(item[1](*args, evaluate=False))
            except TypeError:
                built.append(item[1](*args))
    return built


def _decode(nodes: list[tuple], roots: list[int], dummies: list[sp.Dummy]) -> list[sp.Basic]:
    """The expressions of :func:`_encode` with this process's ``dummies`` (by rank)."""
    built = rebuild(nodes, lambda item: dummies[item[1]])
    return [built[i] for i in roots]


def cse(exprs: Sequence[sp.Basic], optimizations: str | None = "basic") -> Result:
    """``sympy.cse(exprs, symbols=t0, t1, ... (real), optimizations=...)``, read from the disk memo when
    the same expressions were eliminated before. What is computed is returned as it is read back (the
    same trees, whether the memo had it or not)."""
    exprs = list(exprs)

    def compute() -> Result:
        names = sp.numbered_symbols("t", real=True)
        repl, reduced = sp.cse(exprs, symbols=names, optimizations=optimizations)
        return list(repl), list(reduced)

    if os.environ.get("VCIGEN_CSE_MEMO", "1") == "0" or not exprs:
        return compute()
    dummies = sorted(set().union(*(e.atoms(sp.Dummy) for e in exprs)), key=lambda d: d.dummy_index)
    rank = {d: i for i, d in enumerate(dummies)}
    key = hashlib.sha256(
        f"{FORMAT}\0{sp.__version__}\0{optimizations}\0{digest(exprs, rank)}".encode()
    ).hexdigest()
    path = cache_root() / "cse" / key[:2] / f"{key}.pickle"
    try:
        with path.open("rb") as fh:
            syms, nodes, roots = pickle.load(fh)
        if len(roots) == len(syms) + len(exprs):
            got = _decode(nodes, roots, dummies)
            return list(zip(syms, got[: len(syms)])), got[len(syms) :]
    except (OSError, pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, IndexError):
        pass
    repl, reduced = compute()
    syms = [s for s, _ in repl]
    nodes, roots = _encode([e for _, e in repl] + reduced, rank)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".tmp", delete=False) as tmp:
            pickle.dump((syms, nodes, roots), tmp, protocol=pickle.HIGHEST_PROTOCOL)
        Path(tmp.name).replace(path)  # atomic: concurrent writers of one key are harmless
    except OSError:
        pass
    return repl, reduced
