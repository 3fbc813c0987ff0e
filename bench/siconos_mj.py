"""Siconos Moreau–Jean (theta = 1/2, e = 1) on the particle and the star.

Runs under Debian's ``/usr/bin/python3`` (package ``python3-siconos``), not the
venv: ``/usr/bin/python3 bench/siconos_mj.py < request.json > result.json``.
Request: ``{"scene": "particle"|"star", "h", "t_end", "n_impacts", "q0", "v0"}``.
Result: ``{"t", "q", "v", "impacts", "wall"}`` (a list of requests gives a list of
results); ``impacts`` are the ends of the
steps whose contact impulse ``lambda(1)`` is positive.

The star's contact ``phi`` (eq. 81) is the minimum of four smooth vertex heights
``y - L/2 (c cos th + s sin th)``, ``c, s = +-1``; each is one Siconos interaction.
"""

from __future__ import annotations

import json
import math
import sys
import time

import numpy as np
import siconos.kernel as sk

G = 9.81
L = 1.0
INERTIA = 29.0 / 192.0


class _Vertex(sk.LagrangianScleronomousR):
    """Height of one star vertex; the Jacobian is written in place (setJachqPtr segfaults)."""

    def __init__(self, c: float, s: float) -> None:
        sk.LagrangianScleronomousR.__init__(self)
        self.c, self.s = c, s
        self.setJachqPtr(np.zeros((1, 3)))

    def computeh(self, q, z, y) -> None:  # noqa: N802 (Siconos API)
        y[0] = q[1] - L / 2 * (self.c * math.cos(q[2]) + self.s * math.sin(q[2]))

    def computeJachq(self, q, z) -> None:  # noqa: N802
        jac = self.jachq()
        jac[0, 0] = 0.0
        jac[0, 1] = 1.0
        jac[0, 2] = -L / 2 * (-self.c * math.sin(q[2]) + self.s * math.cos(q[2]))

    def computeDotJachq(self, q, z, qdot) -> None:  # noqa: N802
        pass


def run(req: dict) -> dict:
    """Integrate one request; returns plain lists."""
    h, t_end, n_imp = req["h"], req.get("t_end"), req.get("n_impacts")
    t_max = t_end if t_end is not None else 1e6
    if req["scene"] == "particle":
        ds = sk.LagrangianLinearTIDS(req["q0"], req["v0"], np.eye(2))
        ds.setFExtPtr([0.0, -G])
        rels = [sk.LagrangianLinearTIR(np.array([[0.0, 1.0]]))]
    elif req["scene"] == "star":
        ds = sk.LagrangianLinearTIDS(req["q0"], req["v0"], np.diag([1.0, 1.0, INERTIA]))
        ds.setFExtPtr([0.0, -G, 0.0])
        rels = [_Vertex(c, s) for c, s in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
    else:
        raise ValueError(f"siconos_mj: no scene {req['scene']!r}")
    nsds = sk.NonSmoothDynamicalSystem(0.0, t_max)
    nsds.insertDynamicalSystem(ds)
    inters = [sk.Interaction(sk.NewtonImpactNSL(1.0), r) for r in rels]
    for inter in inters:
        nsds.link(inter, ds)
    keep = (sk.TimeDiscretisation(0.0, h), sk.MoreauJeanOSI(0.5), sk.LCP())  # keep alive
    sim = sk.TimeStepping(nsds, *keep)
    n_steps = int(round(t_max / h)) if t_end is not None else 10**9
    qs, vs, impacts = [list(req["q0"])], [list(req["v0"])], []
    start = time.perf_counter()
    for k in range(1, n_steps + 1):
        sim.computeOneStep()
        qs.append(ds.q().tolist())
        vs.append(ds.velocity().tolist())
        if any(inter.lambda_(1)[0] > 0 for inter in inters):
            impacts.append(k * h)
        sim.nextStep()
        if n_imp is not None and len(impacts) >= n_imp:
            break
    wall = time.perf_counter() - start
    t = (np.arange(len(qs)) * h).tolist()
    return {"t": t, "q": qs, "v": vs, "impacts": impacts, "wall": wall}


if __name__ == "__main__":
    request = json.load(sys.stdin)  # one request, or a list of them (one interpreter start)
    json.dump([run(r) for r in request] if isinstance(request, list) else run(request), sys.stdout)
