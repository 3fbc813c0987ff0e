"""The methods of the speed-against-error bench (bench/run.py) and how each one runs a scene.

``METHODS`` names every method (vcigen on both backends and rules, the ``solve_ivp`` event-driven
baselines, SUNDIALS CVODE with root-finding (compiled, :mod:`bench.cvode`), naive Verlet, Siconos
Moreau-Jean); :func:`run_method` runs one of them from several start states and returns one plain
result dict per start.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
import time
from dataclasses import dataclass

import numpy as np

from bench import baselines
from bench.scenes import Scene

SCIPY_GRID = 0.01  # the event-driven runs are sampled on tau + k * SCIPY_GRID


@dataclass(frozen=True)
class Method:
    name: str
    kind: str  # "h" (step size) or "rtol"
    label: str
    style: str = "o-"


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("vcigen_c_trapezoid", "h", "vcigen C, trapezoid", "o-"),
        Method("vcigen_c_midpoint", "h", "vcigen C, midpoint", "s-"),
        Method("vcigen_c_lobatto3", "h", "vcigen C, lobatto3 (order 4)", "p-"),
        Method("vcigen_casadi_trapezoid", "h", "vcigen CasADi, trapezoid", "D--"),
        Method("dop853_events", "rtol", "DOP853 + events", "^-"),
        Method("dop853_events_ms", "rtol", "DOP853 + events, max_step 0.01", "<-"),
        Method("rk45_events", "rtol", "RK45 + events", "v-"),
        Method("cvode_events", "rtol", "CVODE Adams + roots (SUNDIALS)", ">-"),
        Method("verlet_full_flip", "h", "naive Verlet, full-step flip", "x-"),
        Method("verlet_half_flip", "h", "naive Verlet, half-step flip", "+-"),
        Method("siconos_mj", "h", "Siconos Moreau-Jean", "*-"),
    )
}


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


class VcigenSims:
    """Builds (once) and caches ``vcigen`` simulators; remembers why a backend cannot run."""

    def __init__(self) -> None:
        self.cache: dict[tuple[str, str, str], object] = {}
        self.build_time: dict[tuple[str, str, str], float] = {}

    @staticmethod
    def backend_missing(backend: str) -> str | None:
        if backend == "c" and importlib.util.find_spec("vcigen.backends.c") is None:
            return "vcigen C backend not available (module vcigen.backends.c does not exist yet)"
        return None

    def get(self, scene: Scene, backend: str, rule: str):
        """The simulator, or a string saying why it cannot be built."""
        key = (scene.name, backend, rule)
        if key not in self.cache:
            reason = self.backend_missing(backend)
            if reason is None:
                import vcigen

                start = time.perf_counter()
                try:
                    self.cache[key] = vcigen.build(scene.vcigen_model(), backend=backend, rule=rule)
                except Exception as exc:  # noqa: BLE001 - any failure becomes a skip message
                    self.cache[key] = f"vcigen {backend}/{rule} build failed: {type(exc).__name__}: {exc}"
                self.build_time[key] = time.perf_counter() - start
            else:
                self.cache[key] = reason
        return self.cache[key]


def vcigen_runs(sims: VcigenSims, method: str, scene: Scene, h: float, starts, t_rel: float) -> list[dict]:
    _, backend, rule = method.split("_", 2)
    sim = sims.get(scene, backend, rule)
    if isinstance(sim, str):
        return [{"skip": sim}] * len(starts)
    out = []
    for tau, q0, v0 in starts:
        try:
            res = sim.simulate(q0, v0, h, t_end=tau + t_rel, t0=tau)
        except Exception as exc:  # noqa: BLE001 - a SolverError is a result too
            out.append({"fail": f"{type(exc).__name__}: {str(exc)[:200]}"})
            continue
        out.append(
            {
                "t": res.t,
                "q": res.q,
                "energy": res.energy,
                "impacts": [i.t for i in res.impacts],
                "wall": float(res.stats["wall_time"]),
                "steps": res.t.size - 1,
            }
        )
    return out


def baseline_runs(method: str, scene: Scene, x: float, starts, t_rel: float) -> list[dict]:
    if method == "siconos_mj":
        jobs = [(x, q0, v0, t_rel) for _, q0, v0 in starts]
        raw = baselines.run_siconos_batch(scene, jobs)
    else:
        raw = []
        for _, q0, v0 in starts:
            sc = dataclasses.replace(scene, q0=np.asarray(q0, float), v0=np.asarray(v0, float))
            kw = {"grid_h": SCIPY_GRID} if METHODS[method].kind == "rtol" else {}
            try:
                raw.append(baselines.METHODS[method](sc, x, t_end=t_rel, **kw))
            except Exception as exc:  # noqa: BLE001
                raw.append({"fail": f"{type(exc).__name__}: {str(exc)[:200]}"})
    out = []
    for (tau, _, _), r in zip(starts, raw):
        if "skip" in r or "fail" in r:
            out.append(r)
            continue
        steps = r["t"].size - 1 if METHODS[method].kind == "h" else r.get("nfev", 0)
        out.append(
            {
                "t": r["t"] + tau,
                "q": r["q"],
                "energy": r["energy"],
                "impacts": [tau + ti for ti in r["impacts"]],
                "wall": float(r["wall"]),
                "steps": steps,
                "fell_through": bool(r.get("fell_through", False)),
                "stalled": r.get("stalled"),
            }
        )
    return out


def run_method(sims: VcigenSims, method: str, scene: Scene, x: float, starts, t_rel: float) -> list[dict]:
    """One result dict per start ``(tau, q0, v0)``: ``t`` (absolute), ``q``, ``energy``,
    ``impacts`` (absolute times), ``wall``; or ``{"skip": why}`` / ``{"fail": why}``."""
    if method.startswith("vcigen_"):
        return vcigen_runs(sims, method, scene, x, starts, t_rel)
    return baseline_runs(method, scene, x, starts, t_rel)
