"""What a scene allows, detected once per derived system: the :class:`Structure` both backends read.

Like acados' "make consistent" step, the structure of a scene is decided in one place
(:func:`detect`, run once by :attr:`vcigen.derive.DiscreteSystem.structure` on first use) and
every backend reads the one object: the CasADi kernels (:mod:`vcigen.backends.casadi`), the C
render context (:mod:`vcigen.backends.ccontext`, which prints it in the generated header) and
the C kernels (:mod:`vcigen.backends.cwrap`). The routines that exploit a flag are built by their
own modules (:mod:`vcigen.explicit`, :mod:`vcigen.implicit`, :mod:`vcigen.held`) when it is set.

* **Internal points** (``stages``): a rule whose ``L_d`` is an extremum over internal points
  (``lobatto3``) appends their unknowns ``u`` to every phase's; then every phase is a Newton on
  ``(x, u)`` and none of the specialisations below applies, except:
* **Stage eliminated** (``stage_reduced``, ``stage_linear``; :mod:`vcigen.stage`): for ``T - V`` with a
  constant mass the momentum rows of (46) are linear in ``v`` at a fixed internal point: solved for ``v``
  in closed form, the implicit grid step is a Newton on the internal point alone (``n`` unknowns, not
  ``2n``); when the rows left are linear in it too (a quadratic ``V``) one linear solve is exact.
* **Linear smooth step** (``smooth_linear``, ``smooth_diagonal``): the smooth residual (46) is
  ``p-(q0, v, tau) - p0``; when its Jacobian is free of ``v`` (a constant mass matrix) one Newton
  step from any guess is exact, and a diagonal Jacobian makes it a division. Otherwise the grid
  step is the implicit one (``implicit_grid``, :mod:`vcigen.implicit`): Newton on (46) from the
  step's hoisted invariants, carried to the next step when ``par`` is fixed over a run (``carry``).
* **Constant diagonal mass** (``mass_diagonal``): the velocity of a momentum is a division.
* **Explicit grid step** (``explicit_grid``, :mod:`vcigen.explicit`): (46) with a constant diagonal
  Jacobian and a constant diagonal mass, no forces: a grid step is straight-line code.
* **Explicit contact path** (``explicit_path``): (46) linear in ``v`` with a diagonal Jacobian, no
  forces: ``v(s)`` is explicit and the contact time (47) a scalar root along the segment map.
* **Quadratic jump** (``jump_quadratic``): an explicit scene whose ``E_d`` is quadratic in the
  velocity: the jump (48) is a quadratic in ``mu``.
* **Held grid step** (``held``, :mod:`vcigen.held`): rows of sustained contact in an explicit scene
  with momentum ``M qdot`` and no friction: a grid step in sustained contact is straight-line code;
  ``held_pattern``, ``held_columns`` and ``held_constant`` say what of its rows it
  specialises further; ``held_closed`` the rows whose held step, held alone, is closed-form (one square root,
  no Newton: :func:`vcigen.held.closed_forms`).
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, field

import sympy as sp

from .derive import DiscreteSystem
from .explicit import expanded, quadratic_energy, smooth_jacobian
from .held import closed_forms, free_parts, row_hessian
from .held_circle import circle_forms
from .stage import reduced_smooth

# The flags in the order the generated header lists them (Structure.lines).
FLAGS = (
    "stages",
    "stage_reduced",
    "stage_linear",
    "smooth_linear",
    "smooth_diagonal",
    "implicit_grid",
    "carry",
    "mass_diagonal",
    "explicit_grid",
    "explicit_path",
    "jump_quadratic",
    "held",
)


@dataclass(frozen=True)
class Structure:
    """What a scene allows, and why (:func:`detect`; ``why[flag]``: the reason for each of :data:`FLAGS`)."""

    stages: int  # internal unknowns of a segment (DiscreteSystem.stages): 0 for most rules
    stage_reduced: bool  # momentum rows solved for v in closed form: Newton on n unknowns (vcigen.stage)
    stage_linear: bool  # ... and the rows left are linear in the internal point: the grid step is explicit
    smooth_linear: bool  # (46) linear in v: one Newton step is exact (C: one linear solve)
    smooth_diagonal: bool  # ... with a diagonal Jacobian: a division
    implicit_grid: bool  # the grid step is Newton on (46) from hoisted invariants (vcigen.implicit)
    carry: bool  # ... its invariants carried from step to step (par fixed over a run)
    mass_diagonal: bool  # the mass matrix is constant and diagonal
    explicit_grid: bool  # a grid step is straight-line code (vcigen.explicit)
    explicit_path: bool  # the contact time (47) is a scalar root along the explicit segment map
    jump_quadratic: bool  # the jump (48) is a quadratic in mu
    held: bool  # a grid step in sustained contact is straight-line code (vcigen.held)
    held_pattern: tuple[tuple[int, int, int], ...] = ()  # (i, j, weight) where a row's Hessian is not 0
    held_columns: tuple[int, ...] = ()  # coordinates where some row's gradient is not identically 0
    held_constant: tuple[int, ...] = ()  # per row, coordinate (r * n + i): 1 where d psi_r/d q_i is constant
    held_closed: tuple[bool, ...] = ()  # per row, whether held alone its step is closed-form (closed_forms)
    held_circle: tuple[bool, ...] = ()  # per row, whether that closed step is a rotation (held_circle)
    # the forms behind held_closed and held_circle, detected here once for vcigen.held.held_routines to read
    held_closed_forms: tuple = field(default=(), compare=False, repr=False)
    held_circle_forms: tuple = field(default=(), compare=False, repr=False)
    why: dict[str, str] = field(default_factory=dict, compare=False)

    def lines(self, width: int = 96) -> list[str]:
        """``name = value: why`` per flag, wrapped at ``width`` (the generated header's comment block)."""
        out = [f"{f} = {int(getattr(self, f))}: {self.why[f]}" for f in FLAGS]
        if self.held:
            out.append(
                f"held_pattern = {[list(p) for p in self.held_pattern]}: (i, j, weight) where some row's "
                "Hessian is not identically 0 (the curvature u . Hess psi . u needs no other entries)"
            )
            if any(self.held_closed):
                out.append(
                    f"held_closed = {[int(x) for x in self.held_closed]}: per row, 1 where, held alone, its "
                    "step is closed-form: F(a + Lam b) = 0 a quadratic in Lam, its root by one sqrt, the "
                    "projection dividing by a constant (a sphere's row) or by W(q1) (a quadric's: "
                    f"{[int(not c.fixed) if c else 0 for c in self.held_closed_forms]}; held.closed_forms); "
                    "no Newton"
                )
            if any(self.held_circle):
                out.append(
                    f"held_circle = {[int(x) for x in self.held_circle]}: per row, 1 where that step is a "
                    "rotation (a circle under a force affine in q, isotropic mass: held_circle), its loop "
                    "carrying the next sqrt's argument: one multiply-add between two sqrt"
                )
        return [w for line in out for w in textwrap.wrap(line, width, subsequent_indent="    ")]

    def notes(self, system: DiscreteSystem) -> list[str]:
        """Plain-language lines for the top of the generated source."""
        names = ", ".join(system.contact_names) or "none"
        lines = [
            f"contacts: {system.m} ({names}); only these are generated",
            f"sizes fixed: n = {system.n}, m = {system.m}; {len(system.params)} parameters as runtime inputs",
        ]
        if self.stage_linear:
            lines.append(
                "smooth step (46): momentum rows solved for v in closed form, the stage linear in the "
                "internal point -> one n x n solve, no Newton (vcigen.stage)"
            )
        elif self.stage_reduced:
            lines.append(
                "smooth step (46): momentum rows solved for v in closed form -> Newton on the internal point "
                "alone, n unknowns instead of 2n (vcigen.stage)"
            )
        elif self.smooth_diagonal:
            lines.append(
                "smooth step (46): residual linear in v with a diagonal Jacobian -> one division, no Newton"
            )
        elif self.smooth_linear:
            lines.append(
                "smooth step (46): residual linear in v (constant mass matrix) -> one LU solve, no Newton"
            )
        else:
            lines.append("smooth step (46): configuration-dependent mass -> damped Newton")
        if self.explicit_path:
            lines.append(
                "contact time (47): position explicit in alpha -> safeguarded scalar Newton on alpha"
            )
        else:
            lines.append("contact time (47): Newton on (v, alpha)")
        if self.mass_diagonal:
            lines.append("velocity of a momentum (crossing slopes): constant diagonal mass -> one division")
        if self.jump_quadratic:
            lines.append("jump (48): a quadratic in mu -> closed-form root, Newton only checks it")
        if self.explicit_grid:
            lines.append(
                "grid step away from contacts: one straight-line routine (v, q, p, E_d, phi, "
                "slope); subexpressions of (h, par) hoisted out of the loop, computed once per run"
            )
        lines.append(
            "grid test: phi and grad phi at q_k reused from the previous step; sub-solves use phi only"
        )
        if self.implicit_grid:
            lines.append(
                "grid step: Newton on the step's invariants (hoisted, carried from the step before), a "
                "fixed-size solve; p+, E_d, phi, the end slope and the next invariants from one CSE'd routine"
            )
        return lines


def _diagonal_free_of(a: sp.Matrix, symbols: set[sp.Symbol]) -> bool:
    """Whether ``a`` is diagonal and free of ``symbols``."""
    off = (a[i, k] for i in range(a.rows) for k in range(a.cols) if i != k)
    return not (a.free_symbols & symbols) and all(e == 0 for e in off)


def _mass_diagonal(system: DiscreteSystem) -> bool:
    """Whether the mass matrix ``d2L/dqdot2`` is constant and diagonal."""
    leg = system.routines["legendre"]
    return _diagonal_free_of(
        expanded(leg.output("mass").expr), set(leg.input("q").symbols) | set(leg.input("v").symbols)
    )


def _momentum_is_mass_times_velocity(system: DiscreteSystem) -> bool:
    """Whether ``dL/dqdot = M qdot`` (no term free of the velocity, as a magnetic potential's)."""
    leg = system.routines["legendre"]
    mom = expanded(leg.output("momentum").expr - leg.output("mass").expr * sp.Matrix(leg.input("v").symbols))
    return all(e == 0 for e in mom)


def hess_pattern(system: DiscreteSystem) -> list[tuple[int, int, int]]:
    """``(i, j, weight)``, ``i <= j``, where some row's Hessian is not identically 0 (weight 2 off the
    diagonal): ``u . Hess psi_r . u = sum weight u_i H_ij u_j`` over them. Empty for rows linear in ``q``
    (floors, walls)."""
    hs = [row_hessian(system, r) for r in range(system.r)]
    n = system.n
    return [
        (i, j, 1 if i == j else 2)
        for i in range(n)
        for j in range(i, n)
        if any(sp.simplify(hm[i, j]) != 0 for hm in hs)
    ]


def gradient_columns(system: DiscreteSystem) -> list[int]:
    """The coordinates ``i`` where some row's gradient ``d psi_r / d q_i`` is not identically 0."""
    grad = system.routines["rows"].output("grad").expr
    n = system.n
    return [i for i in range(n) if any(sp.simplify(grad[k]) != 0 for k in range(i, len(grad), n))]


def constant_gradients(system: DiscreteSystem) -> list[int]:
    """Per row and coordinate (row-major, ``r * n + i``), 1 where ``d psi_r / d q_i`` does not depend on ``q``
    (the same value at every point of a run): the held step's Newton then keeps the value of its first
    evaluation, which the compiler folds where it is a number (a floor's or a wall's gradient)."""
    rows = system.routines["rows"]
    grad, q = rows.output("grad").expr, set(rows.input("q").symbols)
    return [int(not (sp.sympify(g).free_symbols & q)) for g in grad]


def _circles(system: DiscreteSystem, closed: tuple) -> list:
    """:func:`vcigen.held_circle.circle_forms` of the closed rows (``closed``)."""
    fp = free_parts(system)
    return circle_forms(list(closed), fp["q_arg"].symbols, fp["p0_arg"].symbols, fp["v_arg"].symbols, fp)


def _held(system: DiscreteSystem, explicit_grid: bool) -> tuple[bool, str]:
    """Whether the held step applies (rows, an explicit scene, momentum ``M qdot``, no friction), and why."""
    if not system.r:
        return False, "no rows of sustained contact"
    if system.rows.frictional:
        return False, "friction in sustained contact: the general chain (vcigen.sustained)"
    if not explicit_grid:
        return False, "no explicit grid step: the general chain (vcigen.sustained)"
    if not _momentum_is_mass_times_velocity(system):
        return False, "the momentum is not M qdot: the general chain (vcigen.sustained)"
    dyn = system.routines["dynamics"]
    if dyn.output("rhs").expr.free_symbols & set(dyn.input("u").symbols):
        return False, "the free acceleration depends on the velocity: the general chain (vcigen.sustained)"
    return True, (
        "rows, an explicit scene, momentum M qdot, no friction: a grid step in sustained contact is "
        "straight-line code on the active rows' multipliers (vcigen.held)"
    )


def _stage(system: DiscreteSystem, why: dict[str, str]) -> tuple[bool, bool]:
    """``stage_reduced``, ``stage_linear`` (:mod:`vcigen.stage`), their reasons into ``why``."""
    if not system.stages:
        why["stage_reduced"] = why["stage_linear"] = "no internal points"
        return False, False
    red = reduced_smooth(system)
    if red is None:
        why["stage_reduced"] = (
            f"rule {system.rule.name!r} declares {len(system.rule.nodes)} internal nodes (the closed form "
            "takes one)"
            if len(system.rule.nodes) != 1
            else "the momentum rows of (46) are not linear in v at a fixed internal point (a mass matrix "
            "that depends on q, or a force nonlinear in the velocity): Newton on (v, u)"
        )
        why["stage_linear"] = "no closed-form elimination of the stage"
        return False, False
    why["stage_reduced"] = (
        "the momentum rows of (46) are linear in v at a fixed internal point (T - V with a constant mass, "
        "forces linear in the velocity): v in closed form, every Newton on the internal point and the "
        "phase's other unknowns (n, not 2n, for the grid step)"
    )
    linear = not (red.jac().free_symbols & set(red.unknowns))
    why["stage_linear"] = (
        "the stationarity at v(z) is linear in the internal point (a quadratic V): one n x n solve is exact"
        if linear
        else "the stationarity at v(z) is nonlinear in the internal point: Newton on it"
    )
    return True, linear


def detect(system: DiscreteSystem) -> Structure:
    """Detect what ``system`` allows (see the module); run once per system by ``DiscreteSystem.structure``."""
    why: dict[str, str] = {}
    rule, stages, forced = system.rule, system.stages, bool(system.model.force)
    smooth = system.routines["smooth"]
    x, q0 = set(smooth.inputs[0].symbols), set(smooth.input("q0").symbols)
    mass_diagonal = _mass_diagonal(system)
    why["mass_diagonal"] = (
        "d2L/dqdot2 is constant and diagonal: the velocity of a momentum is one division per coordinate"
        if mass_diagonal
        else "d2L/dqdot2 depends on the state or is not diagonal: the velocity of a momentum is an LU solve"
    )
    if stages:
        inside = "internal points: (46) couples v with their unknowns u, Newton on (v, u)"
        why["stages"] = (
            f"rule {rule.name!r} has {rule.stages} internal point(s): their {stages} unknowns u follow every "
            "phase's own in its Newton"
        )
        smooth_linear = smooth_diagonal = explicit_grid = explicit_path = jump = False
        for f in ("smooth_linear", "smooth_diagonal", "explicit_grid", "explicit_path"):
            why[f] = inside
        why["jump_quadratic"] = "internal points: Newton on (w, mu, u)"
    else:
        why["stages"] = f"rule {rule.name!r} has no internal points"
        jac = smooth_jacobian(system)  # expanded: terms that cancel only then do
        smooth_linear = not (jac.free_symbols & x)
        smooth_diagonal = _diagonal_free_of(jac, x)
        why["smooth_linear"] = (
            "the Jacobian of (46) in v is free of v (constant mass matrix): one Newton step is exact"
            if smooth_linear
            else "the Jacobian of (46) in v depends on v"
        )
        why["smooth_diagonal"] = (
            "the Jacobian of (46) is free of v and diagonal: the solve is one division per coordinate"
            if smooth_diagonal
            else "the Jacobian of (46) is not diagonal: one LU solve"
            if smooth_linear
            else "(46) is nonlinear in v"
        )
        if forced:
            explicit_grid = False
            why["explicit_grid"] = "forces: the explicit grid step would hoist what depends on (h, par) alone"
        elif not _diagonal_free_of(jac, x | q0):
            explicit_grid = False
            why["explicit_grid"] = "the Jacobian of (46) depends on the state or is not diagonal"
        elif not mass_diagonal:
            explicit_grid = False
            why["explicit_grid"] = "the mass matrix is not constant and diagonal"
        else:
            explicit_grid = True
            why["explicit_grid"] = (
                "(46) has a constant diagonal Jacobian, the mass is constant and diagonal: a grid step is "
                "straight-line code, its subexpressions of (h, par) computed once per run (vcigen.explicit)"
            )
        explicit_path = system.m > 0 and not forced and smooth_diagonal
        why["explicit_path"] = (
            "(46) is linear in v with a diagonal Jacobian: v(s) is explicit, the contact time (47) a scalar "
            "root along the segment map"
            if explicit_path
            else "no contacts"
            if not system.m
            else "forces: a segment's momentum depends on its start time, the segment map has no closed form"
            if forced
            else "(46) is not linear in v with a diagonal Jacobian: Newton on (v, alpha)"
        )
        jump = explicit_grid and quadratic_energy(system)
        why["jump_quadratic"] = (
            "E_d is quadratic in the velocity and (48b) linear in it: (48) is a quadratic in mu, its root in "
            "closed form (Newton checks it)"
            if jump
            else "E_d is not quadratic in the velocity: Newton on (w, mu)"
            if explicit_grid
            else "no explicit grid step: Newton on (w, mu)"
        )
    stage_reduced, stage_linear = _stage(system, why)
    implicit_grid = not smooth_linear
    why["implicit_grid"] = (
        "internal points: Newton on (v, u) from the step's invariants, hoisted (vcigen.implicit)"
        if stages
        else "(46) is not linear in v: Newton on it from the step's invariants, hoisted (vcigen.implicit)"
        if implicit_grid
        else "(46) is linear in v: no Newton on it"
    )
    varying_par = system.timed or bool(system.rows and system.rows.frictional)
    carry = implicit_grid and not varying_par
    why["carry"] = (
        "the implicit grid step's invariants at q_k+1 are handed to the next step"
        if carry
        else "no implicit grid step"
        if not implicit_grid
        else "par changes between steps (the time of forces, friction's slots): every step computes its own"
    )
    held, why["held"] = _held(system, explicit_grid)
    closed = tuple(closed_forms(system)) if held else ()
    circles = tuple(_circles(system, closed)) if any(c is not None for c in closed) else ()
    return Structure(
        stages=stages,
        stage_reduced=stage_reduced,
        stage_linear=stage_linear,
        smooth_linear=smooth_linear,
        smooth_diagonal=smooth_diagonal,
        implicit_grid=implicit_grid,
        carry=carry,
        mass_diagonal=mass_diagonal,
        explicit_grid=explicit_grid,
        explicit_path=explicit_path,
        jump_quadratic=jump,
        held=held,
        held_pattern=tuple(hess_pattern(system)) if held else (),
        held_columns=tuple(gradient_columns(system)) if held else (),
        held_constant=tuple(constant_gradients(system)) if held else (),
        held_closed=tuple(c is not None for c in closed),
        held_closed_forms=closed,
        held_circle=tuple(c is not None for c in circles),
        held_circle_forms=circles,
        why=why,
    )
