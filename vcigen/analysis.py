"""After a run: energy measures, symplectic defect, order fits, plots."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .result import Result


def energy_drift(res: Result) -> float:
    """Slope of a least-squares line through ``E_d`` per unit time, relative to ``E_0``."""
    if res.energy.size < 2:
        return 0.0
    t = res.t[:-1]
    slope = np.polyfit(t - t[0], res.energy, 1)[0]
    return float(slope / (abs(res.energy[0]) or 1.0))


def impact_energy_jump(res: Result) -> float:
    """Largest ``|E_after - E_before|`` over all impacts (48a)."""
    return max((abs(i.energy_after - i.energy_before) for i in res.impacts), default=0.0)


def fit_order(hs: Sequence[float], errors: Sequence[float]) -> float:
    """Slope of ``log(error)`` against ``log(h)``."""
    return float(np.polyfit(np.log(np.asarray(hs)), np.log(np.asarray(errors)), 1)[0])


def symplectic_defect(
    step_map: Callable[[np.ndarray], np.ndarray], z: np.ndarray, eps: float = 1e-6
) -> float:
    """``max |J^T Omega J - Omega|`` of ``(q, p) -> (q', p')`` by central differences (sec. 3.3)."""
    z = np.asarray(z, dtype=float)
    d = z.size
    jac = np.empty((d, d))
    for i in range(d):
        dz = np.zeros(d)
        dz[i] = eps
        jac[:, i] = (step_map(z + dz) - step_map(z - dz)) / (2 * eps)
    return jacobian_symplectic_defect(jac)


def jacobian_symplectic_defect(jac: np.ndarray) -> float:
    """``max |J^T Omega J - Omega|`` of a ``2n x 2n`` Jacobian, ``Omega = [[0, I], [-I, 0]]`` (sec. 3.3)."""
    jac = np.asarray(jac, dtype=float)
    n = jac.shape[0] // 2
    omega = np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])
    return float(np.max(np.abs(jac.T @ omega @ jac - omega)))


def step_jacobian(function, q: np.ndarray, p: np.ndarray, h: float, par: np.ndarray) -> np.ndarray:
    """The exact Jacobian ``d(q1, p1)/d(q, p)`` of a step map of :func:`vcigen.casadi_functions`
    (``"step"`` or ``"impact_<c>"``): ``casadi.jacobian`` through its rootfinders (implicit functions)."""
    import casadi as ca

    q = np.asarray(q, dtype=float)
    n = q.size
    z = ca.MX.sym("z", 2 * n)
    out = function(q=z[:n], p=z[n:], h=h, par=par)
    jac = ca.Function("step_jacobian", [z], [ca.jacobian(ca.vertcat(out["q1"], out["p1"]), z)])
    return np.asarray(jac(np.concatenate([q, np.asarray(p, dtype=float)])))


def exact_symplectic_defect(function, q: np.ndarray, p: np.ndarray, h: float, par: np.ndarray) -> float:
    """``max |J^T Omega J - Omega|`` of a step map of :func:`vcigen.casadi_functions` at ``(q, p)`` with its
    exact Jacobian (:func:`step_jacobian`): round-off for a smooth or elastic impact step (sec. 3.3)."""
    return jacobian_symplectic_defect(step_jacobian(function, q, p, h, par))


def plot_energy(res: Result, path: str | Path, title: str = "") -> Path:
    """Energy against time (paper Figs. 2 and 4), impacts marked on the time axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig, ax = plt.subplots(figsize=(8, 3.6), dpi=110)
    ax.plot(res.t[:-1], res.energy, lw=0.6, color="C0", label=r"discrete energy $E_d$")
    if res.impacts:
        ax.plot(
            [i.t for i in res.impacts],
            [i.energy_before for i in res.impacts],
            ".",
            ms=2,
            color="C3",
            label=f"impacts ({res.n_impacts})",
        )
    ax.set_xlabel("t")
    ax.set_ylabel("energy")
    ax.set_title(title or f"max relative deviation {res.max_energy_deviation():.2e}")
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def summary(name: str, res: Result) -> str:
    """One line: impacts, max relative energy deviation, wall time."""
    st = res.stats
    return (
        f"{name}: {res.n_impacts} impacts, {st.get('steps', res.t.size - 1)} steps, "
        f"max |dE|/E = {res.max_energy_deviation():.3e}, max impact dE = {impact_energy_jump(res):.1e}, "
        f"wall {st.get('wall_time', float('nan')):.2f} s "
        f"({1e6 * st.get('seconds_per_step', float('nan')):.1f} us/step)"
    )
