"""The disk memo of SymPy's CSE (vcigen/csememo.py): a second derivation in a fresh process reads back a
valid elimination of *its own* expressions (its dummies, not the first one's); off, corrupt or unwritable
caches fall back to computing it."""

from __future__ import annotations

import pickle

import pytest
import sympy as sp

from vcigen import csememo


def _exprs(tag: str = "x") -> tuple[list[sp.Expr], list[sp.Dummy]]:
    """A small derivation with fresh dummies, as vcigen.derive makes them (new indices every call)."""
    a, b, tau = sp.Dummy("a", real=True), sp.Dummy("b", real=True), sp.Dummy("tau", real=True)
    x = sp.Symbol(tag, real=True)
    s = sp.sin(a * tau + b) ** 2 + x
    return [s * sp.cos(a) + sp.exp(s), (s + 1) / (a - b) + tau * sp.exp(s)], [a, b, tau]


def _rebuild(repl, reduced) -> list[sp.Expr]:
    sub = {}
    for sym, e in repl:
        sub[sym] = e.xreplace(sub)
    return [e.xreplace(sub) for e in reduced]


@pytest.fixture()
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VCIGEN_CACHE", str(tmp_path))
    monkeypatch.delenv("VCIGEN_CSE_MEMO", raising=False)
    return tmp_path


def test_a_second_derivation_reads_a_valid_elimination_of_its_own_dummies(cache):
    first, _ = _exprs()
    csememo.cse(first)
    stored = list((cache / "cse").rglob("*.pickle"))
    assert len(stored) == 1
    second, dummies = _exprs()  # the same derivation again: new dummies, other indices
    assert not set(dummies) & set().union(*(e.atoms(sp.Dummy) for e in first))
    repl, reduced = csememo.cse(second)
    assert len(list((cache / "cse").rglob("*.pickle"))) == 1  # read back, not computed again
    assert repl  # there was something to eliminate
    got = _rebuild(repl, reduced)
    assert [sp.simplify(g - e) for g, e in zip(got, second)] == [0, 0]
    assert set().union(*(g.atoms(sp.Dummy) for g in got)) == set(dummies)  # this call's own dummies


def test_other_expressions_get_another_entry(cache):
    csememo.cse(_exprs("x")[0])
    csememo.cse(_exprs("y")[0])  # another user symbol
    csememo.cse(_exprs("x")[0], optimizations=None)  # other options
    assert len(list((cache / "cse").rglob("*.pickle"))) == 3


def test_off_or_corrupt_computes_the_same_elimination(cache, monkeypatch):
    exprs, _ = _exprs()
    want = sp.cse(exprs, symbols=sp.numbered_symbols("t", real=True), optimizations="basic")
    csememo.cse(exprs)
    for path in (cache / "cse").rglob("*.pickle"):
        path.write_bytes(b"not a pickle")
    assert csememo.cse(exprs) == (list(want[0]), list(want[1]))
    (path,) = (cache / "cse").rglob("*.pickle")
    assert pickle.loads(path.read_bytes())  # rewritten by the fallback
    monkeypatch.setenv("VCIGEN_CSE_MEMO", "0")
    path.unlink()
    assert csememo.cse(exprs) == (list(want[0]), list(want[1]))
    assert not list((cache / "cse").rglob("*.pickle"))


def test_an_unwritable_cache_is_skipped(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache directory would be")
    monkeypatch.setenv("VCIGEN_CACHE", str(blocker))
    exprs, _ = _exprs()
    repl, reduced = csememo.cse(exprs)
    assert [sp.simplify(g - e) for g, e in zip(_rebuild(repl, reduced), exprs)] == [0, 0]


def test_read_back_prints_as_computed(cache):
    """What the memo returns prints exactly as what SymPy computed (no re-evaluation: ``(1/2)*(a + b)``
    stays, so the generated C does not depend on the cache)."""
    a, b = sp.Dummy("a", real=True), sp.Dummy("b", real=True)
    exprs = [a**2 / 2 + b**2 / 2, sp.sin(a * b) * a, sp.sin(a * b) ** 2]
    fresh = sp.cse(exprs, symbols=sp.numbered_symbols("t", real=True), optimizations="basic")
    assert sp.srepr(fresh[1][0]) != sp.srepr(pickle.loads(pickle.dumps(fresh[1][0])))  # SymPy re-evaluates
    first = csememo.cse(exprs)
    again = csememo.cse(exprs)  # read back
    for got in (first, again):
        assert [(s, sp.srepr(e)) for s, e in got[0]] == [(s, sp.srepr(e)) for s, e in fresh[0]]
        assert [sp.srepr(e) for e in got[1]] == [sp.srepr(e) for e in fresh[1]]
