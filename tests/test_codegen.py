"""Code generation: generated/ is reproducible, compiles warning-free, runs, and holds only the scene.

Two tiers, as SymPy's codegen tests: string checks without a compiler, then
compile-and-run with ``cc -std=c99 -O2 -Wall -Wextra -Werror ... -lm`` (and at ``-O3``).
"""

from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
from pathlib import Path

import jinja2
import numpy as np
import pytest
import sympy as sp

import vcigen
from vcigen.backends import c as cbackend
from vcigen.backends.ccontext import NEWTON, render_context
from vcigen.cli import find_examples, generate_example, main
from vcigen.rules import C_RULES

ROOT = Path(__file__).resolve().parents[1]
GENERATED = ROOT / "generated"
EXAMPLES = find_examples(ROOT / "examples")
CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"]
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


def _target(example: Path) -> Path:
    return GENERATED / example.relative_to(ROOT / "examples").with_suffix("")


def _generated_dirs() -> list[Path]:
    """The generated folders, each example's trapezoid (the default rule) before its midpoint."""
    return sorted(
        (p.parent for p in GENERATED.rglob("Makefile")), key=lambda d: (d.parent, d.name != "trapezoid")
    )


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.stem)
def test_generated_matches_a_fresh_generation(example: Path, tmp_path: Path) -> None:
    """``vcigen generate --all`` reproduces the checked-in generated/ byte for byte."""
    fresh = sorted(generate_example(example, tmp_path))
    for path in fresh:
        stored = _target(example) / path.relative_to(tmp_path)
        assert stored.is_file(), f"{stored} is missing; run `vcigen generate --all`"
        assert stored.read_text() == path.read_text(), f"{stored} is stale; run `vcigen generate --all`"


def test_cli_single_example_one_rule(tmp_path: Path) -> None:
    assert (
        main(
            ["generate", str(ROOT / "examples" / "particle.py"), "--out", str(tmp_path), "--rule", "midpoint"]
        )
        == 0
    )
    assert sorted(p.name for p in (tmp_path / "midpoint").iterdir()) == [
        "Makefile",
        "main.c",
        "particle.c",
        "particle.h",
    ]
    assert not (tmp_path / "trapezoid").exists()


def test_sources_hold_only_the_scene_contacts() -> None:
    """Only the scene's contacts are emitted, and every C function is prefixed with the model name."""
    for d in _generated_dirs():
        model = next(d.glob("*.h")).stem
        text = (d / f"{model}.c").read_text()
        example = ROOT / "examples" / d.parent.relative_to(GENERATED).with_suffix(".py")
        contacts = set(vcigen.cli.load_example(example).model().phi)
        assert set(re.findall(rf"static inline void {model}_contact_time_(\w+)\(", text)) == contacts, d
        assert set(re.findall(rf"static inline void {model}_jump_contact_(\w+)\(", text)) == contacts, d
        functions = re.findall(r"^(?:static )?(?:inline )?(?:void|int|double) (\w+)\(", text, re.M)
        assert functions and all(f.startswith(model + "_") for f in functions), d


def test_two_contacts_emit_two_and_only_their_routines() -> None:
    x, y, xd, yd = sp.symbols("x y xd yd")
    model = vcigen.Model(
        name="box2",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - y,
        contacts={"left": x + 1, "right": 1 - x},
    )
    text = cbackend.render(render_context(vcigen.derive(model)))["box2.c"]
    assert set(re.findall(r"static inline void box2_contact_time_(\w+)\(", text)) == {"left", "right"}
    assert set(re.findall(r"static inline void box2_jump_contact_(\w+)\(", text)) == {"left", "right"}
    assert "floor" not in text


def test_specialisation_is_reported_and_follows_the_mass_matrix() -> None:
    r, th, rd, thd = sp.symbols("r theta rd thetad")
    polar = vcigen.Model(
        name="polar",
        q=[r, th],
        qdot=[rd, thd],
        lagrangian=(rd**2 + r**2 * thd**2) / 2 - r * sp.sin(th),
        contacts={"floor": r * sp.sin(th) + 2},
    )
    src = cbackend.render(render_context(vcigen.derive(polar)))["polar.c"]
    assert "configuration-dependent mass -> damped Newton" in src
    assert "Newton on (v, alpha)" in src
    particle = (GENERATED / "particle" / "trapezoid" / "particle.c").read_text()
    assert "diagonal Jacobian -> one division, no Newton" in particle
    assert "safeguarded scalar Newton on alpha" in particle


def test_the_free_glide_has_no_loop_over_coordinates() -> None:
    """The explicit free steps' loop (``<model>_glide``) writes its copies over the coordinates and rows out:
    at -O2 GCC keeps an array indexed in a loop in memory, and a particle's free step in three coordinates
    took 3.5 times as long (``bench/held_curved.py``'s sphere, stop 44)."""
    x, y, z, xd, yd, zd = sp.symbols("x y z xd yd zd")
    ball = vcigen.Model(
        name="cg_ball3",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 - 9.81 * z,
        contacts={"floor": z, "wall": 1 - x},
    )
    src = cbackend.render(render_context(vcigen.derive(ball)))["cg_ball3.c"]
    glide = src[src.index("static long cg_ball3_glide(") :]
    glide = glide[: glide.index("\n}\n")]
    assert [line.strip() for line in glide.splitlines() if line.strip().startswith("for (")] == [
        "for (s = 0; s < n; ++s) {"
    ]
    for i in range(3):
        assert f"q1[{i}] = q[{i}] + h * v[{i}];" in glide and f"Q[s * CG_BALL3_N + {i}] = q1[{i}];" in glide
    assert glide.count("clear &= ") == 2 and "d[1] = d1[1];" in glide


def test_newton_matches_the_casadi_options() -> None:
    from vcigen.backends.casadi import NEWTON_OPTIONS

    assert NEWTON == {
        "abstol": NEWTON_OPTIONS["abstol"],
        "abstol_step": NEWTON_OPTIONS["abstolStep"],
        "max_iter": NEWTON_OPTIONS["max_iter"],
    }


def test_half_integer_powers_print_with_sqrt_only_where_asked() -> None:
    """``sqrt_powers`` (the held rows, ``vcigen.held.SQRT_POWERS``) prints ``b^(k/2)`` as a product with
    ``sqrt(b)``, never libm's ``pow``; without it, and for other exponents, the printing is unchanged."""
    from vcigen.backends.ccontext import SQRT_POWERS
    from vcigen.backends.cprinter import ArrayC99Printer
    from vcigen.derive import derive

    X, Y, XD, YD = sp.symbols("x y xd yd")
    names = {X: "q[0]"}
    fast, plain = ArrayC99Printer(names, sqrt_powers=True), ArrayC99Printer(names)
    b = X**2 + 1
    assert fast.doprint(b ** sp.Rational(3, 2)) == "((((q[0])*(q[0])) + 1)*sqrt(((q[0])*(q[0])) + 1))"
    assert fast.doprint(X ** sp.Rational(-5, 2)) == "(1.0/((q[0])*(q[0])*sqrt(q[0])))"
    assert fast.doprint(X ** sp.Rational(1, 2)) == plain.doprint(X ** sp.Rational(1, 2)) == "sqrt(q[0])"
    assert fast.doprint(X ** sp.Rational(1, 3)) == plain.doprint(X ** sp.Rational(1, 3))
    assert "pow" in plain.doprint(b ** sp.Rational(3, 2))
    dome = vcigen.Model(
        name="cg_dome",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - 9.81 * Y,
        contacts={"dome": sp.sqrt(X**2 + Y**2) - 1},
    )
    system = derive(dome)
    ctx = {r["name"]: r for r in render_context(system)["routines"]}

    def text(r: dict) -> str:
        entries = [e["expr"] for o in r["outputs"] for e in o["entries"]]
        return " ".join([t["expr"] for t in r["temps"]] + entries)

    assert SQRT_POWERS == {"held_rows"} and "pow(" not in text(ctx["held_rows"])  # the Hessian has |q|^-3
    assert any("pow(" in text(r) for name, r in ctx.items() if name != "held_rows")  # elsewhere as before


NAMED_CONSTANTS = [
    sp.sqrt(2),
    1 / sp.sqrt(2),
    sp.pi / 4,
    sp.pi / 2,
    1 / sp.pi,
    2 / sp.pi,
    sp.log(2),
    1 / sp.log(2),
    sp.log(10),
    sp.E,
    2 / sp.sqrt(sp.pi),
]


def test_named_constants_print_as_c99_expressions_not_posix_macros() -> None:
    """SymPy's C printer writes sqrt(2), pi/4, log(2), ... as ``M_SQRT2``, ``M_PI_4``, ``M_LN2``: POSIX,
    undeclared under ``-std=c99``. The printer writes the expressions they stand for."""
    from vcigen.backends.cprinter import ArrayC99Printer

    X = sp.Symbol("x")
    printer = ArrayC99Printer({X: "q[0]"})
    for c in NAMED_CONSTANTS:
        text = printer.doprint(c * X)
        assert "M_" not in text, (c, text)
        assert float(eval(text.replace("q[0]", "1.0"), {"sqrt": np.sqrt, "log": np.log})) == pytest.approx(
            float(c)
        )


@needs_cc
def test_a_model_with_named_constants_compiles_and_takes_casadis_steps() -> None:
    """A particle on a 45-degree rough incline written with ``sqrt(2)`` (its friction tangent), in a
    potential with the other named constants: it did not compile (``M_SQRT1_2`` undeclared); it now takes
    CasADi's steps."""
    X, Y, XD, YD = sp.symbols("x y xd yd")
    k = sum(NAMED_CONSTANTS) / 10
    model = vcigen.Model(
        name="cg_constants",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - 9.81 * Y - k * (X - sp.sqrt(2) / 2) ** 2 / 2,
        contacts={"incline": (Y - X) / sp.sqrt(2)},
        restitution={"incline": sp.log(2)},
        friction={"incline": (1 / sp.pi, (X + Y) / sp.sqrt(2))},
    )
    runs = [
        vcigen.build(model, backend=b).simulate(q0=[0.0, 0.5], v0=[1.0, 0.0], h=0.01, t_end=2.0)
        for b in ("c", "casadi")
    ]
    assert len(runs[0].impacts) > 1 and runs[0].active[-1].any()  # it lands, bounces, and slides held
    assert [(i.kind, i.step) for i in runs[0].impacts] == [(i.kind, i.step) for i in runs[1].impacts]
    assert np.abs(runs[0].q - runs[1].q).max() < 1e-10


def test_templates_are_strict() -> None:
    ctx = render_context(vcigen.derive(vcigen.cli.load_example(ROOT / "examples" / "particle.py").model()))
    del ctx["hash"]
    with pytest.raises(jinja2.UndefinedError):
        cbackend.render(ctx)


def test_templates_found_in_the_package_or_the_repository() -> None:
    assert (cbackend.template_dir() / "stepper.c.j2").is_file()


# digests of the preprocessed sources (comments stripped) of the generated folders compiled in this worker
_COMPILED: set[str] = set()


def _preprocessed(gen_dir: Path, model: str) -> str:
    """The digest of ``main.c`` and ``<model>.c`` of ``gen_dir`` through the preprocessor alone (``cc -E
    -P``): the text the compiler sees, without the comments that name the rule."""
    digest = hashlib.sha256()
    for name in ("main.c", f"{model}.c"):
        run = subprocess.run(["cc", "-E", "-P", name], cwd=gen_dir, capture_output=True, check=True)
        digest.update(run.stdout + b"\0")
    return digest.hexdigest()


@needs_cc
@pytest.mark.parametrize("gen_dir", _generated_dirs(), ids=lambda p: f"{p.parent.name}-{p.name}")
def test_generated_compiles_warning_free_and_runs(gen_dir: Path, tmp_path: Path) -> None:
    """At the shipped -O2 and, for the default rule's folder (trapezoid) of each example, at -O3 (what users
    who want speed pass; its -Wmaybe-uninitialized sees further than -O2's), warning-free and with the same
    numbers: -std=c99 contracts nothing into FMA and neither level reassociates, so -O3's unrolling and
    vectorising change the speed alone. -O3 on one rule of each example, not both: its warnings come from the
    templates' code, which the two rules share (test_shipped_flags compiles every branch of the library
    templates at -O3 too); the two compiles were a third of the suite's compiler time. A folder whose
    preprocessed sources are those of one compiled before (a linear model's two rules: the same expressions,
    comments naming the rule aside; the trapezoid's comes first) is not compiled again."""
    model = next(gen_dir.glob("*.h")).stem
    text = _preprocessed(gen_dir, model)
    if text in _COMPILED:
        return  # compiled, warning-free and run as an earlier folder (this test, parametrized before)
    levels = ("-O2", "-O3") if gen_dir.name == "trapezoid" else ("-O2",)
    outputs = []
    for level in levels:
        exe = tmp_path / f"{model}{level}"
        flags = [level if f == "-O2" else f for f in CFLAGS]
        proc = subprocess.run(
            ["cc", *flags, "-o", str(exe), str(gen_dir / "main.c"), str(gen_dir / f"{model}.c"), "-lm"],
            capture_output=True,
            text=True,
        )
        assert proc.returncode == 0 and proc.stderr == "", (level, proc.stderr)
        out = tmp_path / f"run{level}"
        run = subprocess.run(
            [str(exe), "--t-end", "1.0", "--out", str(out)], capture_output=True, text=True, timeout=60
        )
        assert run.returncode == 0, run.stderr
        rows = (tmp_path / f"run{level}.csv").read_text().splitlines()
        assert rows[0].startswith("t,") and rows[0].endswith(",energy")
        assert len(rows) > 10
        impacts = (tmp_path / f"run{level}_impacts.csv").read_text()
        assert impacts.startswith("t,contact,step,alpha,impulse")
        outputs.append((rows, impacts))
    assert outputs[-1] == outputs[0], "-O3 gives other numbers than -O2"
    _COMPILED.add(text)


@needs_cc
def test_driver_reports_a_bad_start() -> None:
    gen_dir = GENERATED / "particle" / "trapezoid"
    with pytest.raises(subprocess.CalledProcessError) as info:
        subprocess.run(["make", "-s", "-C", str(gen_dir), "particle"], check=True, capture_output=True)
        subprocess.run(
            [str(gen_dir / "particle"), "--q0", "0,-1", "--t-end", "1"],
            check=True,
            capture_output=True,
            cwd=gen_dir,
        )
    subprocess.run(["make", "-s", "-C", str(gen_dir), "clean"], capture_output=True)
    assert b"violates contact 'floor'" in info.value.stderr


@needs_cc
def test_driver_help_and_bad_arguments(tmp_path: Path) -> None:
    gen_dir = GENERATED / "star" / "trapezoid"
    exe = tmp_path / "star"
    subprocess.run(
        ["cc", *CFLAGS, "-o", str(exe), str(gen_dir / "main.c"), str(gen_dir / "star.c"), "-lm"], check=True
    )
    helped = subprocess.run([str(exe), "--help"], capture_output=True, text=True, cwd=tmp_path)
    assert helped.returncode == 0
    assert "coordinates: x y theta; contacts: floor" in helped.stdout and "m=1 g=9.81 L=1" in helped.stdout
    for bad in (
        ["--h", "0.0x1"],
        ["--param", "g=abc"],
        ["--param", "nope=1"],
        ["--q0", "0,1"],
        ["--n-impacts", "-2"],
    ):
        run = subprocess.run([str(exe), *bad], capture_output=True, text=True, cwd=tmp_path)
        assert run.returncode == 1 and "bad argument" in run.stderr, (bad, run.stderr)
    assert not list(tmp_path.glob("*.csv"))  # nothing was run


def test_missing_compiler_is_a_compile_error(tmp_path: Path) -> None:
    model = vcigen.cli.load_example(ROOT / "examples" / "particle.py").model()
    with pytest.raises(vcigen.CompileError, match="not found"):
        vcigen.build(model, backend="c", cc="no-such-compiler-vcigen", cache=tmp_path)


@needs_cc
def test_failing_compiler_is_a_compile_error_with_its_message(tmp_path: Path) -> None:
    fake = tmp_path / "fakecc"
    fake.write_text("#!/bin/sh\necho 'fakecc: error: out of cheese' >&2\nexit 1\n")
    fake.chmod(0o755)
    model = vcigen.cli.load_example(ROOT / "examples" / "particle.py").model()
    with pytest.raises(vcigen.CompileError, match="out of cheese"):
        vcigen.build(model, backend="c", cc=str(fake), cache=tmp_path / "cache")


def test_every_rule_is_generated() -> None:
    for example in EXAMPLES:
        assert sorted(p.name for p in _target(example).iterdir()) == sorted(C_RULES)
