"""``vcigen`` on the command line.

``vcigen generate examples/star.py --out generated/star`` imports the example file,
calls its ``model()`` and writes standalone C (model, driver, Makefile) for every
rule into ``generated/star/<rule>/`` (``--rule`` picks one). The driver's default
start state is the example's ``SETUP``. ``vcigen generate --all`` regenerates
``generated/`` for every ``examples/**/*.py`` in one command; the text is
deterministic (no timestamps; a model hash is stamped instead).

``vcigen simulate examples/particle.py --h 0.005 --t-end 3 --out results`` builds the file's
``model()`` (C backend by default), runs it from the file's ``SETUP`` (every entry overridable:
``--q0``, ``--v0``, ``--h``, ``--t-end``, ``--n-impacts``, ``--param NAME=VALUE``), writes the
trajectory and impact CSVs and the energy plot into ``--out`` and prints the summary line.
Bad input (a missing file, no ``model()``, an inadmissible start, a bad number) prints a message
and exits with status 1, as does a run that cannot be solved.
"""

from __future__ import annotations

import argparse
import importlib.util
import runpy
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from .derive import derive
from .errors import CompileError, SolverError
from .rules import C_RULES, RULES


def load_example(path: str | Path) -> ModuleType:
    """Import an example file by path; it must define ``model()`` (and may define ``SETUP``)."""
    path = Path(path)
    if not path.is_file():
        raise SystemExit(f"vcigen: no such example file: {path}")
    name = "vcigen_example_" + "_".join(path.with_suffix("").parts[-2:]).replace("-", "_")
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    folder = str(path.resolve().parent)  # an example may import its folder's helpers (_common.py)
    sys.path.insert(0, folder)
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - any failure to import the user's file is reported
        raise SystemExit(f"vcigen: cannot import {path}: {type(exc).__name__}: {exc}") from exc
    finally:
        sys.path.remove(folder)
    if not callable(getattr(module, "model", None)):
        raise SystemExit(f"vcigen: {path} does not define model() -> vcigen.Model")
    return module


def generate_example(path: str | Path, out: str | Path, rules: Sequence[str] = C_RULES) -> list[Path]:
    """Write ``<out>/<rule>/`` (model, driver, Makefile) for the example at ``path``."""
    from .backends.c import generate

    module = load_example(path)
    model = module.model()
    setup = getattr(module, "SETUP", None)
    written = []
    for rule in rules:
        written += generate(derive(model, rule), Path(out) / rule, setup)
    return written


def find_examples(root: str | Path) -> list[Path]:
    """Every example file under ``root`` that defines ``model()`` (not ``_*.py``), sorted."""
    return sorted(
        p
        for p in Path(root).rglob("*.py")
        if not p.name.startswith("_") and "\ndef model(" in p.read_text(encoding="utf-8")
    )


def _generate(args: argparse.Namespace) -> int:
    rules = [args.rule] if args.rule else list(C_RULES)
    if args.all:
        root = Path(args.examples)
        jobs = [
            (p, Path(args.out or "generated") / p.relative_to(root).with_suffix(""))
            for p in find_examples(root)
        ]
    elif args.example:
        if args.out is None:
            raise SystemExit("vcigen generate: give --out DIR for a single example")
        jobs = [(Path(args.example), Path(args.out))]
    else:
        raise SystemExit("vcigen generate: give an example file or --all")
    for path, out in jobs:
        files = generate_example(path, out, rules)
        print(f"{path} -> {out} ({len(files)} files, rules: {', '.join(rules)})")
    return 0


def _setup(module: ModuleType, args: argparse.Namespace) -> dict:
    """The example's ``SETUP`` with the command line's overrides: the keywords of ``simulate``."""
    run = dict(getattr(module, "SETUP", None) or {})
    for key in ("q0", "v0", "h"):
        if getattr(args, key) is not None:
            run[key] = getattr(args, key)
    if args.t_end is not None or args.n_impacts is not None:  # the command line says when to stop
        run.pop("t_end", None)
        run.pop("n_impacts", None)
        run.update({k: v for k, v in (("t_end", args.t_end), ("n_impacts", args.n_impacts)) if v is not None})
    if args.param:
        run["params"] = {**run.get("params", {}), **dict(args.param)}
    missing = [k for k in ("q0", "v0", "h") if k not in run]
    if missing:
        raise ValueError(
            f"no {', '.join(missing)}: the file has no SETUP giving them; pass "
            + " ".join(f"--{k.replace('_', '-')}" for k in missing)
        )
    return run


def _simulate(args: argparse.Namespace) -> int:
    from .demo import write_run
    from .simulator import build

    module = load_example(args.file)
    try:
        model = module.model()
        run = _setup(module, args)
        sim = build(model, backend=args.backend, rule=args.rule)
        res = sim.simulate(**run, progress=True)
    except (ValueError, SolverError, CompileError) as exc:
        raise SystemExit(f"vcigen simulate: {args.file}: {exc}") from exc
    write_run(args.name or model.name, res, args.out, args.backend, args.rule, run["h"])
    return 0


def _param(text: str) -> tuple[str, float]:
    name, eq, value = text.partition("=")
    try:
        if not eq or not name.strip():
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not NAME=NUMBER") from None


class _Parser(argparse.ArgumentParser):
    """``argparse`` that exits with status 1 (not 2) on bad arguments, like every other bad input."""

    def error(self, message: str):
        self.print_usage(sys.stderr)
        self.exit(1, f"{self.prog}: error: {message}\n")


def _add_simulate(sub) -> None:
    sim = sub.add_parser(
        "simulate",
        help="run a model file: CSV, energy plot and summary line",
        description="Build FILE's model() and run it from FILE's SETUP (each entry overridable "
        "below); write <out>/<name>_<backend>_<rule>.csv, ..._impacts.csv and ..._energy.png and "
        "print the summary line. Exit status 1 on bad input or a failed solve.",
    )
    sim.add_argument("file", help="a Python file defining model() -> vcigen.Model (and optionally SETUP)")
    sim.add_argument("--h", type=float, help="time step (default: SETUP['h'])")
    sim.add_argument("--t-end", type=float, help="stop at this time (replaces SETUP's stopping rule)")
    sim.add_argument("--n-impacts", type=int, help="stop after this many impacts (with or without --t-end)")
    sim.add_argument("--q0", type=float, nargs="+", help="start positions (default: SETUP['q0'])")
    sim.add_argument("--v0", type=float, nargs="+", help="start velocities (default: SETUP['v0'])")
    sim.add_argument(
        "--param", type=_param, action="append", metavar="NAME=VALUE", help="a parameter value (repeatable)"
    )
    sim.add_argument("--backend", default="c", choices=["c", "casadi"], help="default: c")
    sim.add_argument("--rule", default="trapezoid", choices=sorted(RULES), help="default: trapezoid")
    sim.add_argument("--out", default="results", help="folder for the CSVs and the plot (default: results)")
    sim.add_argument("--name", help="file stem (default: the model's name)")
    sim.set_defaults(func=_simulate)


def parser() -> argparse.ArgumentParser:
    """The argument parser (subcommands: ``generate``, ``simulate``, ``bench``)."""
    top = _Parser(prog="vcigen", description="Variational collision integrators from SymPy models.")
    sub = top.add_subparsers(dest="command", required=True)
    _add_simulate(sub)
    gen = sub.add_parser("generate", help="write standalone C for an example (or all of them)")
    gen.add_argument("example", nargs="?", help="an example file defining model() and optionally SETUP")
    gen.add_argument(
        "--out", help="output directory (one subdirectory per rule); default generated/ with --all"
    )
    gen.add_argument("--rule", choices=sorted(RULES), help="only this rule (default: trapezoid, midpoint)")
    gen.add_argument("--all", action="store_true", help="every example under --examples into generated/")
    gen.add_argument("--examples", default="examples", help="examples folder for --all (default: examples)")
    gen.set_defaults(func=_generate)
    ben = sub.add_parser("bench", help="speed against error, side by side (runs bench/run.py of a checkout)")
    ben.add_argument("rest", nargs=argparse.REMAINDER, help="arguments passed on to bench/run.py")
    ben.set_defaults(func=_bench)
    return top


def _bench(args: argparse.Namespace) -> int:
    """Run ``bench/run.py`` of the source checkout (the benchmark is not installed)."""
    script = Path.cwd() / "bench" / "run.py"
    if not script.exists():
        script = Path(__file__).resolve().parents[1] / "bench" / "run.py"
    if not script.exists():
        raise SystemExit(
            "vcigen bench needs a source checkout: bench/run.py not found here or beside vcigen/"
        )
    sys.argv = [str(script), *args.rest]
    runpy.run_path(str(script), run_name="__main__")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """The ``vcigen`` console script: 0 on success, 1 (and a message on stderr) on bad input."""
    args = parser().parse_args(argv)
    try:
        return int(args.func(args))
    except SystemExit as exc:
        if not isinstance(exc.code, str):
            raise
        print(exc.code, file=sys.stderr)
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
