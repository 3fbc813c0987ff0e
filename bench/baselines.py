"""The methods people use instead of a variational collision integrator.

Every ``run_*`` has the signature ``(scene, h_or_tol, t_end=None, n_impacts=None)``
and returns a dict with ``t, q, v, energy`` (continuous energy at each grid
point), ``impacts`` (times) and ``wall`` (seconds of integration only), or
``{"skip": reason}`` when the method does not apply.
"""

from __future__ import annotations

import json
import subprocess
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from bench.cvode import run_cvode_events
from bench.scenes import Scene

Array = np.ndarray
SICONOS_PYTHON = "/usr/bin/python3"
FELL_THROUGH = 0.5  # scipy runs stop when some phi < -FELL_THROUGH (a missed impact)
STUCK_LIMIT = 50  # scipy runs stop after this many impacts in a row without time advancing
SICONOS_SCRIPT = Path(__file__).with_name("siconos_mj.py")


def _result(scene: Scene, t, q, v, impacts, wall: float) -> dict:
    q, v = np.asarray(q, float), np.asarray(v, float)
    energy = np.array([scene.energy(a, b) for a, b in zip(q, v, strict=True)])
    return {
        "t": np.asarray(t, float),
        "q": q,
        "v": v,
        "energy": energy,
        "impacts": list(impacts),
        "wall": wall,
    }


def _check_stop(t_end: float | None, n_impacts: int | None) -> None:
    if t_end is None and n_impacts is None:
        raise ValueError("give t_end or n_impacts")


def _verlet(scene: Scene, h: float, t_end, n_impacts, flip_half: bool) -> dict:
    """Velocity Verlet with velocity reflection (constant ``M`` only).

    Per step: ``vh = v + h/2 a(q)``, ``q' = q + h vh``, ``v' = vh + h/2 a(q')``.
    For every contact with ``phi(q') < 0`` and the velocity moving inward
    (``grad phi . w < 0``), ``w`` is reflected across the M-metric normal
    ``n = grad phi(q')``: ``w = v'`` (full step, after the kick) or ``w = vh``
    (half step, before the second kick). The position is kept as is (not
    projected); the impact time logged is the step end ``t_{k+1}``.
    """
    _check_stop(t_end, n_impacts)
    if not scene.constant_mass:
        return {"skip": f"naive Verlet needs a constant mass matrix; {scene.name} has M(q)"}
    minv = np.linalg.inv(scene.mass(scene.q0))
    n_max = int(round(t_end / h)) if t_end is not None else 10**9
    q, v = scene.q0.astype(float).copy(), scene.v0.astype(float).copy()
    qs, vs, impacts = [q], [v], []
    contacts = scene.contacts
    start = time.perf_counter()
    a = -minv @ scene.grad_potential(q)
    for k in range(1, n_max + 1):
        vh = v + 0.5 * h * a
        q = q + h * vh
        hit = False
        if flip_half:
            for c in contacts:
                if c.phi(q) < 0:
                    n = c.grad_phi(q)
                    if n @ vh < 0:
                        vh = vh - 2 * (n @ vh) / (n @ minv @ n) * (minv @ n)
                        hit = True
        a = -minv @ scene.grad_potential(q)
        v = vh + 0.5 * h * a
        if not flip_half:
            for c in contacts:
                if c.phi(q) < 0:
                    n = c.grad_phi(q)
                    if n @ v < 0:
                        v = v - 2 * (n @ v) / (n @ minv @ n) * (minv @ n)
                        hit = True
        qs.append(q)
        vs.append(v)
        if hit:
            impacts.append(k * h)
            if n_impacts is not None and len(impacts) >= n_impacts:
                break
    wall = time.perf_counter() - start
    return _result(scene, h * np.arange(len(qs)), qs, vs, impacts, wall)


def run_verlet_full_flip(scene: Scene, h: float, t_end=None, n_impacts=None) -> dict:
    """Naive Verlet, reflect the full-step velocity ``v_{k+1}`` when ``phi(q_{k+1}) < 0``."""
    return _verlet(scene, h, t_end, n_impacts, flip_half=False)


def run_verlet_half_flip(scene: Scene, h: float, t_end=None, n_impacts=None) -> dict:
    """Naive Verlet, reflect the half-step velocity ``v_{k+1/2}`` when ``phi(q_{k+1}) < 0``."""
    return _verlet(scene, h, t_end, n_impacts, flip_half=True)


def run_scipy_events(
    scene: Scene,
    rtol: float,
    t_end=None,
    n_impacts=None,
    method: str = "RK45",
    grid_h: float | None = None,
    max_step: float = np.inf,
) -> dict:
    """``solve_ivp`` with terminal events (direction -1) and the elastic law, restarted
    after each impact. ``atol = rtol * 1e-3``; default ``max_step`` (unbounded); the
    dense output is sampled on ``t = k * grid_h`` (default ``scene.h``) after timing.
    A missed impact lets the body fall through; the run then stops at
    ``phi = -FELL_THROUGH`` with ``fell_through = True`` in the result. A restart that
    re-impacts at once, ``STUCK_LIMIT`` times in a row (the state sits on a kink of
    ``phi`` and the law flips between the two branches' normals), stops the run with
    ``stalled = t`` (else ``None``).
    """
    _check_stop(t_end, n_impacts)
    n = scene.n
    grid_h = scene.h if grid_h is None else grid_h
    t_max = t_end if t_end is not None else 1e6

    def rhs(_t: float, y: Array) -> Array:
        return np.concatenate([y[n:], scene.accel(y[:n], y[n:])])

    events = []
    for c in scene.contacts:

        def ev(_t: float, y: Array, c=c) -> float:
            return float(c.phi(y[:n]))

        ev.terminal, ev.direction = True, -1
        events.append(ev)

        def lost(_t: float, y: Array, c=c) -> float:  # passed through: stop, flag it
            return float(c.phi(y[:n])) + FELL_THROUGH

        lost.terminal, lost.direction = True, -1
        events.append(lost)
    t, y = 0.0, np.concatenate([scene.q0, scene.v0]).astype(float)
    segments, impacts, fell_through, stalled, stuck = [], [], False, None, 0
    start = time.perf_counter()
    while t < t_max:
        sol = solve_ivp(
            rhs,
            (t, t_max),
            y,
            method=method,
            rtol=rtol,
            atol=rtol * 1e-3,
            events=events,
            dense_output=True,
            max_step=max_step,
        )
        if sol.status == -1:
            raise RuntimeError(f"solve_ivp failed at t={sol.t[-1]}: {sol.message}")
        segments.append((t, sol.t[-1], sol.sol))
        if sol.status != 1:
            break
        j = min((j for j, te in enumerate(sol.t_events) if te.size), key=lambda j: sol.t_events[j][0])
        if j % 2:
            fell_through = True
            break
        j //= 2
        t_hit, ye = float(sol.t_events[j][0]), sol.y_events[j][0]
        stuck = stuck + 1 if t_hit - t <= 1e-12 else 0
        t = t_hit
        if stuck > STUCK_LIMIT:  # re-impacting at the same instant: a kink chatters between branches
            stalled = t
            break
        y = np.concatenate([ye[:n], scene.reflect(ye[:n], ye[n:], scene.contacts[j])])
        impacts.append(t)
        if n_impacts is not None and len(impacts) >= n_impacts:
            break
    wall = time.perf_counter() - start
    t_hi = segments[-1][1]
    grid = grid_h * np.arange(int(np.floor(t_hi / grid_h + 1e-9)) + 1)
    ys = np.empty((grid.size, 2 * n))
    for a, b, dense in segments:
        sel = (grid >= a) & (grid <= b)
        if sel.any():
            ys[sel] = dense(grid[sel]).T
    res = _result(scene, grid, ys[:, :n], ys[:, n:], impacts, wall)
    res["fell_through"] = fell_through
    res["stalled"] = stalled
    return res


SICONOS_SCENES = ("particle",)
SICONOS_STAR_SKIP = (
    "siconos star: a Python-subclassed LagrangianScleronomousR (4 vertex heights) "
    "segfaults inside TimeStepping.computeOneStep at the first active contact "
    "(Debian python3-siconos 4.4.0+dfsg-2)"
)


def siconos_available() -> str | None:
    """``None`` if ``/usr/bin/python3`` imports siconos, else the reason why not."""
    try:
        out = subprocess.run(
            [SICONOS_PYTHON, "-c", "import siconos.kernel"], capture_output=True, text=True, timeout=60
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"siconos: cannot run {SICONOS_PYTHON}: {exc}"
    return None if out.returncode == 0 else f"siconos: import failed: {out.stderr[-300:]}"


def run_siconos(scene: Scene, h: float, t_end=None, n_impacts=None) -> dict:
    """Siconos Moreau–Jean (theta=1/2, e=1, LCP) in a ``/usr/bin/python3`` subprocess.

    ``wall`` is measured inside the subprocess around the time loop.
    """
    _check_stop(t_end, n_impacts)
    return run_siconos_batch(scene, [(h, scene.q0, scene.v0, t_end)], n_impacts=n_impacts)[0]


def run_siconos_batch(
    scene: Scene, jobs: list[tuple[float, Array, Array, float | None]], n_impacts: int | None = None
) -> list[dict]:
    """Several Siconos runs ``(h, q0, v0, t_end)`` in one ``/usr/bin/python3`` start.

    Returns one result dict per job, or ``[{"skip": reason}] * len(jobs)``.
    """
    if scene.name == "star":
        return [{"skip": SICONOS_STAR_SKIP}] * len(jobs)
    if scene.name not in SICONOS_SCENES:
        return [{"skip": f"siconos: scene {scene.name} not wired (particle only)"}] * len(jobs)
    reason = siconos_available()
    if reason:
        return [{"skip": reason}] * len(jobs)
    req = [
        {
            "scene": scene.name,
            "h": float(h),
            "t_end": None if t_end is None else float(t_end),
            "n_impacts": n_impacts,
            "q0": [float(a) for a in q0],
            "v0": [float(a) for a in v0],
        }
        for h, q0, v0, t_end in jobs
    ]
    out = subprocess.run(
        [SICONOS_PYTHON, str(SICONOS_SCRIPT)],
        input=json.dumps(req),
        capture_output=True,
        text=True,
        timeout=3600,
    )
    if out.returncode != 0:
        return [{"skip": f"siconos: subprocess exit {out.returncode}: {out.stderr[-300:]}"}] * len(jobs)
    return [_result(scene, r["t"], r["q"], r["v"], r["impacts"], r["wall"]) for r in json.loads(out.stdout)]


METHODS: dict[str, Callable[..., dict]] = {
    "verlet_full_flip": run_verlet_full_flip,
    "verlet_half_flip": run_verlet_half_flip,
    "rk45_events": partial(run_scipy_events, method="RK45"),
    "dop853_events": partial(run_scipy_events, method="DOP853"),
    "dop853_events_ms": partial(run_scipy_events, method="DOP853", max_step=0.01),
    "siconos_mj": run_siconos,
    "cvode_events": run_cvode_events,
}
