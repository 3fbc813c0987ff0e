"""Partial derivatives of every phase with respect to its data (MATH.md, *Exact sensitivities*).

Pure SymPy, like :mod:`vcigen.derive`. Every phase of a step solves ``F(x; d) = 0`` for its unknowns
``x`` given data ``d``; the residual routines already carry ``dF/dx`` (``jac``). The implicit-function
theorem ``dx/dz = -(dF/dx)^-1 (dF/dd . dd/dz)`` needs ``dF/dd`` as well, and the chain through a step
needs the partials of the explicit maps (momenta and energy of a segment (50), (51), (55), the Legendre
transform, the contact gradients, the restitution). :func:`tangent_routines` derives them as routines
named ``d_<routine>`` (SENS_DESIGN.md):

* ``d_smooth``, ``d_contact_time_<c>``, ``d_jump``, ``d_jump_contact_<c>``, ``d_rattle``,
  ``d_rattle_project``: the residual routine's own inputs (``x`` first), output ``dres = d res / d(every
  input after x, concatenated in input order)``; (46), (47), (48), (78), and the constrained step of
  sustained contact with its end projection (MATH.md *Sustained contact*; their ``act`` columns are
  those of a fixed active set, never used);
* ``d_segment(q0, v, tau, par)``: ``dp_minus``, ``dp_plus``, ``denergy``, each ``d/d(q0, v, tau, par)``
  (with internal points ``d/d(q0, v, tau, u, par)``);
* ``d_rattle_end(q0, v, tau, u, lm, act, par)`` (a rule with internal points and rows): ``dp_plus``,
  ``denergy``, each ``d/d(every input)``: ``p+`` and ``E_d`` of a constrained segment whose internal points
  are held (``derive.held_internal_points``), the tangent of the held step's end momentum;
* ``d_contacts(q, par)``: ``dgrad``, ``(m n) x (n + npar)``, row ``j n + i`` is ``d grad_j[i] / d(q, par)``;
* ``d_legendre(q, v, a, par)``: ``dmom = d mom / d(q, v, par)`` and ``dmass_a = d (M(q, v) a) / d(q, v, par)``
  (the tangent of one Newton step of the inverse Legendre transform, and of ``M^-1 n``);
* ``d_restitution(par)``: ``de``, ``m x npar`` (the loss of (39));
* ``d_friction(q, par)`` (a model with friction): ``dmu``, ``m x npar``: each contact's ``mu_f`` in ``par``
  (the tangent of a slip slot ``-mu_f s``, the sliding direction ``s`` fixed within a friction mode), and
  ``dtgrad``, ``(m n) x (n + npar)``: the tangents' gradients (a frictional impact's direction ``n + rho t``);
* ``d_friction_cone(q, par)`` (a contact with an isotropic cone): ``dtgrad2``, ``(m n) x (n + npar)``: the
  second tangents' gradients (a cone's impulse direction ``n + rho_1 t1 + rho_2 t2`` at an impact);
* ``d_rows(q, u, par)``: ``dgrad``, ``(R n) x (n + npar)``: the rows' gradients (a plastic impact's
  impulse law);
* ``d_forces(q, u, a, lam, par)``: ``dres``, ``(n + R) x (2n + npar)``: ``d/d(q, u, par)`` of the contact
  force law ``M(q, u) a - rhs(q, u) - G(q)^T lam = 0``, ``G(q) a + curv(q, u) = 0`` (unknowns the
  acceleration ``a`` and the forces ``lam``; the second block on the active rows only): the tangent of the
  force whose root locates a lift-off (``SustainedSteps._forces``, ``Tracker.liftoff``);
* ``d_psi(q, u, par)``: ``dpsi``, ``R x (n + npar)``: the rows' values, whose root locates a row crossed
  while others are held (``SustainedSteps._row_crossing``, ``Tracker.event``).

They are added to :attr:`DiscreteSystem.routines` only by ``derive(model, rule, sensitivities=True)``;
a simulator asked for sensitivities derives them lazily from the system it has (:func:`tangent_routines`).
"""

from __future__ import annotations

import pickle

import sympy as sp

from . import diskmemo, memo
from .calculus import jacobian
from .routines import Arg, Output, Routine

TANGENT_PREFIX = "d_"
# the residual routines a tangent is derived for: the phases covered (SENS_DESIGN.md)
RESIDUAL_PREFIXES = ("smooth", "contact_time_", "jump", "jump_contact_")
# the constrained step of sustained contact and its end projection (MATH.md, Sustained contact)
HELD_RESIDUALS = ("rattle", "rattle_project")


def is_tangent(name: str) -> bool:
    """Whether routine ``name`` is one of :func:`tangent_routines` (never solved, never on a hot path)."""
    return name.startswith(TANGENT_PREFIX)


def _covered(name: str) -> bool:
    return name in ("smooth", "jump", *HELD_RESIDUALS) or name.startswith(("contact_time_", "jump_contact_"))


def _data_symbols(args: tuple[Arg, ...]) -> list[sp.Symbol]:
    return [s for a in args for s in a.symbols]


def residual_tangent(r: Routine) -> Routine:
    """``d_<name>``: ``d res / d(data)`` of residual routine ``r`` (its inputs after ``x``)."""
    res = r.output("res").expr
    dres = jacobian(res, _data_symbols(r.inputs[1:]))
    return Routine(
        TANGENT_PREFIX + r.name,
        r.inputs,
        (Output("dres", dres),),
        f"d res / d(data) of {r.name}: the data's columns of the implicit-function theorem.",
    )


def explicit_tangent(r: Routine, outputs: tuple[str, ...], doc: str) -> Routine:
    """``d_<name>``: partials of the explicit routine ``r``'s ``outputs`` in all its inputs (in order)."""
    xs = _data_symbols(r.inputs)
    return Routine(
        TANGENT_PREFIX + r.name,
        r.inputs,
        tuple(Output("d" + o, jacobian(r.output(o).expr, xs)) for o in outputs),
        doc,
    )


def segment_tangent(r: Routine) -> Routine:
    """``d_segment``: partials of ``p-``, ``p+`` (50)-(51) and ``E_d`` (55) in ``(q0, v, tau, [u,] par)``."""
    return explicit_tangent(
        r,
        ("p_minus", "p_plus", "energy"),
        "Partials of the discrete momenta (50)-(51) and energy (55) in (q0, v, tau, par).",
    )


def rattle_end_tangent(r: Routine) -> Routine:
    """``d_rattle_end``: partials of ``p+ = D2 L_d`` (51) and ``E_d = -D3 L_d`` (55) of a constrained segment
    whose internal points are held on the active rows (``derive.held_internal_points``) in ``(q0, v, tau,
    u, lm, act, par)``: the chain from the held step's unknowns ``(v, Lam, Lam_m, u)`` to ``p+``."""
    return explicit_tangent(
        r,
        ("p_plus", "energy"),
        "Partials of p+ (51) and E_d (55) of a constrained segment with held internal points (every input).",
    )


def _matrix_tangent(r: Routine, name: str) -> sp.Matrix:
    """Partials of the matrix output ``name`` of ``r`` (row-major: row ``j n + i`` its entry ``[j, i]``) in
    every input of ``r`` (gradients of the contacts or of the tangents in ``(q, par)``)."""
    grad = r.output(name).expr
    return jacobian(sp.Matrix(grad.rows * grad.cols, 1, list(grad)), _data_symbols(r.inputs))


def contacts_tangent(r: Routine) -> Routine:
    """``d_contacts``: partials of the contact gradients (row-major) in ``(q, par)``."""
    return Routine(
        "d_contacts",
        r.inputs,
        (Output("dgrad", _matrix_tangent(r, "grad")),),
        "Partials of grad phi_j[i] (row j n + i) in (q, par): the tangent of the impulse direction.",
    )


def legendre_tangent(r: Routine) -> Routine:
    """``d_legendre(q, v, a, par)``: partials of ``dL/dqdot`` and of ``M(q, v) a`` in ``(q, v, par)``."""
    q, v, par = r.inputs
    a = tuple(sp.Dummy(f"a{i}", real=True) for i in range(q.size))
    xs = [*q.symbols, *v.symbols, *par.symbols]
    mass_a = r.output("mass").expr * sp.Matrix(a)
    return Routine(
        "d_legendre",
        (q, v, Arg("a", a), par),
        (Output("dmom", jacobian(r.output("momentum").expr, xs)), Output("dmass_a", jacobian(mass_a, xs))),
        "Partials of p = dL/dqdot and of M(q, v) a in (q, v, par).",
    )


def rows_tangent(r: Routine) -> Routine:
    """``d_rows``: partials of the rows' gradients (row-major) in ``(q, par)``, an impulse law's."""
    grad = r.output("grad").expr
    flat = sp.Matrix(grad.rows * grad.cols, 1, list(grad))
    q, _, par = r.inputs
    return Routine(
        "d_rows",
        r.inputs,
        (Output("dgrad", jacobian(flat, [*q.symbols, *par.symbols])),),
        "Partials of grad psi_r[i] (row r n + i) in (q, par): the tangent of a plastic impact's directions.",
    )


def psi_tangent(r: Routine) -> Routine:
    """``d_psi``: partials of the rows' values ``psi`` in ``(q, par)``: the root of a row crossed while others
    are held (an impact while held, located along the constrained sub-step map like (47))."""
    q, _, par = r.inputs
    return Routine(
        "d_psi",
        r.inputs,
        (Output("dpsi", jacobian(r.output("psi").expr, [*q.symbols, *par.symbols])),),
        "Partials of psi_r in (q, par): the tangent of the fraction where an inactive row is crossed.",
    )


def forces_tangent(routines: dict[str, Routine]) -> Routine:
    """``d_forces(q, u, a, lam, par)``: partials in ``(q, u, par)`` of the force law of sustained contact
    (``rows``, ``dynamics``, ``legendre``): ``[M(q, u) a - rhs - G^T lam; G a + curv]`` (MATH.md *Sustained
    contact*: ``G M^-1 (rhs + G^T lam) + curv = 0`` on the active rows, with ``a = M^-1 (rhs + G^T lam)``)."""
    rows, dyn, leg = routines["rows"], routines["dynamics"], routines["legendre"]
    q, u, par = rows.inputs
    same = [*q.symbols, *u.symbols, *par.symbols]
    rep = {**dict(zip(_data_symbols(dyn.inputs), same)), **dict(zip(_data_symbols(leg.inputs), same))}
    n, nr = q.size, rows.output("psi").expr.rows
    a = Arg("a", tuple(sp.Dummy(f"a{i}", real=True) for i in range(n)))
    lam = Arg("lam", tuple(sp.Dummy(f"lam{r}", real=True) for r in range(nr)))
    grad, curv = rows.output("grad").expr, rows.output("curv").expr
    mass = leg.output("mass").expr.xreplace(rep)
    rhs = dyn.output("rhs").expr.xreplace(rep)
    amat, lmat = sp.Matrix(a.symbols), sp.Matrix(lam.symbols)
    res = (mass * amat - rhs - grad.T * lmat).col_join(grad * amat + curv)
    return Routine(
        "d_forces",
        (q, u, a, lam, par),
        (Output("dres", jacobian(res, same)),),
        "Partials in (q, u, par) of the force law [M a - rhs - G^T lam; G a + curv] (the lift-off's root).",
    )


def restitution_tangent(r: Routine) -> Routine:
    """``d_restitution(par)``: partials of each contact's coefficient of restitution (39)."""
    return Routine(
        "d_restitution",
        r.inputs,
        (Output("de", jacobian(r.output("e").expr, _data_symbols(r.inputs))),),
        "Partials of each contact's coefficient of restitution in par.",
    )


def friction_tangent(r: Routine) -> Routine:
    """``d_friction(q, par)``: partials of each contact's ``mu_f`` in ``par`` (a slip slot's tangent) and of
    the tangents' gradients (row-major, ``(m n) x (n + npar)``, as ``d_contacts``; a frictional impact's)."""
    par = r.inputs[-1]
    return Routine(
        "d_friction",
        r.inputs,
        (
            Output("dmu", jacobian(r.output("mu").expr, list(par.symbols))),
            Output("dtgrad", _matrix_tangent(r, "tgrad")),
        ),
        "Partials of each contact's mu_f in par and of its tangent's gradient in (q, par) (Coulomb).",
    )


def friction_cone_tangent(r: Routine) -> Routine:
    """``d_friction_cone(q, par)``: partials of the second tangents' gradients (row-major, ``(m n) x (n +
    npar)``, as ``d_friction``'s ``dtgrad``; an isotropic cone's impulse direction at an impact)."""
    return Routine(
        "d_friction_cone",
        r.inputs,
        (Output("dtgrad2", _matrix_tangent(r, "tgrad2")),),
        "Partials of each cone contact's second tangent's gradient in (q, par) (Coulomb, two tangents).",
    )


_TANGENTS = memo.Lru()  # memo.routines_key(routines) -> (routines, their d_* routines): vcigen.memo


def tangent_routines(routines: dict[str, Routine]) -> dict[str, Routine]:
    """The ``d_*`` routines of the derived ``routines`` (a :class:`DiscreteSystem`'s), by name.

    Derived once per process for the same expressions (:mod:`vcigen.memo`): a copy of the first result;
    derived by another process, read from disk (:mod:`vcigen.diskmemo`)."""
    if not memo.enabled():
        return _tangent_routines(routines)
    key, held = memo.routines_key(routines)
    # what the key names is kept in the entry, so that its identities are not reused while the entry lives
    _, out = _TANGENTS.get_or_make(key, lambda: (held, _tangent_routines_stored(routines)))
    return memo.copy_routines(out)


def _tangent_routines_stored(routines: dict[str, Routine]) -> dict[str, Routine]:
    """:func:`_tangent_routines`, read from the disk memo when the same routines (up to their dummies'
    indices) were differentiated before."""
    if not diskmemo.enabled():
        return _tangent_routines(routines)
    try:
        nodes, payload, dummies = diskmemo.encode(routines, {}, canonical=True)
    except (pickle.PicklingError, TypeError, AttributeError, RecursionError, ValueError):
        return _tangent_routines(routines)
    key = diskmemo.digest(nodes, payload)
    return diskmemo.get_or_make("tangents", key, lambda: _tangent_routines(routines), dummies)


def _tangent_routines(routines: dict[str, Routine]) -> dict[str, Routine]:
    """:func:`tangent_routines` without the memo."""
    out = {
        "d_segment": segment_tangent(routines["segment"]),
        "d_contacts": contacts_tangent(routines["contacts"]),
        "d_legendre": legendre_tangent(routines["legendre"]),
        "d_restitution": restitution_tangent(routines["restitution"]),
    }
    if "friction" in routines:
        out["d_friction"] = friction_tangent(routines["friction"])
    if "friction_cone" in routines:
        out["d_friction_cone"] = friction_cone_tangent(routines["friction_cone"])
    if "rows" in routines:
        out["d_rows"] = rows_tangent(routines["rows"])
        out["d_forces"] = forces_tangent(routines)
        out["d_psi"] = psi_tangent(routines["rows"])
    if "rattle_end" in routines:  # internal points held on the rows (lobatto3): p+ of the held step
        out["d_rattle_end"] = rattle_end_tangent(routines["rattle_end"])
    for name, r in routines.items():
        if _covered(name):
            out[TANGENT_PREFIX + name] = residual_tangent(r)
    return out
