"""The tangent through a friction switch inside a held step (MATH.md *Friction*, *Exact sensitivities*): a
located event like a lift-off, carried by :meth:`vcigen.sensitivity_held.HeldTangents.event`.

A one-tangent contact that slips and stops inside a constrained sub-step (``"stop"``) has its event at the
root of its sliding speed ``g(s) = grad t(q1(s)) . u1(s)`` along the sub-step map
(``SustainedSteps._friction_events``); one that sticks and whose force reaches the cone (``"slide"``) at the
root of its cone margin ``g(s) = mu_f sum_r lambda_r - |lambda_t|`` (the force law at ``(q1(s), u1(s))``,
``SustainedSteps._cone_margin``). A small change of the data keeps the mode sequence and moves the root
smoothly: ``d tau_s = -(dg|_{tau_s}) / (dg/d tau_s)`` (:meth:`HeldTangents._located`). The rest of the step
runs in the new mode from the event point (``Tracker.held``, ``entry``): a stick's reference ``ref = t(q*)``
moves with the point it stuck at, ``d ref = grad t(q*) dq*``; a slip's slot ``-mu_f s`` with ``mu_f``
(:meth:`HeldTangents._friction_slots`). C: ``templates/sens_switch.c.j2``.
"""

from __future__ import annotations

import numpy as np


class SwitchTangents:
    """The root of a friction switch's event, for :meth:`HeldTangents._located` (a mixin of ``Tracker``)."""

    def _switch_root(self, kind: str, q1, u1, act, r: int, par, dd) -> np.ndarray:
        """The tangent of the root function of a friction switch of stick row ``r`` at the end ``(q1, u1)``
        of a sub-step, ``dd`` the tangent of ``(q1, u1, par)`` (any number of columns).

        ``"stop"``: the sliding speed ``g = grad t(q1) . u1``, ``dg = u1^T (d grad t) (dq1, dpar) + grad t
        du1`` (``d_rows``). ``"slide"``: the cone margin ``mu_f N - |lambda_t|``, ``N`` the sum of the
        contact's row forces (:meth:`_dforce` of each, the stick row held; no contact slips in a carried
        slide, ``SustainedSteps._sw_covered``: the force law frictionless) and ``mu_f`` moving with ``par``
        (``d_friction``)."""
        n, k, tg = self.n, self.k, self.tg
        if kind == "stop" and k.partner[k.row_stick[r]] >= 0:  # a cone: the sliding along its slip, -slip . w
            return self._cone_stop_root(q1, u1, r, par, dd)
        if kind == "stop":
            _, grad, _ = tg.get("rows")(q1, u1, par)
            dgrad = tg.get("d_rows")(q1, u1, par)[0][r * n : (r + 1) * n]
            dqp = np.vstack([dd[:n], dd[2 * n :]])
            return u1 @ (dgrad @ dqp) + grad[r] @ dd[n : 2 * n]
        f = k.row_stick[r]
        j = k.frictional[f]
        lam = self._switch_forces(q1, u1, act, par)
        rows = [x for x in np.flatnonzero(act) if k.row_contact[x] == j]
        normal = float(sum(lam[x] for x in rows))
        mu = float(k.friction(q1)[0][j])
        dmu = tg.get("d_friction")(q1, par)[0][j] @ dd[2 * n :]
        dn = sum(self._dforce(q1, u1, act, x, par, dd) for x in rows)
        return dmu * normal + mu * dn - np.sign(lam[r]) * self._dforce(q1, u1, act, r, par, dd)

    def _cone_stop_root(self, q1, u1, r: int, par, dd) -> np.ndarray:
        """A slipping cone's stop (``SustainedSteps._cone_stop``; ``r`` its first stick row): the root ``g =
        -(slip_f w_1 + slip_p w_2)``, ``w_i = grad t_i(q1) . u1``, the slots ``slip = -mu_f s`` parameters
        whose tangents ``dd`` carries (the slip's aim moves with the segment's start: ``_cone_slots``)."""
        n, k, tg = self.n, self.k, self.tg
        f = k.row_stick[r]
        pf, fs = k.partner[f], k.friction_slot
        rows = (r, k.row_stick.index(pf))
        _, grad, _ = tg.get("rows")(q1, u1, par)
        dgrad = tg.get("d_rows")(q1, u1, par)[0]
        dqp = np.vstack([dd[:n], dd[2 * n :]])
        out = np.zeros(dd.shape[1])
        for g, x in zip((f, pf), rows):
            w = float(grad[x] @ u1)
            dw = u1 @ (dgrad[x * n : (x + 1) * n] @ dqp) + grad[x] @ dd[n : 2 * n]
            out -= par[fs + g] * dw + w * dd[2 * n + fs + g]
        return out

    def _switch_forces(self, q1, u1, act, par) -> np.ndarray:
        """The rows' forces at ``(q1, u1)`` (``SustainedSteps._forces``, frictionless: the stick row held)."""
        n, tg = self.n, self.tg
        rows = np.flatnonzero(act)
        _, grad, curv = tg.get("rows")(q1, u1, par)
        rhs = tg.get("dynamics")(q1, u1, par)[0][:, 0]
        mass = tg.get("legendre")(q1, u1, par)[1]
        g = grad[rows]
        jac = np.block([[mass, -g.T], [g, np.zeros((rows.size, rows.size))]])
        sol = np.linalg.solve(jac, np.concatenate([rhs, -curv[rows, 0]]))
        lam = np.zeros(grad.shape[0])
        lam[rows] = sol[n:]
        return lam
