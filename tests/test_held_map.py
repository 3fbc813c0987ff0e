"""The fused tangent of a held grid step (``vcigen.backends.cheld_map``, ``templates/sens_held_map.c.j2``).

Per active set of one or two rows the C variant prints the tangent of a held step as three straight-line
routines (the state-dependent partials, ``Phi = d(q1, p1)/d(q, p, params)`` eliminated symbolically, ``S_k+1
= Phi S_k``). Checked here: the slide's map is the closed form of a unit mass on a floor; on curved and
two-row sets the routines equal the numeric implicit-function theorem (``Tracker.held``'s algebra:
``rattle``, ``rattle_project``, ``d_segment``, ``d_legendre``, solved with ``numpy.linalg.solve``) at random
states, since every zero or one the elimination leaves out holds for any values of the partials; and the
generated C calls them from the held glide. The whole runs (C against CasADi, the same breaks) are
``test_sensitivity_c``'s.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import sympy as sp
import test_sensitivity as ts

import vcigen
from vcigen.backends.c import LIBRARY_TEMPLATES, render
from vcigen.backends.ccontext import held_sets, render_context
from vcigen.backends.cheld_map import HeldMap, _settled_on_states, held_map, held_maps
from vcigen.derive import DiscreteSystem, derive
from vcigen.routines import Routine


@cache
def system(scene: str) -> DiscreteSystem:
    return derive(ts.HELD_SCENES[scene][0](), "trapezoid", sensitivities=True)


def call(r: Routine, *args) -> np.ndarray:
    """Routine ``r``'s first output at ``args`` (one array per input), as a float array."""
    syms = [s for a in r.inputs for s in a.symbols]
    vals = [float(x) for a in args for x in np.ravel(a)]
    expr = r.outputs[0].expr
    return np.array(expr.xreplace(dict(zip(syms, vals))).evalf(), dtype=float).reshape(expr.shape)


def fused(m: HeldMap, q, p, tau, v, lam, lam1, u1, par, s) -> np.ndarray:
    """``S_k+1`` from the three routines, as the C variant calls them."""
    a = call(m.atoms, q, p, [tau], v, lam, lam1, u1, par)
    f = call(m.phi, a, [tau], par)
    return call(m.map, f, [tau], par, s)


def numeric(sys_: DiscreteSystem, rows, q, p, tau, v, lam, lam1, u1, par, s) -> np.ndarray:
    """``S_k+1`` by ``Tracker.held``'s algebra: the two implicit-function theorems solved numerically."""
    r = sys_.routines
    n, nr, big_p = sys_.n, sys_.r, len(sys_.model.defaults)
    k = s.shape[1]
    act = np.array([1.0 if j in rows else 0.0 for j in range(nr)])
    dq, dp = s[:n], s[n:]
    dpar = np.zeros((par.size, k))
    dpar[:big_p, 2 * n :] = np.eye(big_p)
    zr = np.zeros((nr, k))
    x = np.concatenate([v, lam])
    jac = call_out(r["rattle"], "jac", x, q, p, [tau], act, par)
    dres = call(r["d_rattle"], x, q, p, [tau], act, par)
    dv = -np.linalg.solve(jac, dres @ np.vstack([dq, dp, np.zeros((1, k)), zr, dpar]))[:n]
    q1 = q + tau * v
    dq1 = dq + tau * dv
    dpp = call_out(r["d_segment"], "dp_plus", q, v, [tau], par) @ np.vstack([dq, dv, np.zeros((1, k)), dpar])
    y = np.concatenate([u1, lam1])
    pp = np.zeros(n)  # p1 enters rattle_project linearly: its value is not read by jac nor dres
    jac = call_out(r["rattle_project"], "jac", y, q1, pp, act, par)
    dres = call(r["d_rattle_project"], y, q1, pp, act, par)
    du1 = -np.linalg.solve(jac, dres @ np.vstack([dq1, dpp, zr, dpar]))[:n]
    dmom = call(r["d_legendre"], q1, u1, np.zeros(n), par)
    return np.vstack([dq1, dmom @ np.vstack([dq1, du1, dpar])])


def parameters(sys_: DiscreteSystem) -> np.ndarray:
    """The full ``par`` vector: the model's defaults, then 0 in the other slots."""
    given = [float(x) for x in sys_.model.defaults.values()]
    return np.array(given + [0.0] * (len(sys_.params) - len(given)))


def call_out(r: Routine, name: str, *args) -> np.ndarray:
    out = r.output(name)
    return call(Routine(r.name, r.inputs, (out,)), *args)


def test_the_slides_map_is_the_closed_form() -> None:
    """A unit mass held on the floor y = 0: x1 = x + h px, y1 = 0, px1 = px, py1 = 0 for any S_k (and the map
    reads no partial: every entry of Phi is a number or h)."""
    sys_ = system("slide")
    (m,) = held_maps(sys_, held_sets(sys_.r))
    assert m.atoms.outputs[0].size == 0 and m.phi.outputs[0].size == 0
    h = 0.01
    rng = np.random.default_rng(1)
    s = rng.normal(size=(4, 2 * 2 + len(sys_.model.defaults)))
    par = parameters(sys_)
    got = call(m.map, [], [h], par, s)
    want = np.vstack([s[0] + h * s[2], 0 * s[1], s[2], 0 * s[3]])
    assert np.array_equal(got, want)


def test_the_box_on_its_face_map_is_the_closed_form() -> None:
    """The box held on any two of its vertices (every two-row set): the two rows fix y and theta, so y1,
    theta1 and their momenta do not move with the start, and x1 = x + h px, px1 = px (unit mass, no force
    along x).
    Those zeros hold through the relations between the partials (sin and cos of one angle), not for
    independent values of them: ``_settled_on_states`` finds them, and the map reads no partial at all."""
    sys_ = system("box_face")
    h = 0.002
    rng = np.random.default_rng(3)
    par = parameters(sys_)
    s = rng.normal(size=(6, 2 * 3 + len(sys_.model.defaults)))
    want = np.vstack([s[0] + h * s[3], 0 * s[1], 0 * s[2], s[3], 0 * s[4], 0 * s[5]])
    pairs = [st for st in held_sets(sys_.r) if len(st["rows"]) == 2]
    assert len(pairs) == 6
    for st in pairs:
        m = held_map(sys_, tuple(st["rows"]), st["key"])
        assert m.atoms.outputs[0].size == 0 and m.phi.outputs[0].size == 0, st["rows"]
        assert np.array_equal(call(m.map, [], [h], par, s), want), st["rows"]


def test_settled_on_states_keeps_what_is_not_identically_0_or_1() -> None:
    """On partials ``a0 = sin q``, ``a1 = cos q``, ``a2 = |q|``: ``a0^2 + a1^2`` is 1 and
    ``a0^2 + a1^2 - 1`` is 0 as functions of ``q`` (settled); ``a0 - a1``, ``a0 a1`` and a rough entry
    that is 0 where it is sampled (``a2 - q``, 0 for ``q > 0`` only) stay."""
    q = sp.Symbol("q", real=True)
    a = sp.symbols("a0:3", real=True)
    atoms = {a[0]: sp.sin(q), a[1]: sp.cos(q), a[2]: sp.Abs(q)}
    m = sp.Matrix([[a[0] ** 2 + a[1] ** 2, a[0] ** 2 + a[1] ** 2 - 1, a[0] - a[1], a[0] * a[1], a[2] - q]])
    got = _settled_on_states(m, atoms, [q])
    assert list(got) == [1, 0, *m[2:]]


SETS = [("bowl", (0,)), ("box_face", (0, 1)), ("box_face", (2,)), ("rod", (0,))]


@pytest.mark.parametrize(("scene", "rows"), SETS)
def test_the_fused_map_is_the_numeric_tangent(scene: str, rows: tuple[int, ...]) -> None:
    """At random states (the identity holds for any values): fused == numeric to round-off."""
    sys_ = system(scene)
    n, nr = sys_.n, sys_.r
    key = next(s["key"] for s in held_sets(nr) if tuple(s["rows"]) == rows)
    m = held_map(sys_, rows, key)
    rng = np.random.default_rng(7)
    k = 2 * n + len(sys_.model.defaults)
    for _ in range(3):
        q, p, v, u1 = (rng.normal(size=n) for _ in range(4))
        q[:2] += 2.0  # off the bowl's centre (its row's gradient q/|q|)
        lam = np.array([rng.normal() if j in rows else 0.0 for j in range(nr)])
        lam1 = np.array([rng.normal() if j in rows else 0.0 for j in range(nr)])
        par = parameters(sys_)
        s = rng.normal(size=(2 * n, k))
        got = fused(m, q, p, 0.01, v, lam, lam1, u1, par, s)
        want = numeric(sys_, rows, q, p, 0.01, v, lam, lam1, u1, par, s)
        assert np.abs(got - want).max() <= 1e-12 * (1.0 + np.abs(want).max())


def test_the_held_glide_calls_the_fused_map() -> None:
    """The variant of a held-glide scene prints a map per active set of one or two rows and its held loop
    hands each step to sens_held_step (the map straight into the row); the plain library has none of it."""
    sys_ = system("box_face")
    ctx = render_context(sys_, sensitivities=True)
    assert [m["key"] for m in ctx["held_maps"]] == [s["key"] for s in held_sets(sys_.r)]
    names = {r["name"] for r in ctx["routines"]}
    parts = ("atoms", "phi", "map")
    assert all(f"sens_held_{part}_{m['key']}" in names for m in ctx["held_maps"] for part in parts)
    src = next(t for f, t in render(ctx, LIBRARY_TEMPLATES).items() if f.endswith(".c"))
    assert "_sens_held_step(c, q, p, h, v, lam, lam1, u1, S, W, s);" in src
    plain = render_context(sys_)
    assert plain["held_maps"] == [] and not any(r["name"].startswith("sens_held_") for r in plain["routines"])


def _shaft() -> vcigen.Model:
    """A unit mass in 1-D between a floor ``y >= 0`` and a ceiling ``y <= 1`` (restitution ``e``)."""
    y, yd, e = sp.symbols("y yd e")
    return vcigen.Model(
        name="shaft",
        q=[y],
        qdot=[yd],
        lagrangian=yd**2 / 2 - 9.81 * y,
        contacts={"floor": y, "ceiling": 1 - y},
        params={e: 0.5},
        restitution={"floor": e, "ceiling": e},
    )


def test_a_set_that_is_singular_everywhere_maps_to_nan_and_builds() -> None:
    """Both rows of the 1-D shaft held at once (never a state: the floor and the ceiling apart): its ``F`` is
    singular for every state, so its map is NaN (the caller's numeric path), where SymPy's elimination gave
    ``zoo`` and the C did not compile ("'zoo' undeclared"). The C run with sensitivities then bounces to rest
    on the floor (from the ceiling first) with the tangent CasADi's gives (the same breaks)."""
    sys_ = derive(_shaft(), "trapezoid", sensitivities=True)
    both = next(st for st in held_sets(sys_.r) if len(st["rows"]) == 2)
    m = held_map(sys_, tuple(both["rows"]), both["key"])
    values = [*m.phi.outputs[0].expr, *m.map.outputs[0].expr]
    assert not any(e.has(sp.zoo, sp.oo, -sp.oo) for e in values) and any(e.has(sp.nan) for e in values)
    runs = {
        b: vcigen.build(_shaft(), backend=b).simulate([0.5], [4.0], 0.01, t_end=3.0, sensitivities=True)
        for b in ("c", "casadi")
    }
    c, k = runs["c"], runs["casadi"]
    assert c.active[-1, 0] and np.abs(c.q[-1]).max() < 1e-12 and c.impacts[-1].kind == "plastic"
    assert {i.contact for i in c.impacts} == {"floor", "ceiling"}
    assert c.sensitivity_breaks == k.sensitivity_breaks
    finite = np.isfinite(k.sensitivity)
    assert finite.any() and np.array_equal(finite, np.isfinite(c.sensitivity))
    np.testing.assert_allclose(c.sensitivity[finite], k.sensitivity[finite], rtol=0, atol=1e-9)
