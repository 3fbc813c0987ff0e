"""The C backend: routines -> render context -> Jinja2 templates -> files -> ``cc`` -> ctypes.

Separate, separately callable steps:

* :func:`render` -- pure: a :class:`~vcigen.derive.DiscreteSystem` to ``{filename: text}``;
* :func:`write` -- the text to a directory (``vcigen generate``);
* :func:`build_library` -- compile the model source into a shared library, cached by a
  hash of the source and the compiler command (``VCIGEN_CACHE`` or ``~/.cache/vcigen``), at the
  optimisation level :func:`cflags` reads from ``VCIGEN_CC_OPT`` (default ``-O2``);
* :func:`build_c` -- all of it, wrapped as a :class:`~vcigen.simulator.Simulator`.
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
import threading
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import jinja2

from ..csememo import cache_root
from ..derive import DiscreteSystem
from ..errors import CompileError
from ..stepper import Tolerances
from .ccontext import render_context

# template -> output file name ({model} is the model's name)
TEMPLATES = {
    "model.h.j2": "{model}.h",
    "model.c.j2": "{model}.c",
    "main.c.j2": "main.c",
    "Makefile.j2": "Makefile",
}
LIBRARY_TEMPLATES = ("model.h.j2", "model.c.j2")
CFLAGS = ("-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared")  # the shipped flags
# VCIGEN_CC_OPT: the optimisation levels build_library accepts in place of CFLAGS' -O2. Both give the same
# floating-point results bit for bit on x86-64 (SSE2, no FMA contraction under -std=c99, no -ffast-math): only
# the compile and run times differ. make test builds at -O0 (the compiler's time a fifth of -O2's; the shipped
# -O2 -Werror is held by tests/test_shipped_flags.py). Not offered: -O1, where GCC 12's -Wmaybe-uninitialized
# reports false positives that -O2 does not (an error under -Werror), and -Ofast/-ffast-math (other numbers).
OPT_LEVELS = ("-O0", "-O2")


def cflags() -> tuple[str, ...]:
    """:data:`CFLAGS` with ``-O2`` replaced by ``$VCIGEN_CC_OPT`` (one of :data:`OPT_LEVELS`) if it is set."""
    level = os.environ.get("VCIGEN_CC_OPT", "")
    if not level:
        return CFLAGS
    if level not in OPT_LEVELS:
        raise ValueError(
            f"VCIGEN_CC_OPT = {level!r} is not an optimisation level vcigen builds at; "
            f"set one of {', '.join(OPT_LEVELS)} or unset it (the default, -O2)"
        )
    return tuple(level if flag == "-O2" else flag for flag in CFLAGS)


def template_dir() -> Path:
    """``vcigen/templates`` in an installed wheel, else the repository's top-level ``templates/``."""
    here = Path(__file__).resolve().parent.parent
    for cand in (here / "templates", here.parent / "templates"):
        if (cand / "model.c.j2").is_file():
            return cand
    raise FileNotFoundError(
        f"vcigen templates not found in {here / 'templates'} or {here.parent / 'templates'}"
    )


@functools.cache
def environment() -> jinja2.Environment:
    """Jinja2 with StrictUndefined: a name missing from the context is an error, never blank text. One per
    process: it keeps the templates it compiled (a template changed on disk is compiled again, the loader's
    ``auto_reload``); compiling them anew for every build was a quarter of a C build's time in the suite
    (``tests/test_held_quadric.py``: 8.8 of its 38 s under cProfile)."""
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(template_dir())),
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
        autoescape=False,
    )


def render(ctx: Mapping[str, Any], templates: Sequence[str] = tuple(TEMPLATES)) -> dict[str, str]:
    """Render ``templates`` from a :func:`~vcigen.backends.ccontext.render_context`; ``{file name: text}``."""
    env = environment()
    return {TEMPLATES[t].format(model=ctx["model"]): env.get_template(t).render(**ctx) for t in templates}


def write(files: Mapping[str, str], out: str | Path) -> list[Path]:
    """Write rendered files into ``out`` (created); returns the paths. Each file is written whole under a
    temporary name and moved into place: a compiler reading it while another process builds the same sources
    into the same cache directory (the workers of a sweep) never sees it cut short."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, text in files.items():
        path = out / name
        tmp = out / f".{name}.{os.getpid()}.{threading.get_ident()}"
        tmp.write_text(text)
        os.replace(tmp, path)
        paths.append(path)
    return paths


def build_library(
    files: Mapping[str, str], model: str, cc: str | None = None, cache: str | Path | None = None
) -> Path:
    """Compile ``<model>.c`` into ``lib<model>.so`` in a directory named by the sources' hash.

    The flags are :func:`cflags` (``VCIGEN_CC_OPT``), part of the hash. Raises
    :class:`~vcigen.errors.CompileError` with the compiler's message if the compiler is missing
    or fails, and ValueError for a bad ``VCIGEN_CC_OPT``.
    """
    flags = cflags()
    cc = cc or os.environ.get("CC", "cc")
    exe = shutil.which(cc)
    if exe is None:
        raise CompileError(f"C compiler {cc!r} not found; install one (e.g. gcc) or pass cc=... / set CC")
    digest = hashlib.sha256(
        "\0".join([cc, *flags, *(f"{k}\0{v}" for k, v in sorted(files.items()))]).encode()
    )
    where = Path(cache or cache_root()) / digest.hexdigest()[:24]
    lib = where / f"lib{model}.so"
    if lib.is_file():
        return lib
    where.mkdir(parents=True, exist_ok=True)
    write(files, where)
    with tempfile.NamedTemporaryFile(dir=where, suffix=".so", delete=False) as tmp:
        tmp_lib = Path(tmp.name)
    cmd = [exe, *flags, "-o", str(tmp_lib), str(where / f"{model}.c"), "-lm"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.SubprocessError) as exc:
        tmp_lib.unlink(missing_ok=True)
        raise CompileError(f"running {' '.join(cmd)} failed: {exc}") from exc
    if proc.returncode != 0:
        tmp_lib.unlink(missing_ok=True)
        raise CompileError(f"{' '.join(cmd)} failed (exit {proc.returncode}):\n{proc.stderr.strip()}")
    tmp_lib.replace(lib)  # atomic: concurrent builds of the same hash are harmless
    return lib


def generate(system: DiscreteSystem, out: str | Path, setup: Mapping[str, Any] | None = None) -> list[Path]:
    """Write the standalone sources (model, driver, Makefile) of ``system`` into ``out``."""
    return write(render(render_context(system, setup)), out)


def build_c(
    system: DiscreteSystem,
    tol: Tolerances | None = None,
    cc: str | None = None,
    cache: str | Path | None = None,
):
    """Render, compile (cached) and load ``system``: a simulator running the whole loop in C."""
    from .cwrap import CKernels, CSimulator

    tol = tol or Tolerances()
    ctx = render_context(system, None, tol)
    files = render(ctx, LIBRARY_TEMPLATES)
    lib = build_library(files, ctx["model"], cc=cc, cache=cache)
    return CSimulator(system, CKernels(system, lib, ctx), tol, build={"cc": cc, "cache": cache})
