"""The wall time of a run as the benches of forced and frictional scenes take it: the best of a few."""

from __future__ import annotations

import math
import time


def best_of(fn, *args, repeats: int = 3, **kw):
    """``(fn(*args, **kw), best wall time in s)`` over ``repeats`` calls (the last call's result)."""
    out, best = None, math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn(*args, **kw)
        best = min(best, time.perf_counter() - start)
    return out, best
