"""The disk memo of ``derive`` and ``tangent_routines`` (``vcigen.diskmemo``): a derivation read back in
another process renders the same C, text for text, as one computed there; another model, another rule or
other code misses; a corrupt or unwritable cache is computed anew."""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import sympy as sp
from test_memo import ball

from vcigen import diskmemo, memo
from vcigen.derive import DiscreteSystem

derive_module = importlib.import_module("vcigen.derive")  # the package's `derive` is the function
tangents = importlib.import_module("vcigen.tangents")

# Renders the plain library and the sensitivity variant of the ball under lobatto3 and prints their
# digests; with "trap" as argument a derivation or tangent computed here (not read back) raises.
SCRIPT = """
import hashlib, importlib, json, sys
derive = importlib.import_module("vcigen.derive")
tangents = importlib.import_module("vcigen.tangents")
from vcigen.backends.c import LIBRARY_TEMPLATES, render
from vcigen.backends.ccontext import render_context
sys.path.insert(0, sys.argv[1] + "/tests")
from test_memo import ball
if sys.argv[2] == "trap":
    def trap(*args, **kwargs):
        raise AssertionError("computed, not read back")
    derive._derive = tangents._tangent_routines = trap
model = ball(name="disk_ball")
plain = render(render_context(derive.derive(model, "lobatto3")))
sens = render(render_context(derive.derive(model, "lobatto3", sensitivities=True), sensitivities=True),
              LIBRARY_TEMPLATES)
texts = {**plain, **{"sens/" + k: v for k, v in sens.items()}}
print(json.dumps({k: hashlib.sha256(v.encode()).hexdigest() for k, v in texts.items()}))
"""


@pytest.fixture()
def cache(tmp_path, monkeypatch) -> Path:
    monkeypatch.setenv("VCIGEN_CACHE", str(tmp_path))
    for var in ("VCIGEN_DERIVE_DISK", "VCIGEN_DERIVE_MEMO"):
        monkeypatch.delenv(var, raising=False)
    return tmp_path


def _run(cache: Path, mode: str, **env: str) -> dict[str, str]:
    root = str(Path(__file__).resolve().parent.parent)
    full = {k: v for k, v in os.environ.items() if k not in ("VCIGEN_DERIVE_DISK", "VCIGEN_DERIVE_MEMO")}
    full.update(VCIGEN_CACHE=str(cache), VCIGEN_CSE_MEMO="0", **env)
    out = subprocess.run([sys.executable, "-c", SCRIPT, root, mode], env=full, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.splitlines()[-1])


def test_a_derivation_read_back_in_another_process_renders_the_same_c(cache) -> None:
    fresh = _run(cache, "compute")
    assert len(list((cache / "derive").rglob("*.pickle"))) == 2  # derive and tangent_routines
    read = _run(cache, "trap")  # nothing derived: both read back
    assert read.keys() == fresh.keys() and any(k.startswith("sens/") for k in read)
    assert read == fresh
    with pytest.raises(AssertionError):  # the trap works: off, it is computed
        _run(cache, "trap", VCIGEN_DERIVE_DISK="0")


def _structure(obj: object, rank: dict[sp.Dummy, int] | None = None) -> str:
    """``obj`` with its dummies by rank: equal for the same derivation in any process."""
    nodes, payload, _ = diskmemo.encode(obj, rank or {}, canonical=True)
    return diskmemo.digest(nodes, payload)


def _parts(system: DiscreteSystem) -> dict:
    return {k: getattr(system, k) for k in ("contact_names", "params", "routines", "rows", "segment")}


@pytest.fixture()
def counted(monkeypatch) -> list[int]:
    """How many times ``_derive`` computed."""
    calls = [0]
    real = derive_module._derive

    def counting(*args, **kwargs):
        calls[0] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(derive_module, "_derive", counting)
    return calls


def _derived(model, rule: str = "trapezoid") -> DiscreteSystem:
    from vcigen.rules import get_rule

    return derive_module._derive_stored(model, get_rule(rule), memo.model_key(model))


def test_the_same_model_hits_another_misses(cache, counted) -> None:
    first = _derived(ball())
    again = _derived(ball())
    assert counted[0] == 1
    assert _structure(_parts(again)) == _structure(_parts(first))
    assert again.routines["smooth"].inputs != first.routines["smooth"].inputs  # dummies made anew
    for other in (ball(g=9.8), ball(e=0.7), ball(name="disk_other")):
        _derived(other)
    _derived(ball(), "midpoint")
    assert counted[0] == 5


def test_other_code_misses(cache, counted, monkeypatch) -> None:
    _derived(ball())
    monkeypatch.setattr(diskmemo, "code_digest", lambda: "other code")
    _derived(ball())
    assert counted[0] == 2


def test_a_corrupt_or_unwritable_cache_is_computed_anew(cache, counted, tmp_path, monkeypatch) -> None:
    want = _structure(_parts(_derived(ball())))
    for path in (cache / "derive").rglob("*.pickle"):
        path.write_bytes(b"not a pickle")
    assert _structure(_parts(_derived(ball()))) == want
    assert counted[0] == 2
    for path in (cache / "derive").rglob("*.pickle"):
        path.write_bytes(path.read_bytes()[:40])  # a pickle cut short
    assert _structure(_parts(_derived(ball()))) == want
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache directory should be")
    monkeypatch.setenv("VCIGEN_CACHE", str(blocker))
    assert _structure(_parts(_derived(ball()))) == want
    assert counted[0] == 4


def test_tangents_read_back_are_in_the_callers_own_dummies(cache, monkeypatch) -> None:
    monkeypatch.setenv("VCIGEN_DERIVE_DISK", "0")  # two derivations: the same routines, other dummies
    one = derive_module.derive(ball(name="disk_rows"), "lobatto3").routines
    monkeypatch.setenv("VCIGEN_DERIVE_MEMO", "0")
    two = derive_module.derive(ball(name="disk_rows"), "lobatto3").routines
    monkeypatch.delenv("VCIGEN_DERIVE_MEMO")
    monkeypatch.delenv("VCIGEN_DERIVE_DISK")
    assert two["smooth"].inputs != one["smooth"].inputs
    computed = tangents._tangent_routines_stored(one)
    monkeypatch.setattr(tangents, "_tangent_routines", lambda r: pytest.fail("computed, not read back"))
    read = tangents._tangent_routines_stored(two)
    assert list(read) == list(computed) and "d_forces" in read  # with dummies of its own (a, lam)
    for name, r in read.items():
        base = two.get(name.removeprefix("d_"))
        if base is not None:  # this process's input symbols
            names = {a.name for a in base.inputs}
            assert all(a == base.input(a.name) for a in r.inputs if a.name in names), name
    rank = {}
    for routines in (one, two):
        _, _, dummies = diskmemo.encode(routines, {}, canonical=True)
        rank[id(routines)] = {d: i for i, d in enumerate(dummies)}
    assert _structure(read, rank[id(two)]) == _structure(computed, rank[id(one)])
