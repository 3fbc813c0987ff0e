"""Coulomb friction at an impact (MATH.md, *Friction*; paper (38)-(39)): the impulse law, pure functions.

At an impact on a contact with normal ``n = grad phi`` and tangent ``t = grad psi`` (the sliding velocity
is ``t . qdot``), the impulse is ``P = mu_n n + mu_t t``. The normal velocity leaves with ``-e`` times its
incoming value (Newton), and ``mu_t`` takes the most energy out that Coulomb's cone ``|mu_t| <= mu_f mu_n``
allows (maximal dissipation). With ``A = M^-1`` and ``d = t - b n``, ``b = n.A t / n.A n`` (the tangent
``A``-orthogonal to ``n``), ``mu_n = a - b mu_t`` with ``a = -(1 + e) n.qdot / n.A n``, and the kinetic
energy after is a quadratic in ``mu_t`` alone: minimised over the cone's interval. Where the minimiser is
inside, the contact sticks (with ``n.A t = 0``, e.g. a disk on a floor: the sliding velocity leaves at 0,
rolling); at an end it slips. ``mu_t = 0`` is in the interval, so the energy never rises above the
frictionless law's, which never rises above the incoming one. The stepper then solves the jump (48) along
the impulse direction ``n + (mu_t / mu_n) t`` with the energy target changed by ``dK``.
"""

from __future__ import annotations

import math

import numpy as np


def impact_law(vel: np.ndarray, mass: np.ndarray, n: np.ndarray, t: np.ndarray, mu_f: float, e: float):
    """``(mu_n, mu_t, dK, M^-1 n, M^-1 t)``: the impulses, the kinetic energy change, and the two solves."""
    an, at = np.linalg.solve(mass, np.column_stack([n, t])).T
    nv, tv = float(n @ vel), float(t @ vel)
    nn, nt, tt = float(n @ an), float(n @ at), float(t @ at)
    a = max(-(1.0 + e) * nv / nn, 0.0)
    b = nt / nn
    dv, dad = tv - b * nv, tt - b * nt  # d . qdot and d . A d
    mu_t = -dv / dad if dad > 0.0 else 0.0
    hi = mu_f * a / (1.0 + mu_f * b) if 1.0 + mu_f * b > 0.0 else math.inf
    lo = -mu_f * a / (1.0 - mu_f * b) if 1.0 - mu_f * b > 0.0 else -math.inf
    mu_t = min(max(mu_t, lo), hi)
    mu_n = a - b * mu_t
    dk = mu_t * dv + 0.5 * mu_t * mu_t * dad + a * nv + 0.5 * a * a * nn
    return mu_n, mu_t, dk, an, at
