"""Sensitivities through two slipping cones of one body: the figures of README *Sensitivities of a run*.

    .venv/bin/python bench/sensitivity_cone_rod.py

The rod of ``tests/test_friction_cone_rod.py`` (lying on two rough ends of a 3-D floor, each an isotropic
cone) launched at v0 = (1.2, -0.9) with a yaw rate 0.8, h = 0.01: both cones slip, their directions aimed
anew every step from the state and turning with the rod (``Tracker._cone_slots``, C ``sens_cone_slots``).
Printed per backend: to t = 0.25 the tangent against central differences (eps = 1e-6) of whole runs for
every column but the normal ones (z, theta and their rates lift an end), relative to the largest entry; and
to t = 1 (through the stop) the first break and its reason; then C against CasADi to t = 1.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_friction_cone_rod import PHI0, sim  # noqa: E402

H = 0.01
Q0, V0 = [0.0, 0.0, 0.0, PHI0, 0.0], [1.2, -0.9, 0.0, 0.8, 0.0]


def fd_errors(backend: str, t_end: float = 0.25) -> dict[str, float]:
    s = sim(backend)
    names = [str(p) for p in s.model.defaults]
    values = dict(zip(names, s.model.resolve_params(None)))
    res = s.simulate(Q0, V0, H, t_end=t_end, params=values, sensitivities=True, progress=False)
    assert res.sensitivity_breaks == [], res.sensitivity_breaks
    cols = [0, 1, 3, 5, 6, 8] + [10 + names.index(k) for k in ("m", "g", "mu", "l")]
    out = {}
    scale = float(np.abs(res.sensitivity[:, :, cols]).max())
    for c in cols:
        ends = []
        for sign in (1.0, -1.0):
            q, v, p = list(Q0), list(V0), dict(values)
            if c < 5:
                q[c] += sign * 1e-6
            elif c < 10:
                v[c - 5] += sign * 1e-6
            else:
                p[names[c - 10]] += sign * 1e-6
            r = s.simulate(q, v, H, t_end=t_end, params=p, progress=False)
            ends.append(np.hstack([r.q, r.p]))
        fd = (ends[0] - ends[1]) / 2e-6
        out[res.sensitivity_names[c]] = float(np.abs(res.sensitivity[:, :, c] - fd).max()) / scale
    return out


def main() -> None:
    runs = {}
    for backend in ("casadi", "c"):
        errs = fd_errors(backend)
        print(
            f"{backend}: FD to t = 0.25, worst {max(errs.values()):.1e}: "
            + ", ".join(f"{k} {v:.1e}" for k, v in errs.items())
        )
        runs[backend] = sim(backend).simulate(Q0, V0, H, t_end=1.0, sensitivities=True, progress=False)
        print(f"{backend}: to t = 1, first break {runs[backend].sensitivity_breaks[:1]}")
    a, b = runs["casadi"].sensitivity, runs["c"].sensitivity
    fin = np.isfinite(a)
    same = (
        np.array_equal(fin, np.isfinite(b))
        and runs["casadi"].sensitivity_breaks == runs["c"].sensitivity_breaks
    )
    rel = float(np.abs(a[fin] - b[fin]).max() / np.abs(a[fin]).max())
    print(f"C against CasADi to t = 1: {rel:.1e} (same breaks and NaN: {same})")


if __name__ == "__main__":
    main()
