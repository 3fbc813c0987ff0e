"""Shooting through impacts: the launch velocity that sends a ball through two bounces to a target.

A unit ball in the box 0 <= x, y <= 1 under gravity (g = 9.81), elastic walls, starts at q0 = (0.2, 0.8).
Find v0 such that the ball is at the target point at time T after bouncing off the right wall and the
floor. Newton on the exact sensitivities: the run is the composition of ``vcigen.casadi_functions``'s
``"step"`` and ``"impact_<c>"`` along the mode sequence of a ``simulate`` run from the current iterate,
and ``casadi.jacobian`` of that chain is the exact ``d q(T) / d v0`` (implicit-function theorem through
every contact time and jump). The residual per iteration shows quadratic convergence.

    python examples/optimise/shooting.py [--fast]
"""

from __future__ import annotations

import argparse

import casadi as ca
import numpy as np
import sympy as sp

import vcigen

Q0 = np.array([0.2, 0.8])
V_TRUE = np.array([2.0, 1.0])  # defines the target: where this launch is at T (right wall, then floor)
V_START = np.array([1.6, 1.5])  # Newton's start: the same two bounces, in other steps
T = 0.8


def model() -> vcigen.Model:
    """A unit ball in the unit box under gravity, elastic walls."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g = sp.Symbol("g", positive=True)
    return vcigen.Model(
        name="ball_box",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"left": x, "right": 1 - x, "bottom": y, "top": 1 - y},
        params={g: 9.81},
    )


def modes(res: vcigen.Result) -> tuple[str, ...]:
    """The mode of every grid step of a run: ``"step"`` or ``"impact_<c>"`` (one impact per step)."""
    out = ["step"] * (res.t.size - 1)
    for im in res.impacts:
        if out[im.step] != "step":
            raise ValueError(f"step {im.step} holds several impacts: not a composition of these Functions")
        out[im.step] = f"impact_{im.contact}"
    return tuple(out)


def chain(fs: dict[str, ca.Function], sequence: tuple[str, ...], h: float, par) -> ca.Function:
    """``v0 -> (q(T), alphas)``: the step Functions composed along ``sequence`` from ``(Q0, p0 = v0)``."""
    v0 = ca.MX.sym("v0", 2)
    q, p, alphas = ca.MX(Q0), v0, []  # p0 = dL/dqdot = v0 for a unit mass
    for mode in sequence:
        out = fs[mode](q=q, p=p, h=h, par=par)
        q, p = out["q1"], out["p1"]
        if mode != "step":
            alphas.append(out["alpha"])
    return ca.Function(
        "shot", [v0], [q, ca.jacobian(q, v0), ca.vertcat(*alphas)], ["v0"], ["qT", "J", "alpha"]
    )


def solve(fast: bool = False, verbose: bool = True) -> dict:
    """Newton on ``q(T; v0) = target``; returns the residual history, the answer and the mode sequence."""
    h = 0.02 if fast else 0.005
    m = model()
    sim = vcigen.build(m)
    fs = vcigen.casadi_functions(m)
    par = vcigen.casadi_parameters(m, fs["step"])
    true = sim.simulate(q0=Q0, v0=V_TRUE, h=h, t_end=T)
    target = true.q[-1]
    v, residuals, built = V_START.copy(), [], {}
    for it in range(20):
        sequence = modes(sim.simulate(q0=Q0, v0=v, h=h, t_end=T))  # the mode sequence at this iterate
        if sequence not in built:
            built[sequence] = chain(fs, sequence, h, par)
        q_t, jac, alphas = (np.asarray(o) for o in built[sequence](v))
        # the chain left the mode simulate found (round-off allowed: the start strikes the right wall at the
        # grid time t = 0.5, alpha = 0 of one step, the same state as alpha = 1 of the step before)
        if not np.all((alphas >= -1e-9) & (alphas <= 1.0 + 1e-9)):
            raise RuntimeError(f"impact fractions {alphas.ravel()} outside [0, 1] at v0 = {v}")
        r = q_t.ravel() - target
        residuals.append(float(np.abs(r).max()))
        if verbose:
            bounces = [s.removeprefix("impact_") for s in sequence if s != "step"]
            print(f"iteration {it}: |q(T) - target| = {residuals[-1]:.3e}, v0 = {v}, bounces {bounces}")
        if residuals[-1] <= 1e-13:
            break
        v = v - np.linalg.solve(jac, r)
    replay = sim.simulate(q0=Q0, v0=v, h=h, t_end=T)
    out = {
        "residuals": residuals,
        "v0": v,
        "target": target,
        "replayed": replay.q[-1],
        "bounces": [im.contact for im in replay.impacts],
        "true_bounces": [im.contact for im in true.impacts],
        "v_true": V_TRUE,
    }
    if verbose:
        print(f"target {target}, replayed with simulate {replay.q[-1]}, bounces {out['bounces']}")
        print(
            f"v0 = {v} (the launch that made the target: {V_TRUE}), h = {h}, {len(residuals) - 1} iterations"
        )
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", help="h = 0.02 instead of 0.005")
    solve(parser.parse_args().fast)
