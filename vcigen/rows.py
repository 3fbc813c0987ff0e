"""Rows of sustained contact: smooth constraint functions the constrained step holds at 0.

A contact in sustained contact is held as ``psi_r(q) = 0`` (MATH.md, *Sustained contact*).
For a smooth contact the row is ``phi_j`` itself. A contact with *concave kinks*, each
``Abs(u_i)`` entering ``phi_j`` with a coefficient ``<= 0`` (the star's
``y - L/2 (|sin theta| + |cos theta|)``, eq. 81), is the minimum of its smooth branches
``psi_sigma = phi_j(Abs(u_i) -> sigma_i u_i)``, ``sigma_i = +-1``: the admissible set is the
intersection of ``psi_sigma >= 0`` and each branch is one vertex or face of the body. Those
branches are the rows, so that a body resting on a face (two branches at 0: the kink of
eq. 86) is two smooth constraints with two multipliers ``lambda >= 0``. Bilateral
``constraints`` of the model are rows too, always active, with multipliers of either sign.

Pure SymPy: a model in, plain data out.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import sympy as sp

from .model import Model

MAX_BRANCH_KINKS = 4  # at most 2**4 branch rows per contact; more kinks keep phi as one row


@dataclass(frozen=True)
class Rows:
    """The rows: expression, owning contact (index into the contacts, or -1), bilateral flag."""

    exprs: tuple[sp.Expr, ...]
    contact: tuple[int, ...]  # contact index of each row; -1 for a bilateral constraint
    constraint: tuple[int, ...]  # constraint index of each row; -1 for a contact row
    names: tuple[str, ...]  # "floor", "floor[+-]" for a branch, the constraint's name, "floor/stick"
    stick: tuple[int, ...] = ()  # frictional contact index of a stick row (vcigen.friction), -1 otherwise
    slips: tuple[sp.Symbol, ...] = ()  # per frictional contact: its slip coefficient -mu_f s (a par slot)
    refs: tuple[
        sp.Symbol, ...
    ] = ()  # per frictional contact: the tangent's value while it sticks (a par slot)
    frictional: tuple[int, ...] = ()  # per frictional contact: its contact index
    # per frictional contact: the sign() atoms of its tangent become par slots while it sticks (the branch it
    # sticks on, so that a kinked body's tangent stays that of one vertex or face), and their arguments
    branches: tuple[tuple[sp.Symbol, ...], ...] = ()
    branch_args: tuple[tuple[sp.Expr, ...], ...] = ()
    # per frictional contact: the other tangent's frictional contact of a two-tangent (cone) contact, or -1
    partner: tuple[int, ...] = ()

    @property
    def size(self) -> int:
        return len(self.exprs)

    @property
    def bilateral(self) -> tuple[bool, ...]:
        return tuple(c >= 0 for c in self.constraint)

    @property
    def sticks(self) -> tuple[int, ...]:
        """``stick`` padded to every row (-1: not a stick row)."""
        return self.stick or (-1,) * self.size


def _concave_kinks(phi: sp.Expr) -> list[sp.Abs] | None:
    """The ``Abs`` atoms of ``phi`` if each enters linearly with a coefficient ``<= 0``, else None."""
    atoms = sorted(phi.atoms(sp.Abs), key=sp.default_sort_key)
    if not atoms or len(atoms) > MAX_BRANCH_KINKS:
        return None
    if phi.atoms(sp.sign, sp.Heaviside, sp.Min, sp.Max, sp.Piecewise):
        return None
    dummies = [sp.Dummy(f"a{i}") for i in range(len(atoms))]
    flat = phi.xreplace(dict(zip(atoms, dummies)))
    if flat.atoms(sp.Abs):  # nested: an Abs inside another
        return None
    for a in dummies:
        coeff = flat.diff(a)
        if coeff.free_symbols & set(dummies) or not coeff.is_nonpositive:
            return None
    return atoms


def contact_rows(model: Model) -> Rows:
    """Rows of every contact (its smooth branches, see the module) and every bilateral constraint."""
    exprs, owner, cons, names = [], [], [], []
    for j, (name, phi) in enumerate(model.phi.items()):
        kinks = _concave_kinks(phi)
        if kinks is None:
            exprs.append(phi)
            owner.append(j)
            cons.append(-1)
            names.append(name)
            continue
        for signs in itertools.product((1, -1), repeat=len(kinks)):
            rep = {a: s * a.args[0] for a, s in zip(kinks, signs)}
            exprs.append(phi.xreplace(rep))
            owner.append(j)
            cons.append(-1)
            names.append(f"{name}[{''.join('+' if s > 0 else '-' for s in signs)}]")
    for i, (name, g) in enumerate(model.constraint.items()):
        exprs.append(g)
        owner.append(-1)
        cons.append(i)
        names.append(name)
    # Stick rows (Coulomb friction in sustained contact): tangent(q) - ref = 0 while a contact sticks. A
    # contact with two tangents (an isotropic cone) has two of them, each with its own slots: the two
    # "frictional contacts" f of one contact are partners, switched together (vcigen.sustained).
    stick = [-1] * len(exprs)
    slips, refs, frictional, branches, branch_args, partner = [], [], [], [], [], []
    contacts = list(model.phi)
    for name, tangents in model.tangents_of.items():
        for d, tangent in enumerate(tangents):
            tag = name if d == 0 else f"{name}_{d + 1}"
            f = len(frictional)
            slips.append(sp.Symbol(f"slip_{tag}", real=True))
            refs.append(sp.Symbol(f"stick_{tag}", real=True))
            frictional.append(contacts.index(name))
            partner.append(-1 if len(tangents) == 1 else (f + 1 if d == 0 else f - 1))
            atoms = sorted(tangent.atoms(sp.sign), key=sp.default_sort_key)
            sigma = tuple(sp.Symbol(f"branch_{tag}_{i}", real=True) for i in range(len(atoms)))
            branches.append(sigma)
            branch_args.append(tuple(a.args[0] for a in atoms))
            exprs.append(tangent.xreplace(dict(zip(atoms, sigma))) - refs[-1])
            owner.append(-1)
            cons.append(-1)
            names.append(f"{name}/stick" if d == 0 else f"{name}/stick{d + 1}")
            stick.append(f)
    if not frictional:
        return Rows(tuple(exprs), tuple(owner), tuple(cons), tuple(names))
    return Rows(
        tuple(exprs),
        tuple(owner),
        tuple(cons),
        tuple(names),
        tuple(stick),
        tuple(slips),
        tuple(refs),
        tuple(frictional),
        tuple(branches),
        tuple(branch_args),
        tuple(partner),
    )
