"""A compiled event-driven baseline: SUNDIALS CVODE with its root-finding (scikit-sundae).

CVODE's variable-order Adams method (orders 1-12) runs in C; the right-hand side and the event
functions are the scene's Python callbacks, as a user of the binding would write them. Same
protocol as :func:`bench.baselines.run_scipy_events`: terminal events (direction -1) on every
contact, the elastic law at the located root, restart; ``atol = rtol * 1e-3``; the solution is
reported on ``t = k * grid_h``. Skipped with a message where ``scikit-sundae`` does not install.
"""

from __future__ import annotations

import time

import numpy as np

from bench.scenes import Scene

MAX_RESTARTS_AT_ONE_TIME = 50  # as STUCK_LIMIT in bench.baselines: a kink chattering between branches


def cvode_missing() -> str | None:
    """``None`` if ``sksundae`` imports, else why the CVODE baseline is skipped."""
    try:
        import sksundae  # noqa: F401
    except ImportError as exc:
        return f"cvode: scikit-sundae does not import here ({exc}); pip install scikit-sundae"
    return None


def run_cvode_events(
    scene: Scene, rtol: float, t_end=None, n_impacts=None, grid_h: float | None = None, method: str = "Adams"
) -> dict:
    """CVODE (``method``: ``"Adams"`` or ``"BDF"``) with root-finding and the elastic law at each root."""
    from bench.baselines import _check_stop, _result

    _check_stop(t_end, n_impacts)
    reason = cvode_missing()
    if reason:
        return {"skip": reason}
    import sksundae as sun

    n = scene.n
    grid_h = scene.h if grid_h is None else grid_h
    t_max = t_end if t_end is not None else 1e3
    contacts = scene.contacts

    def rhs(_t, y, yp):
        yp[:n] = y[n:]
        yp[n:] = scene.accel(y[:n], y[n:])

    def events(_t, y, out):
        q = y[:n]
        for j, c in enumerate(contacts):
            out[j] = c.phi(q)

    events.terminal = [True] * len(contacts)
    events.direction = [-1] * len(contacts)
    grid = grid_h * np.arange(int(np.floor(t_max / grid_h + 1e-9)) + 1)
    ts, ys, impacts = [0.0], [np.concatenate([scene.q0, scene.v0]).astype(float)], []
    t, y, stuck, nfev, stalled = 0.0, ys[0].copy(), 0, 0, None
    start = time.perf_counter()
    while t < t_max:
        solver = sun.cvode.CVODE(
            rhs,
            method=method,
            rtol=rtol,
            atol=rtol * 1e-3,
            eventsfn=events,
            num_events=len(contacts),
            max_num_steps=10**7,
        )
        out_t = np.concatenate([[t], grid[grid > t + 1e-14], [t_max] if grid[-1] < t_max else []])
        if out_t.size < 2:
            break
        sol = solver.solve(out_t, y)
        if not sol.success:
            raise RuntimeError(f"CVODE failed at t={sol.t[-1]}: {sol.message}")
        nfev += int(sol.nfev)
        hit = sol.status == 2 and sol.t_events is not None and len(sol.t_events)
        keep = slice(1, -1) if hit else slice(1, None)
        ts.extend(sol.t[keep])
        ys.extend(sol.y[keep])
        if not hit:
            break
        t_hit, y_hit = float(sol.t_events[0]), np.array(sol.y_events[0], dtype=float)
        j = int(np.argmin([c.phi(y_hit[:n]) for c in contacts]))
        stuck = stuck + 1 if t_hit - t <= 1e-12 else 0
        t = t_hit
        if stuck > MAX_RESTARTS_AT_ONE_TIME:
            stalled = t
            break
        y = np.concatenate([y_hit[:n], scene.reflect(y_hit[:n], y_hit[n:], contacts[j])])
        impacts.append(t)
        if n_impacts is not None and len(impacts) >= n_impacts:
            break
    wall = time.perf_counter() - start
    ts_a, ys_a = np.asarray(ts), np.asarray(ys)
    on_grid = np.isclose(ts_a / grid_h, np.round(ts_a / grid_h), rtol=0, atol=1e-9)
    res = _result(scene, ts_a[on_grid], ys_a[on_grid, :n], ys_a[on_grid, n:], impacts, wall)
    res["nfev"] = nfev
    res["fell_through"] = False
    res["stalled"] = stalled
    return res
