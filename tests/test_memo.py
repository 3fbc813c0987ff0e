"""The in-process memos of ``derive`` and ``tangent_routines`` (``vcigen.memo``): a model derived again is
the first derivation, handed out in fresh containers, and every backend's input is the same as without them
(the rendered C of the plain library and of the sensitivity variant, text for text)."""

from __future__ import annotations

import sympy as sp

import vcigen
from vcigen import memo
from vcigen.backends.c import LIBRARY_TEMPLATES, render
from vcigen.backends.ccontext import render_context
from vcigen.derive import derive
from vcigen.tangents import tangent_routines


def ball(g: float = 9.81, e: float = 0.8, name: str = "memo_ball") -> vcigen.Model:
    """A ball under gravity on a tilted floor, lossy: contacts, restitution and a parameter."""
    x, y, xd, yd, gs = sp.symbols("x y xd yd g")
    return vcigen.Model(
        name=name,
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - gs * y,
        contacts={"floor": y - x / 4},
        params={gs: g},
        restitution={"floor": e},
    )


def test_a_model_derived_again_is_the_first_derivation_in_new_containers() -> None:
    first, again = derive(ball(), "lobatto3"), derive(ball(), "lobatto3")
    assert list(first.routines) == list(again.routines)
    assert first.routines is not again.routines
    for name, r in first.routines.items():
        s = again.routines[name]
        assert s.inputs == r.inputs  # the same symbols: the same derivation
        for o, p in zip(r.outputs, s.outputs):
            assert o.expr is not p.expr and all(a is b for a, b in zip(o.expr, p.expr)), (name, o.name)
    model = ball()
    assert derive(model, "lobatto3").model is model  # the caller's own model
    # what a caller does to what it got does not reach the next one
    again.routines["smooth"].output("res").expr[0, 0] = sp.Integer(7)
    again.routines.pop("jump")
    third = derive(ball(), "lobatto3")
    res = first.routines["smooth"].output("res").expr
    assert third.routines["smooth"].output("res").expr[0, 0] is res[0, 0]
    assert "jump" in third.routines


def test_different_models_and_rules_are_derived_apart() -> None:
    base = derive(ball(), "trapezoid")
    others = (derive(ball(g=9.8), "trapezoid"), derive(ball(e=0.7), "trapezoid"), derive(ball(), "midpoint"))
    for other in others:
        assert other.routines["segment"].inputs != base.routines["segment"].inputs
    assert memo.model_key(ball()) == memo.model_key(ball())
    assert memo.model_key(ball(name="memo_other")) != memo.model_key(ball())


def test_tangents_are_derived_once_for_the_same_expressions() -> None:
    system = derive(ball(), "trapezoid")
    first = tangent_routines(system.routines)
    copied = memo.copy_routines(system.routines)  # other matrices, the same expressions
    again = tangent_routines(copied)
    assert list(first) == list(again)
    for name, r in first.items():
        for o, p in zip(r.outputs, again[name].outputs):
            assert o.expr is not p.expr and all(a is b for a, b in zip(o.expr, p.expr))
    # an entry changed is other expressions: derived anew
    copied["smooth"].output("res").expr[0, 0] = 2 * copied["smooth"].output("res").expr[0, 0]
    dres = tangent_routines(copied)["d_smooth"].output("dres").expr
    before = first["d_smooth"].output("dres").expr
    assert dres[0, :] == 2 * before[0, :] != before[0, :] and dres[1:, :] == before[1:, :]


def _rendered(system: vcigen.DiscreteSystem) -> dict[str, str]:
    with_tangents = derive(system.model, system.rule, sensitivities=True)
    plain = render(render_context(system))
    sens = render(render_context(with_tangents, sensitivities=True), LIBRARY_TEMPLATES)
    return {**plain, **{f"sens/{k}": v for k, v in sens.items()}}


def test_the_rendered_c_is_the_same_with_and_without_the_memos(monkeypatch) -> None:
    """The plain library (every template) and the sensitivity variant, text for text (the CSE disk memo off:
    this compares derivations only)."""
    monkeypatch.setenv("VCIGEN_CSE_MEMO", "0")
    for rule in ("trapezoid", "lobatto3"):
        model = ball(name=f"memo_ball_{rule}")
        derive(model, rule)
        tangent_routines(derive(model, rule).routines)  # a session that derived it and its tangents before
        with_memo = _rendered(derive(model, rule))
        monkeypatch.setenv("VCIGEN_DERIVE_MEMO", "0")
        without = _rendered(derive(model, rule))
        monkeypatch.delenv("VCIGEN_DERIVE_MEMO")
        assert with_memo.keys() == without.keys()
        for name, text in without.items():
            assert with_memo[name] == text, (rule, name)
