"""``vcigen.tangents``: the ``d_*`` routines equal CasADi's automatic derivatives of their routines."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from forced_scenes import driven_oscillator
from hard_scenes import ball, box, double_pendulum, star
from test_sensitivity_friction import incline_disk
from test_sustained_closed_forms import pendulum

from vcigen.backends.casadi import routine_to_function
from vcigen.derive import derive

SCENES = {"box_lossy": lambda: box(lossy=True), "star": star, "double_pendulum": double_pendulum}
SCENES["driven"] = driven_oscillator
SCENES["incline_disk"] = incline_disk  # Coulomb friction: d_friction
# under lobatto3 (internal points held on the rows): the wider rattle (v, Lam, Lam_m, u) and rattle_end
LOBATTO3 = {"ball_lobatto3": ball, "pendulum_lobatto3": pendulum}


def _reference(system, name: str, ins: list) -> list:
    """CasADi's AD of the routine ``d_<name>`` differentiates, at the same symbols."""
    if name == "forces":  # the force law [M a - rhs - G^T lam; G a + curv] of rows, dynamics, legendre
        q, u, a, lam, par = ins
        _, grad, curv = routine_to_function(system.routines["rows"])(q, u, par)
        rhs = routine_to_function(system.routines["dynamics"])(q, u, par)[0]
        mass = routine_to_function(system.routines["legendre"])(q, u, par)[1]
        res = ca.vertcat(ca.mtimes(mass, a) - rhs - ca.mtimes(grad.T, lam), ca.mtimes(grad, a) + curv)
        return [ca.jacobian(res, ca.vertcat(q, u, par))]
    if name == "psi":  # the rows' values in (q, par): a row crossed while others are held
        q, _, par = ins
        return [ca.jacobian(routine_to_function(system.routines["rows"])(*ins)[0], ca.vertcat(q, par))]
    base = system.routines[name]
    g = routine_to_function(base)
    if name == "legendre":
        q, v, a, par = ins
        mom, mass = g(q, v, par)
        z = ca.vertcat(q, v, par)
        return [ca.jacobian(mom, z), ca.jacobian(ca.mtimes(mass, a), z)]
    if base.inputs[0].name == "x":
        return [ca.jacobian(g(*ins)[0], ca.vertcat(*ins[1:]))]
    if name == "contacts":
        return [ca.jacobian(ca.vec(g(*ins)[1].T), ca.vertcat(*ins))]
    if name == "friction":  # each contact's mu_f in par; the tangents' gradients, row-major, in (q, par)
        mu, tgrad = g(*ins)[:2]
        return [ca.jacobian(mu, ins[-1]), ca.jacobian(ca.vec(tgrad.T), ca.vertcat(*ins))]
    if name == "rows":  # the rows' gradients, row-major, in (q, par); u does not enter them
        q, _, par = ins
        return [ca.jacobian(ca.vec(g(*ins)[1].T), ca.vertcat(q, par))]
    outs = g(*ins)
    outs = outs if isinstance(outs, (list, tuple)) else [outs]
    return [ca.jacobian(o, ca.vertcat(*ins)) for o in outs]


@pytest.mark.parametrize("scene", sorted(SCENES | LOBATTO3))
def test_tangents_match_automatic_differentiation(scene: str) -> None:
    maker, rule = (LOBATTO3[scene], "lobatto3") if scene in LOBATTO3 else (SCENES[scene], "trapezoid")
    plain, system = derive(maker(), rule), derive(maker(), rule, sensitivities=True)
    assert not [r for r in plain.routines if r.startswith("d_")]  # a scene that does not ask does not pay
    names = [r for r in system.routines if r.startswith("d_")]
    expected = {"d_smooth", "d_jump", "d_segment", "d_contacts", "d_legendre", "d_restitution"}
    expected |= {f"d_{p}_{c}" for p in ("contact_time", "jump_contact") for c in system.contact_names}
    if "rows" in system.routines:  # sustained contact: the held step's residuals and the rows' directions
        expected |= {"d_rattle", "d_rattle_project", "d_rows", "d_forces", "d_psi"}
    if "friction" in system.routines:  # Coulomb: mu_f in par, the tangents' gradients
        expected.add("d_friction")
    if rule == "lobatto3" and "rows" in system.routines:  # p+ of a constrained segment, internal points held
        expected.add("d_rattle_end")
        assert system.routines["rattle"].inputs[0].size == 2 * system.n + 2 * system.r  # (v, Lam, Lam_m, u)
    assert set(names) == expected
    rng = np.random.default_rng(1)
    for name in names:
        r = system.routines[name]
        ins = [ca.SX.sym(a.name, a.size) for a in r.inputs]
        outs = routine_to_function(r)(*ins)
        outs = list(outs) if isinstance(outs, (list, tuple)) else [outs]
        ref = _reference(system, name[2:], ins)
        f = ca.Function("f", ins, outs + ref)
        vals = f(*[rng.uniform(0.2, 0.9, a.size) for a in r.inputs])
        for mine, theirs in zip(vals[: len(outs)], vals[len(outs) :]):
            assert np.array(mine).shape == np.array(theirs).shape
            np.testing.assert_allclose(np.array(mine), np.array(theirs), rtol=1e-12, atol=1e-13, err_msg=name)
