"""``vcigen`` on the command line.

``vcigen generate examples/star.py --out generated/star`` imports the example file,
calls its ``model()`` and writes standalone C (model, driver, Makefile) for every
rule into ``generated/star/<rule>/`` (``--rule`` picks one). The driver's default
start state is the example's ``SETUP``. ``vcigen generate --all`` regenerates
``generated/`` for every ``examples/**/*.py`` in one command; the text is
deterministic (no timestamps; a model hash is stamped instead).
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
from .rules import RULES


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
    finally:
        sys.path.remove(folder)
    if not callable(getattr(module, "model", None)):
        raise SystemExit(f"vcigen: {path} does not define model() -> vcigen.Model")
    return module


def generate_example(path: str | Path, out: str | Path, rules: Sequence[str] = tuple(RULES)) -> list[Path]:
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
    rules = [args.rule] if args.rule else list(RULES)
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


def parser() -> argparse.ArgumentParser:
    """The argument parser (subcommands: ``generate``, ``bench``)."""
    top = argparse.ArgumentParser(
        prog="vcigen", description="Variational collision integrators from SymPy models."
    )
    sub = top.add_subparsers(dest="command", required=True)
    gen = sub.add_parser("generate", help="write standalone C for an example (or all of them)")
    gen.add_argument("example", nargs="?", help="an example file defining model() and optionally SETUP")
    gen.add_argument(
        "--out", help="output directory (one subdirectory per rule); default generated/ with --all"
    )
    gen.add_argument("--rule", choices=sorted(RULES), help="only this rule (default: every rule)")
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
    """Entry point of the ``vcigen`` console script."""
    args = parser().parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    raise SystemExit(main())
