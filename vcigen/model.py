"""The user's mechanical system: coordinates, Lagrangian, contacts, parameters.

A :class:`Model` is validated once, at construction. Internally every
coordinate and velocity is replaced by a *real* SymPy symbol, so that
``Abs``, ``sign``, ``Min`` and ``Max`` in contacts or potentials
differentiate cleanly whatever assumptions the user's symbols carry.
"""

from __future__ import annotations

import keyword
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import sympy as sp

from .model_checks import dependent_everywhere

_C_IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for "
    "goto if inline int long register restrict return short signed sizeof static struct "
    "switch typedef union unsigned void volatile while main".split()
)


def check_identifier(name: str, what: str) -> str:
    """Return ``name`` if it is a usable C and Python identifier, else raise."""
    if not isinstance(name, str) or not _C_IDENTIFIER.match(name):
        raise ValueError(
            f"{what} {name!r} is not a C identifier; use letters, digits and '_' "
            "and start with a letter or '_'"
        )
    if name in _C_KEYWORDS or keyword.iskeyword(name):
        raise ValueError(f"{what} {name!r} is a reserved word in C or Python; rename it")
    return name


def _is_time_function(expr: sp.Basic) -> bool:
    return isinstance(expr, sp.core.function.AppliedUndef) and len(expr.args) == 1


def _coordinate_name(c: sp.Basic) -> str:
    return c.func.__name__ if _is_time_function(c) else str(c)


@dataclass(frozen=True)
class Model:
    """A Lagrangian system with unilateral contacts ``phi_j(q) >= 0``.

    Parameters follow ``shared/API.md``: ``q`` are SymPy symbols or
    ``sympy.physics.mechanics`` dynamicsymbols (``qdot`` is then optional),
    ``contacts`` maps names to ``phi_j(q)``, ``params`` maps symbols to their
    default values. ``restitution`` (optional) maps contact names to a coefficient
    ``e`` in [0, 1] — a number or an expression of parameters, so that it can be
    changed at run time; contacts not named are elastic (``e = 1``). An impact on
    contact j then loses ``(1 - e^2)/2 (n.qdot)^2 / (n.M^-1 n)`` of energy (the
    frictionless ``f_t`` of eq. 39): the normal velocity leaves with ``e`` times its
    incoming size. ``forces`` (optional) is a generalized force ``F(q, qdot, t, params)``, one
    entry per coordinate (Lagrange-d'Alembert, paper §2.5, MATH.md *Forcing*); ``time`` is the
    symbol for time that it may use.
    """

    name: str
    q: Sequence[sp.Basic]
    lagrangian: sp.Expr
    qdot: Sequence[sp.Basic] | None = None
    contacts: Mapping[str, sp.Expr] = field(default_factory=dict)
    params: Mapping[sp.Symbol, float] = field(default_factory=dict)
    restitution: Mapping[str, float | sp.Expr] = field(default_factory=dict)
    constraints: Mapping[str, sp.Expr] = field(default_factory=dict)
    forces: Sequence[sp.Expr] | None = None
    time: sp.Symbol | None = None
    friction: Mapping[str, tuple] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_identifier(self.name, "model name")
        q = list(self.q)
        if not q:
            raise ValueError("model needs at least one coordinate in q")
        qdot = self._velocities(q)
        if len(set(q)) != len(q) or len(set(qdot)) != len(qdot):
            raise ValueError("coordinates and velocities must be distinct symbols")
        names = [_coordinate_name(c) for c in q]
        real_q = [sp.Symbol(nm, real=True) for nm in names]
        real_v = [sp.Symbol(f"{nm}_dot", real=True) for nm in names]
        # Velocities first: for dynamicsymbols they are Derivatives of q.
        subs = list(zip(qdot, real_v)) + list(zip(q, real_q))
        lagr = sp.sympify(self.lagrangian).subs(subs)
        contacts = {
            check_identifier(cname, "contact name"): sp.sympify(phi).subs(subs)
            for cname, phi in dict(self.contacts).items()
        }
        constraints = {
            check_identifier(cname, "constraint name"): sp.sympify(g).subs(subs)
            for cname, g in dict(self.constraints).items()
        }
        clash = set(constraints) & set(contacts)
        if clash:
            raise ValueError(f"{sorted(clash)} name both a contact and a constraint; use distinct names")
        params = self._parameters()
        rest = self._restitution(contacts, params)
        time_sym, forces = self._forces_of(q, subs, names, params)
        fric = self._friction(contacts, params, subs, real_q)
        object.__setattr__(self, "_coords", tuple(real_q))
        object.__setattr__(self, "_vels", tuple(real_v))
        object.__setattr__(self, "_lagr", lagr)
        object.__setattr__(self, "_phis", contacts)
        object.__setattr__(self, "_pars", params)
        object.__setattr__(self, "_rest", rest)
        object.__setattr__(self, "_cons", constraints)
        object.__setattr__(self, "_time", time_sym)
        object.__setattr__(self, "_forces", forces)
        object.__setattr__(self, "_fric", fric)
        self._check_free_symbols()
        self._check_contacts_depend_on_q_only()
        self._check_constraints()
        self._check_regular()

    # -- construction helpers -------------------------------------------------
    def _velocities(self, q: list[sp.Basic]) -> list[sp.Basic]:
        if self.qdot is not None:
            qdot = list(self.qdot)
        elif all(_is_time_function(c) for c in q):
            t = q[0].args[0]
            qdot = [c.diff(t) for c in q]
        else:
            raise ValueError(
                "qdot is required when q holds plain symbols (it is optional only "
                "for sympy.physics.mechanics dynamicsymbols)"
            )
        if len(qdot) != len(q):
            raise ValueError(
                f"q has {len(q)} entries but qdot has {len(qdot)}; give one velocity per coordinate"
            )
        for c in q:
            if not (isinstance(c, sp.Symbol) or _is_time_function(c)):
                raise ValueError(f"coordinate {c!r} is not a SymPy symbol or dynamicsymbol")
        return qdot

    def _parameters(self) -> dict[sp.Symbol, float]:
        params: dict[sp.Symbol, float] = {}
        for sym, val in dict(self.params).items():
            if not isinstance(sym, sp.Symbol):
                raise ValueError(f"parameter key {sym!r} is not a SymPy symbol")
            check_identifier(sym.name, "parameter name")
            try:
                fval = float(val)
            except (TypeError, ValueError):
                raise ValueError(f"default of parameter {sym} is not a number: {val!r}") from None
            if not math.isfinite(fval):
                raise ValueError(f"default of parameter {sym} is not finite: {val!r}")
            params[sym] = fval
        return params

    def _forces_of(self, q, subs, names, params) -> tuple[sp.Symbol | None, tuple[sp.Expr, ...]]:
        """The generalized force ``F(q, qdot, t, params)``, one entry per coordinate (Lagrange-d'Alembert).

        The time symbol becomes a real symbol of the same name. Checked: the length, and that every
        symbol is a coordinate, a velocity, a parameter or the time symbol.
        """
        time_sym = None
        if self.time is not None:
            if not isinstance(self.time, sp.Symbol):
                raise ValueError(f"time = {self.time!r} is not a SymPy symbol")
            check_identifier(self.time.name, "time symbol")
            taken = set(names) | {s.name for s in params}
            if self.time in q or self.time in params or self.time.name in taken:
                raise ValueError(
                    f"time symbol {self.time} is also a coordinate or a parameter; give time its own symbol"
                )
            time_sym = sp.Symbol(self.time.name, real=True)
        if self.forces is None:
            return time_sym, ()
        forces = list(self.forces) if not isinstance(self.forces, (sp.Expr, str)) else [self.forces]
        if len(forces) != len(q):
            raise ValueError(
                f"forces has {len(forces)} entries but q has {len(q)}; "
                "give one generalized force per coordinate"
            )
        tsub = [(self.time, time_sym)] if time_sym is not None else []
        out = []
        allowed = set(s for _, s in subs) | set(params) | ({time_sym} if time_sym is not None else set())
        for i, f in enumerate(forces):
            try:
                expr = sp.sympify(f).subs(subs).subs(tsub)
            except (sp.SympifyError, TypeError):
                raise ValueError(f"force {i} ({names[i]}) is not an expression: {f!r}") from None
            stray = expr.free_symbols - allowed
            funcs = expr.atoms(sp.core.function.AppliedUndef, sp.Derivative)
            if stray or funcs:
                bad = ", ".join(sorted(str(x) for x in stray | funcs))
                hint = "" if time_sym is not None else " (a force of time needs Model(time=t))"
                raise ValueError(
                    f"force {i} ({names[i]}) contains {bad}, which is neither a coordinate, a velocity, "
                    f"a parameter nor the time symbol{hint}"
                )
            out.append(expr)
        return time_sym, tuple(out)

    def _friction(self, contacts, params, subs, real_q) -> dict[str, tuple[sp.Expr, sp.Expr | tuple]]:
        """Coulomb friction per contact: ``(mu_f, tangent)``, ``mu_f >= 0`` a number or an expression of
        parameters, ``tangent`` an expression of ``q`` whose rate is the sliding velocity (MATH.md), or a
        tuple of two such (the two sliding velocities of a 3-D contact: an isotropic cone).
        """
        out = {}
        for name, spec in dict(self.friction).items():
            if name not in contacts:
                raise ValueError(
                    f"friction is given for {name!r}, which is not a contact; "
                    f"the contacts are {sorted(contacts) or 'none'}"
                )
            if not isinstance(spec, (tuple, list)) or len(spec) != 2:
                raise ValueError(f"friction of {name!r} must be a pair (mu_f, tangent), got {spec!r}")
            mu, tangent = spec
            mu = sp.sympify(mu)
            stray = mu.free_symbols - set(params)
            if stray:
                bad = ", ".join(sorted(str(x) for x in stray))
                raise ValueError(
                    f"friction coefficient of {name!r} contains {bad}, which is not a parameter; "
                    "use a number or an expression of parameters"
                )
            if not mu.free_symbols and not float(mu) >= 0.0:
                raise ValueError(f"friction coefficient of {name!r} is {mu}; it must be >= 0")
            tangents = tuple(tangent) if isinstance(tangent, (tuple, list)) else (tangent,)
            if len(tangents) not in (1, 2):
                raise ValueError(
                    f"friction of {name!r} has {len(tangents)} tangents; give one tangent expression, or a "
                    "tuple of two (the isotropic cone of a 3-D contact)"
                )
            tans = []
            for tangent in tangents:
                tan = sp.sympify(tangent).subs(subs)
                extra = tan.free_symbols - set(real_q) - set(params)
                if extra or not tan.free_symbols & set(real_q):
                    raise ValueError(
                        f"friction tangent of {name!r} = {tangent} must be an expression of the coordinates "
                        "(and parameters) that depends on q"
                    )
                tans.append(tan)
            if len(tans) == 2 and sp.simplify(tans[0] - tans[1]) == 0:
                raise ValueError(f"friction of {name!r}: its two tangents are the same expression")
            if dependent_everywhere([contacts[name], *tans], real_q, params):
                what = (
                    f"the gradient of its tangent {tans[0]} is parallel to the contact's normal grad phi"
                    if len(tans) == 1
                    else "the gradients of its two tangents and the contact's normal grad phi are dependent"
                )
                raise ValueError(
                    f"friction of {name!r}: {what} everywhere (tested at random q), so it measures no "
                    "sliding along the contact; a tangent's rate is the sliding velocity (for a floor "
                    "phi = y, the tangent is x)"
                )
            out[name] = (mu, tans[0] if len(tans) == 1 else tuple(tans))
        return out

    def _restitution(
        self, contacts: Mapping[str, sp.Expr], params: Mapping[sp.Symbol, float]
    ) -> dict[str, sp.Expr]:
        """Coefficient of restitution per contact (1 where not given), checked."""
        rest = {name: sp.S.One for name in contacts}
        for name, value in dict(self.restitution).items():
            if name not in contacts:
                raise ValueError(
                    f"restitution is given for {name!r}, which is not a contact; "
                    f"the contacts are {sorted(contacts) or 'none'}"
                )
            expr = sp.sympify(value)
            stray = expr.free_symbols - set(params)
            if stray:
                bad = ", ".join(sorted(str(x) for x in stray))
                raise ValueError(
                    f"restitution of {name!r} contains {bad}, which is not a parameter; "
                    "use a number or an expression of parameters"
                )
            if not expr.free_symbols:
                e = float(expr)
                if not 0.0 <= e <= 1.0:
                    raise ValueError(f"restitution of {name!r} is {e}; it must lie in [0, 1]")
            rest[name] = expr
        return rest

    def _check_free_symbols(self) -> None:
        allowed = set(self._coords) | set(self._vels) | set(self._pars)
        for what, expr in [
            ("the Lagrangian", self._lagr),
            *((f"contact {n!r}", e) for n, e in self._phis.items()),
            *((f"constraint {n!r}", e) for n, e in self._cons.items()),
        ]:
            stray = expr.free_symbols - allowed
            funcs = expr.atoms(sp.core.function.AppliedUndef, sp.Derivative)
            if self.time is not None and any(s.name == self.time.name for s in stray):
                raise ValueError(
                    f"{what} depends on the time symbol {self.time}: time enters through forces only (the "
                    "Lagrangian is L(q, qdot), contacts and constraints are functions of q, with "
                    "parameters); for a moving boundary write the scene in the boundary's frame with a force "
                    "of time, as examples/forced/conveyor.py does"
                )
            if stray or funcs:
                bad = ", ".join(sorted(str(s) for s in stray | funcs))
                raise ValueError(
                    f"{what} contains {bad}, which is neither a coordinate, a velocity "
                    "nor a parameter; add it to params with a default value"
                )
        names = [s.name for s in (*self._coords, *self._pars)]
        if len(set(names)) != len(names):
            raise ValueError(f"coordinate and parameter names must be unique: {names}")

    def _check_contacts_depend_on_q_only(self) -> None:
        for n, e in self._phis.items():
            if e.free_symbols & set(self._vels):
                raise ValueError(f"contact {n!r} depends on a velocity; phi must be a function of q only")
            if not e.free_symbols & set(self._coords):
                raise ValueError(
                    f"contact {n!r} = {e} does not depend on any coordinate; phi(q) >= 0 bounds nothing"
                )
            if e.is_nonnegative:  # SymPy proves it for every real q (and the parameters' assumptions)
                raise ValueError(
                    f"contact {n!r} = {e} is never negative, so nothing can cross it and it bounds nothing; "
                    "phi is a signed gap, below 0 on the forbidden side (a floor at y = 0 is y, not y**2)"
                )

    def _check_constraints(self) -> None:
        """Bilateral constraints ``g_i(q) = 0``: functions of ``q`` that depend on ``q``."""
        for n, e in self._cons.items():
            if e.free_symbols & set(self._vels):
                raise ValueError(
                    f"constraint {n!r} depends on a velocity; constraints must be holonomic, g(q) = 0"
                )
            if not e.free_symbols & set(self._coords):
                raise ValueError(
                    f"constraint {n!r} = {e} does not depend on any coordinate; it constrains nothing"
                )

    def _check_regular(self) -> None:
        mass = self.mass_matrix
        if mass.free_symbols & set(self._coords) and mass.shape[0] > 3:
            return  # symbolic determinant too costly; checked numerically at run time
        det = sp.simplify(mass.det())
        if det == 0:
            raise ValueError(
                "the Lagrangian is singular: d2L/dqdot2 has zero determinant, so the "
                "velocities cannot be recovered from the momenta; every coordinate needs "
                "kinetic energy"
            )

    # -- the internal, real-symbol view ---------------------------------------
    @property
    def coordinates(self) -> tuple[sp.Symbol, ...]:
        """Real symbols standing for ``q``."""
        return self._coords  # type: ignore[attr-defined]

    @property
    def velocities(self) -> tuple[sp.Symbol, ...]:
        """Real symbols standing for ``qdot``."""
        return self._vels  # type: ignore[attr-defined]

    @property
    def L(self) -> sp.Expr:
        """The Lagrangian in the real symbols."""
        return self._lagr  # type: ignore[attr-defined]

    @property
    def phi(self) -> dict[str, sp.Expr]:
        """Contact functions by name, in the real symbols."""
        return dict(self._phis)  # type: ignore[attr-defined]

    @property
    def defaults(self) -> dict[sp.Symbol, float]:
        """Parameter symbols and their default values (insertion order kept)."""
        return dict(self._pars)  # type: ignore[attr-defined]

    @property
    def restitution_of(self) -> dict[str, sp.Expr]:
        """Coefficient of restitution by contact (1: elastic), numbers or expressions of parameters."""
        return dict(self._rest)  # type: ignore[attr-defined]

    def restitution_values(self, par: Sequence[float]) -> list[float]:
        """The coefficients at parameter values ``par`` (model order); raises if one is outside [0, 1]."""
        values = dict(zip(self.defaults, par))
        out = []
        for name, expr in self.restitution_of.items():
            e = float(expr.xreplace(values))
            if not 0.0 <= e <= 1.0:
                raise ValueError(f"restitution of {name!r} is {e} at these parameters; it must lie in [0, 1]")
            out.append(e)
        return out

    @property
    def constraint(self) -> dict[str, sp.Expr]:
        """Bilateral holonomic constraints ``g_i(q) = 0`` by name, in the real symbols."""
        return dict(self._cons)  # type: ignore[attr-defined]

    @property
    def force(self) -> tuple[sp.Expr, ...]:
        """The generalized force per coordinate in the real symbols; ``()`` without forces or all 0."""
        forces = self._forces  # type: ignore[attr-defined]
        return forces if any(f != 0 for f in forces) else ()

    @property
    def friction_of(self) -> dict[str, tuple[sp.Expr, sp.Expr | tuple[sp.Expr, sp.Expr]]]:
        """Coulomb friction by contact: ``(mu_f, tangent)`` in the real symbols (frictional contacts only);
        ``tangent`` a tuple of two for the isotropic cone of a 3-D contact."""
        return dict(self._fric)  # type: ignore[attr-defined]

    @property
    def tangents_of(self) -> dict[str, tuple[sp.Expr, ...]]:
        """The tangent expressions of each frictional contact: one, or two (an isotropic cone)."""
        return {c: t if isinstance(t, tuple) else (t,) for c, (_, t) in self.friction_of.items()}

    def friction_values(self, par: Sequence[float]) -> list[float]:
        """``mu_f`` of every contact (0 where frictionless) at ``par``; raises if one is negative."""
        values = dict(zip(self.defaults, par))
        out = []
        for name in self.phi:
            mu = float(self.friction_of[name][0].xreplace(values)) if name in self.friction_of else 0.0
            if not mu >= 0.0:
                raise ValueError(
                    f"friction coefficient of {name!r} is {mu} at these parameters; it must be >= 0"
                )
            out.append(mu)
        return out

    @property
    def time_symbol(self) -> sp.Symbol | None:
        """The real symbol standing for time in :attr:`force`, if the force depends on time."""
        t = self._time  # type: ignore[attr-defined]
        return t if t is not None and any(t in f.free_symbols for f in self.force) else None

    @property
    def n(self) -> int:
        return len(self.coordinates)

    @property
    def mass_matrix(self) -> sp.Matrix:
        """``d2L/dqdot2``, the matrix that must be nonsingular."""
        from .calculus import hessian

        return hessian(self.L, self.velocities)

    @property
    def coordinate_names(self) -> list[str]:
        return [c.name for c in self.coordinates]

    def resolve_params(self, overrides: Mapping[object, float] | None) -> list[float]:
        """Default parameter values with ``overrides`` (keys: symbols or names)."""
        values = dict(self.defaults)
        by_name = {s.name: s for s in values}
        for key, val in dict(overrides or {}).items():
            name = key.name if isinstance(key, sp.Symbol) else key
            if name not in by_name:
                raise ValueError(f"unknown parameter {key!r}; the model has {sorted(by_name) or 'none'}")
            fval = float(val)
            if not math.isfinite(fval):
                raise ValueError(f"parameter {name} is not finite: {val!r}")
            values[by_name[name]] = fval
        return list(values.values())
