"""The README's Python examples run as written, top to bottom in one session, as a newcomer would paste them
(each block may use the names the blocks before it defined)."""

from __future__ import annotations

import contextlib
import io
import re
import warnings
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parents[1] / "README.md"


def blocks() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", README.read_text(encoding="utf-8"), flags=re.S | re.M)


def test_the_readme_examples_run_in_order() -> None:
    code = blocks()
    assert len(code) >= 9
    ns: dict = {"__name__": "readme"}
    with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for i, block in enumerate(code):
            try:
                exec(compile(block, f"README.md python block {i + 1}", "exec"), ns)
            except Exception as exc:  # name the block: the traceback's file is the block
                raise AssertionError(f"README python block {i + 1} fails: {exc!r}\n{block}") from exc
    # what the last blocks promise: 8 runs, swept and kept in order, and a tangent of the ball's run
    assert len(ns["results"]) == 8 and len(ns["rest"]) == 8
    assert ns["rest"] == [r.impacts[-1].t for r in ns["results"]]
    assert ns["res"].sensitivity.shape == (ns["res"].t.size, 4, 4 + 1)
    assert np.isfinite(ns["res"].sensitivity[: np.argmax(ns["res"].active[:, 0]) or None]).all()
