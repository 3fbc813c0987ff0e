"""The shipped compiler flags: every branch of the library templates compiles at ``-std=c99 -O2 -Wall -Wextra
-Werror`` (and at ``-O3``), and a library built at the test suite's optimisation level runs bit for bit as the
shipped one.

``make test`` builds the suite's libraries at ``VCIGEN_CC_OPT`` (``-O0``: a fifth of the compiler's time; the
flags are otherwise the shipped :data:`vcigen.backends.c.CFLAGS`). Some warnings (``-Wmaybe-uninitialized``)
only appear when optimising, so this file builds a set of scenes at the shipped ``-O2``, plain library and
sensitivity variant, checks that the template conditions they take (every ``{% if %}`` of the library's
templates) come out both ways across the set, and runs each scene on both libraries: the trajectory, impact
log, forces and tangent must be equal byte for byte (x86-64 without ``-ffast-math``: SSE2 arithmetic, no
contraction into FMA under ``-std=c99``, so the level changes the speed, not the numbers).
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import jinja2
import numpy as np
import pytest
import sympy as sp
import test_rough_ladder as rl
import test_sensitivity as ts
import test_sensitivity_friction as tf
import test_sensitivity_friction_events as fe
from jinja2 import meta

import vcigen
from vcigen.backends import c as cbackend

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")

SUITE = os.environ.get("VCIGEN_CC_OPT", "-O2")  # the level the rest of the suite builds at
TEMPLATES = Path(cbackend.template_dir())
DRIVER = {"main.c.j2", "Makefile.j2"}  # the standalone driver: test_codegen compiles it at -O2 already


def _args(q0: list, v0: list, h: float, t_end: float, params: dict | None = None) -> dict:
    return {"q0": q0, "v0": v0, "h": h, "t_end": t_end, "params": params}


def _scene(name: str, rule: str = "trapezoid") -> tuple:
    maker, *run = ts.SCENES[name]
    return maker, rule, _args(*run)


def _held(name: str, rule: str = "trapezoid") -> tuple:
    maker, *run, _ = ts.HELD_SCENES[name]
    return maker, rule, _args(*run)


def free_oscillator() -> vcigen.Model:
    """No contact and no constraint: no rows."""
    x, xd = sp.symbols("x xd")
    return vcigen.Model(name="sf_free", q=[x], qdot=[xd], lagrangian=(xd**2 - x**2) / 2, contacts={})


def heptagon() -> vcigen.Model:
    """A particle inside a regular heptagon (seven rows: more than the held loops per active set take) and,
    uncoupled, a pendulum and an anharmonic oscillator: four coordinates, a nonlinear grid step (LU)."""
    x, y, a, b, xd, yd, ad, bd = sp.symbols("x y a b xd yd ad bd")
    walls = {
        f"w{k}": 1 - math.cos(2 * math.pi * k / 7) * x - math.sin(2 * math.pi * k / 7) * y for k in range(7)
    }
    kinetic = (xd**2 + yd**2 + ad**2 + bd**2) / 2
    return vcigen.Model(
        name="sf_heptagon",
        q=[x, y, a, b],
        qdot=[xd, yd, ad, bd],
        lagrangian=kinetic + sp.cos(a) - b**4 / 4,
        contacts=walls,
    )


# scene -> (model maker, rule, simulate's arguments); each runs with sensitivities, so both the plain library
# and the sensitivity variant are built. Chosen to take every template condition both ways at the least cost
# (test_the_scenes_take_every_template_condition_both_ways); all but the last two are built by other tests.
CASES = {
    "double_pendulum": _scene("double_pendulum"),  # configuration-dependent mass: the Newton grid step
    "box_lobatto3": _scene("box", "lobatto3"),  # internal points, the stage in closed form
    "rod": _held("rod"),  # a bilateral constraint, a curved row held
    # one-tangent Coulomb friction (a disk sliding on an incline)
    "incline_disk": (tf.incline_disk, "trapezoid", _args([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], 0.01, 0.5)),
    # the isotropic cone (two tangents) and a force of time
    "puck_timed": (fe.puck_timed, "trapezoid", _args([0.0, 0.0, 0.0], [0.5, 0.0, 0.0], 0.01, 0.5)),
    # two one-tangent contacts, one riding on the other's stick: their split (a ladder sliding off its stand)
    "rough_ladder": (
        rl.model,
        "trapezoid",
        _args([math.sin(1.0) / 2, math.cos(1.0) / 2, 1.0], [0.0, 0.0, 0.0], 0.01, 0.5, {"mu": 0.3}),
    ),
    # no rows; seven rows and four coordinates
    "free": (free_oscillator, "trapezoid", _args([1.0], [0.0], 0.01, 1.0)),
    "heptagon": (heptagon, "trapezoid", _args([0.0, 0.0, 0.5, 0.5], [1.0, 0.3, 0.0, 0.0], 0.01, 2.0)),
}


def fingerprint(res: vcigen.Result) -> str:
    """A digest of every array of ``res`` (bytes, dtypes and shapes) and its lift-offs and breaks."""
    tab = res.impact_table
    arrays = [res.t, res.q, res.p, res.energy, res.active, res.contact_force, res.constraint_force]
    arrays += [res.work, res.friction_work, res.sensitivity, tab.t, tab.contact, tab.step, tab.q, tab.alpha]
    arrays += [tab.impulse, tab.energy_before, tab.energy_after, tab.kind]
    h = hashlib.sha256()
    for a in arrays:
        a = None if a is None else np.ascontiguousarray(a)
        h.update(b"-" if a is None else f"{a.dtype}{a.shape}".encode() + a.tobytes())
    h.update(repr((res.liftoffs, res.sensitivity_breaks, res.stats.get("sensitivity_lost"))).encode())
    return h.hexdigest()


def conditions() -> list[str]:
    """Every ``{% if %}`` / ``{% elif %}`` condition of the library templates."""
    found = set()
    for path in TEMPLATES.glob("*.j2"):
        if path.name not in DRIVER:
            found |= set(re.findall(r"{%-?\s*(?:el)?if\s+(.+?)\s*-?%}", path.read_text()))
    return sorted(found)


def _value(env: jinja2.Environment, cond: str, ctx: dict) -> bool | None:
    """``cond`` on the render context ``ctx``; None if it reads a name ``ctx`` does not hold (a loop's or a
    macro's variable) or an attribute of a name that is a loop variable there (``r.hot``)."""
    if not meta.find_undeclared_variables(env.parse(f"{{% if {cond} %}}{{% endif %}}")) <= ctx.keys():
        return None
    try:
        return bool(env.compile_expression(cond, undefined_to_none=False)(**ctx))
    except jinja2.UndefinedError:
        return None


# conditions no scene above takes both ways, and where the other way is compiled at -O2
ONE_WAY = {
    "nb > 0": "friction tangents with kinks: examples/friction/star_friction, generated/ (test_codegen, -O2)",
}
CONTEXTS: dict[str, list[dict]] = {}  # scene -> the render contexts its -O2 libraries were compiled from


@pytest.mark.parametrize("scene", sorted(CASES))
def test_shipped_flags_compile_and_give_the_suite_levels_numbers(
    scene: str, monkeypatch, tmp_path: Path
) -> None:
    maker, rule, run = CASES[scene]
    model = maker()
    seen: list[dict] = []
    render = cbackend.render

    def recording(ctx, *args, **kw):
        seen.append(ctx)
        return render(ctx, *args, **kw)

    monkeypatch.setattr(cbackend, "render", recording)
    monkeypatch.setenv("VCIGEN_CC_OPT", "-O2")  # the shipped flags: a warning fails the build
    shipped = vcigen.build(model, backend="c", rule=rule).simulate(**run, sensitivities=True, progress=False)
    monkeypatch.setattr(cbackend, "render", render)
    monkeypatch.setenv("VCIGEN_CC_OPT", SUITE)
    suite = vcigen.build(model, backend="c", rule=rule).simulate(**run, sensitivities=True, progress=False)
    assert [c["sens"] for c in seen] == [False, True]
    CONTEXTS[scene] = seen
    for ctx in seen:  # and at -O3 (its -Wmaybe-uninitialized sees further than -O2's), warning-free
        paths = cbackend.write(render(ctx), tmp_path / f"sens{ctx['sens']}")
        source = next(str(p) for p in paths if p.suffix == ".c")
        flags = [f for f in cbackend.CFLAGS if f not in ("-O2", "-shared")]
        proc = subprocess.run(
            ["cc", *flags, "-O3", "-c", source, "-o", os.devnull], capture_output=True, text=True
        )
        assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert shipped.t.size > 10 and np.isfinite(shipped.q).all()
    assert fingerprint(suite) == fingerprint(shipped), f"{scene}: {SUITE} and -O2 give different numbers"


def test_the_scenes_take_every_template_condition_both_ways() -> None:
    """Every condition of the library templates is true for one of the contexts compiled at -O2 above and
    false for another (a branch no scene takes would go unchecked at -O2)."""
    if set(CONTEXTS) != set(CASES):
        pytest.skip("needs every scene's test above (run the whole file)")
    env = jinja2.Environment(undefined=jinja2.StrictUndefined)
    contexts = [c for ctxs in CONTEXTS.values() for c in ctxs]
    one_way = {}
    for cond in conditions():
        values = {_value(env, cond, c) for c in contexts}
        if values != {None}:
            assert None not in values, cond
            if values != {True, False}:
                one_way[cond] = values
    assert one_way.keys() == ONE_WAY.keys(), f"conditions taken one way only: {one_way}; known: {ONE_WAY}"


def test_the_level_is_validated_and_keys_the_cache(tmp_path: Path, monkeypatch) -> None:
    files = {"tiny.c": "double tiny_one(void) { return 1.0; }\n"}
    monkeypatch.delenv("VCIGEN_CC_OPT", raising=False)
    assert cbackend.cflags() == cbackend.CFLAGS and "-O2" in cbackend.CFLAGS
    shipped = cbackend.build_library(files, "tiny", cache=tmp_path)
    for level in cbackend.OPT_LEVELS:
        monkeypatch.setenv("VCIGEN_CC_OPT", level)
        flags = cbackend.cflags()
        assert [f for f in flags if f.startswith("-O")] == [level]
        assert [f for f in flags if not f.startswith("-O")] == [f for f in cbackend.CFLAGS if f != "-O2"]
        lib = cbackend.build_library(files, "tiny", cache=tmp_path)
        assert (lib == shipped) == (level == "-O2")
    for bad in ("-Ofast", "-O1", "-O3", "O0", "0", "-O2 -ffast-math"):
        monkeypatch.setenv("VCIGEN_CC_OPT", bad)
        with pytest.raises(ValueError, match="VCIGEN_CC_OPT.*-O0, -O2"):
            cbackend.build_library(files, "tiny", cache=tmp_path / "bad")
    assert not (tmp_path / "bad").exists()
