"""A minimum-effort throw: the double pendulum's tip into the wall x = 1.2 at a prescribed height.

Point masses m1 = m2 = 1 on rods l1 = l2 = 1 (angles from the downward vertical), gravity, a wall at
x = 1.2 (``phi = 1.2 - sin(theta1) - sin(theta2) >= 0``). From rest position q0 = (0, 0), choose
the initial angular velocity v0 of least |v0|^2 such that the tip strikes the wall at the height y*
during step K + 1 (a fixed mode sequence: K smooth steps, then one impact step on the wall).

The NLP, with ``vcigen.casadi_functions``: ``"step"`` composed K times, then ``"contact_wall"`` (the
impact point and alpha of (47)) and ``"impact_wall"`` (the jump (48): mu), all differentiable through
their rootfinders; IPOPT (``casadi.nlpsol``) with exact first derivatives (limited-memory Hessian):

    min |v0|^2  s.t.  y_tip(q~) = y*,  0.05 <= alpha <= 0.95,  mu >= 0,  phi(q_k) >= 0 (k = 1..K)

With ``--torque`` the decision variables are instead two constant joint torques ``u`` (parameters of a
Lagrange-d'Alembert force ``F = (u1, u2)``) from rest, and the objective ``|u|^2``: ``par`` is an input of
every Function, so the derivatives with respect to parameters are exact too.

The answer is replayed with ``vcigen.build(model).simulate``: its first impact must be on the wall in step
K + 1 at the prescribed point. A trial point where a rootfinder fails (outside the mode) is an evaluation
error for IPOPT, which backtracks; CasADi prints the failed call's inputs.

    python examples/optimise/throw.py [--fast] [--torque]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import sympy as sp

import vcigen
from vcigen.backends.casadi import routine_to_function

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))  # the model, shared with the tests
from hard_scenes import double_pendulum  # noqa: E402

Q0 = np.array([0.0, 0.0])  # hanging straight down, the tip at (0, -2)
V_GUESS = np.array([2.5, 3.5])  # IPOPT's start; its first impact fixes K
U_GUESS = np.array([10.0, 10.0])  # the same with --torque (from rest)
WALL, Y_TARGET = 1.2, -1.5


def model(torque: bool = False) -> vcigen.Model:
    """The double pendulum against the wall x = 1.2 (``tests/hard_scenes.py``, shared with the hard cases);
    ``torque``: with constant joint torques ``u1``, ``u2`` (parameters, Lagrange-d'Alembert forces)."""
    base = double_pendulum()
    if not torque:
        return base
    u1, u2 = sp.symbols("u1 u2")
    return vcigen.Model(
        name="double_pendulum_torque",
        q=list(base.coordinates),
        qdot=list(base.velocities),
        lagrangian=base.L,
        contacts=base.phi,
        params={**base.defaults, u1: 0.0, u2: 0.0},
        forces=[u1, u2],
    )


def tip(q) -> tuple:
    """The tip's position ``(x, y)`` (l1 = l2 = 1)."""
    return ca.sin(q[0]) + ca.sin(q[1]), -ca.cos(q[0]) - ca.cos(q[1])


def nlp(fs: dict[str, ca.Function], par, h: float, k_steps: int, torque: bool):
    """The problem's expressions in the decision variables ``x``: ``v0`` (``p0 = M(q0) v0``), or the two
    torques (the last two parameters) from rest."""
    legendre = routine_to_function(vcigen.derive(model(torque)).routines["legendre"])
    x = ca.MX.sym("x", 2)
    if torque:
        par = ca.vertcat(par[:-2], x)
        q, p = ca.MX(Q0), ca.MX.zeros(2)
    else:
        q, p = ca.MX(Q0), legendre(Q0, x, par)[0]
    admissible = []
    for _ in range(k_steps):
        q, p = fs["step"](q, p, h, par)
        admissible.append(WALL - tip(q)[0])
    qc, _, alpha = fs["contact_wall"](q, p, h, par)
    _, _, _, mu = fs["impact_wall"](q, p, h, par)
    g = ca.vertcat(tip(qc)[1] - Y_TARGET, alpha, mu, *admissible)
    lbg = [0.0, 0.05, 0.0] + [0.0] * k_steps
    ubg = [0.0, 0.95, ca.inf] + [ca.inf] * k_steps
    return x, ca.sumsqr(x), g, lbg, ubg


def solve(fast: bool = False, verbose: bool = True, torque: bool = False) -> dict:
    """Solve with IPOPT, then replay with ``simulate``."""
    h = 0.02 if fast else 0.005
    m = model(torque)
    sim = vcigen.build(m)
    guess = U_GUESS if torque else V_GUESS

    def run(x, t_end, n_impacts=None):
        v0, params = (np.zeros(2), {"u1": x[0], "u2": x[1]}) if torque else (x, None)
        return sim.simulate(q0=Q0, v0=v0, h=h, t_end=t_end, n_impacts=n_impacts, params=params)

    k_steps = run(guess, 2.0, 1).impacts[0].step  # the mode sequence of the guess: K smooth steps, an impact
    fs = vcigen.casadi_functions(m)
    par = vcigen.casadi_parameters(m, fs["step"])
    x, f, g, lbg, ubg = nlp(fs, par, h, k_steps, torque)
    opts = {"ipopt.hessian_approximation": "limited-memory", "ipopt.tol": 1e-10, "ipopt.print_level": 0}
    opts["print_time"] = False
    solver = ca.nlpsol("throw", "ipopt", {"x": x, "f": f, "g": g}, opts)
    sol = solver(x0=guess, lbg=lbg, ubg=ubg)
    stats = solver.stats()
    x_opt = np.asarray(sol["x"]).ravel()
    res = run(x_opt, (k_steps + 1) * h)
    im = res.impacts[0]
    point = np.array([np.sin(im.q[0]) + np.sin(im.q[1]), -np.cos(im.q[0]) - np.cos(im.q[1])])
    out = {
        "x": x_opt,
        "effort": float(x_opt @ x_opt),
        "iterations": int(stats["iter_count"]),
        "status": stats["return_status"],
        "success": bool(stats["success"]),
        "target": np.array([WALL, Y_TARGET]),
        "replayed": point,
        "impact_step": im.step,
        "k_steps": k_steps,
        "alpha": im.alpha,
        "impulse": im.impulse,
        "impacts": len(res.impacts),
    }
    if verbose:
        what = "torques u" if torque else "v0"
        print(f"IPOPT: {out['status']} after {out['iterations']} iterations; h = {h}, K = {k_steps} smooth")
        print(f"{what} = {x_opt}, |{what.split()[-1]}|^2 = {out['effort']:.10f}")
        print(f"target impact point      {out['target']}")
        print(f"replayed with simulate   {point} (step {im.step}, alpha {im.alpha:.6f}, mu {im.impulse:.6f})")
        print(f"distance {np.abs(point - out['target']).max():.2e}")
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", help="h = 0.02 instead of 0.005")
    parser.add_argument(
        "--torque", action="store_true", help="constant joint torques from rest instead of v0"
    )
    a = parser.parse_args()
    solve(a.fast, torque=a.torque)
