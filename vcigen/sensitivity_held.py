"""The tangent through held phases (MATH.md *Sustained contact*, *Exact sensitivities*): the hooks of
:class:`vcigen.sensitivity.Tracker` that :mod:`vcigen.sustained` calls inside a held step.

A held step (``rattle``, ``rattle_project``, with internal points ``rattle_end``) by the implicit-function
theorem on its active set (:meth:`HeldTangents.held`); the impulse law onto the rows of a plastic entry or an
impact while held (:meth:`HeldTangents.impulse`); a lift-off or a row crossed at a located fraction of a
constrained sub-step (:meth:`HeldTangents.liftoff`, :meth:`HeldTangents.event`), then the free or
constrained rest; Coulomb friction in one mode (the slip and stick slots of ``par``,
:meth:`HeldTangents._friction_slots`, :meth:`HeldTangents._cone_slots`). The module docstring of
:mod:`vcigen.sensitivity` gives the whole chain and what it does not cover.
"""

from __future__ import annotations

import functools

import numpy as np

from .held_roots import SLIDE_EPS
from .impulse_law import _least_split, _spanned


def _split(grad, w, b) -> np.ndarray:
    """The least split ``W^+ b`` of the impulse on all the rows ``grad`` (dependent: a box's four cones
    sticking flat on a floor; ``b`` in ``W``'s range, one or a column of them),
    :func:`vcigen.impulse_law._least_split`."""
    lam = _least_split(grad, w, b, list(range(len(b))))
    if lam is None:
        raise np.linalg.LinAlgError("least split: singular")
    return lam


def _least_tangent(grad, w, y, dg, dy, lam, rhs) -> np.ndarray:
    """``dLam`` of a least split ``Lam = W^+ b`` (``HeldTangents._impulse`` on dependent rows; ``W = G M^-1
    G^T`` of constant rank, the rows dependent on the body whatever its state): ``dLam = W^+ (db - dW Lam) + P
    dW^T W^+ Lam``, ``P = I - W^+ W`` the projector onto ``W``'s null space (the derivative of a
    pseudo-inverse of constant rank, Golub and Pereyra 1973, with ``b`` in ``W``'s range); ``rhs = db - dW
    Lam`` (``na, K``), ``dW_ce = y_e.dg_c + g_c.dy_e``. Each ``W^+`` is a least split of a right-hand side in
    ``W``'s range."""
    na = len(lam)
    u = _split(grad, w, lam)
    z = np.array([sum((y[:, c] @ dg[e] + grad[e] @ dy[c]) * u[e] for e in range(na)) for c in range(na)])
    return _split(grad, w, rhs) + z - _split(grad, w, w @ z)  # z (na, K): dW^T W^+ Lam


def _guarded(hook, name: str | None = None):
    """A hook whose linear solve meets a singular matrix loses the tangent instead of stopping the run (the
    reason names ``name``, else the hook)."""

    @functools.wraps(hook)
    def run(self, *args) -> None:
        try:
            hook(self, *args)
        except np.linalg.LinAlgError:
            self.lose(f"a singular Jacobian in the tangent of {name or hook.__name__}")

    return run


def _event_hook(hook):
    """:func:`_guarded`, each phase of an event inside a held step named ``event`` (C WHY_SINGULAR_EVENT)."""
    return _guarded(hook, "event")


class HeldTangents:
    """The held phases' hooks of :class:`vcigen.sensitivity.Tracker` (its state and its free phases' hooks
    are the Tracker's own)."""

    def _friction_slots(self, q, dq, act, t: float) -> np.ndarray | None:
        """The tangent of the friction slots of ``par`` within a friction mode (MATH.md *Friction*), at the
        start ``q`` of a held segment (``dq`` its tangent): a slipping contact's slot ``-mu_f s`` moves with
        ``mu_f`` alone (``d_friction``; the sliding direction ``s`` of a one-tangent contact is fixed within
        the mode), a sticking one's reference ``ref_f`` with the point it sticks at: its stick row
        ``tangent_f(q) - ref_f = 0`` holds at every point of the mode, so ``d ref_f = d tangent_f(q; par) =
        grad tangent_f dq + d tangent_f/d par dpar`` (``d_psi``; exact, whenever the stick began: before the
        step it held at ``q`` too; the parameters' term: a disk's ``x - r th`` in ``r``). The branch signs: 0.
        ``None`` without friction (every slot 0)."""
        k = self.k
        nf = len(getattr(k, "frictional", ()))
        if not nf:
            return None
        fs, par = k.friction_slot, self.par(t)
        out = np.zeros((self.tg.npar, self.K))
        slip = par[fs : fs + nf]
        if slip.any():
            mu = k.friction(q)[0]
            dmu = self.tg.get("d_friction")(q, par)[0] @ self._par0  # (m, K): mu_f moves with the parameters
            for f, j in enumerate(k.frictional):
                if slip[f]:
                    out[fs + f] = slip[f] / mu[j] * dmu[j]
        sticks = [(f, k.row_stick.index(f)) for f in range(nf) if act[k.row_stick.index(f)]]
        if sticks:
            dpsi = self.tg.get("d_psi")(q, np.zeros(self.n), par)[0]  # R x (n + npar): psi_sr = t_f - ref_f
            for f, sr in sticks:  # the slots' own rows of _par0 are 0: what moves is t_f's q and parameters
                out[fs + nf + f] = dpsi[sr, : self.n] @ dq[:, : self.K] + dpsi[sr, self.n :] @ self._par0
        return out

    def _cone_slots(self, q, p, dq, dp, tau: float, act, t: float, out: np.ndarray, dtau=None) -> bool:
        """The slip slots of the slipping cones (two tangents) in ``out``: ``SustainedSteps._cone_aim`` at the
        segment's start ``(q, u)``, ``u = M^-1 p`` (the stepper's one Newton step, exact for a momentum
        linear in the velocity): every slipping cone first along its sliding velocity ``w = (grad t1 . u,
        grad t2 . u)``, ``s0 = -mu_f w / |w|``, then, if the stepper took it, along the midpoint prediction
        ``mid = w + tau/2 (grad t . a + curv_t)``, ``s1 = -mu_f mid / |mid|``, ``a`` the acceleration of
        the force law with the directions ``s0`` (``M a = rhs + dirs^T lam``, ``G a + curv = 0`` on the
        active rows: its tangent by the implicit-function theorem with ``d_forces`` at ``lam~``, the stick
        rows carrying ``s lam``). Which one the stepper took is read from the slots (to 1e-9); ``False`` if
        neither (the implicit aim of several cones near rest, or a cone too slow to aim): no tangent then.
        ``dtau``: the tangent of the segment's duration ``tau`` (after an event inside the step), or None (a
        grid step's ``h``)."""
        k, n, K, tg = self.k, self.n, self.K, self.tg
        fs, nf = k.friction_slot, len(k.frictional)
        par = self.par(t)
        cones = [(f, g) for f, g in enumerate(k.partner) if g > f and (par[fs + f] or par[fs + g])]
        if not cones:
            return True
        rows = [k.row_stick.index(f) for f in range(nf)]
        dpar = self._par0 + out  # the one-tangent slips' tangents already in out
        mom0, mass0 = k.legendre(q, np.zeros(n))
        u = np.linalg.solve(mass0, p - mom0)
        dmom0, dma0 = tg.get("d_legendre")(q, np.zeros(n), u, par)
        d0 = np.vstack([dq, np.zeros((n, K)), dpar])
        du = np.linalg.solve(mass0, dp - (dmom0 + dma0) @ d0)
        _, grad, curv = k.rows(q, u)
        rhs, mass = k.dynamics(q, u)[0], k.legendre(q, u)[1]
        dgrad = tg.get("d_rows")(q, u, par)[0]
        dqp = np.vstack([dq, dpar])
        mu = k.friction(q)[0]
        dmu = tg.get("d_friction")(q, par)[0] @ self._par0
        tiny = 1e-12 * (1.0 + float(np.max(np.abs(u))))  # sustained.SLIDE_EPS

        def unit(vec, dvec, m, dm):  # -m vec/|vec| and its tangent
            nv = float(np.linalg.norm(vec))
            e = vec / nv
            return -m * e, -np.outer(e, dm) - m * (dvec - np.outer(e, e @ dvec)) / nv

        slip = par[fs : fs + nf].copy()
        dslip = out[fs : fs + nf].copy()
        w, dw = {}, {}
        for f, g in cones:
            rr = [rows[f], rows[g]]
            w[f] = np.array([grad[r] @ u for r in rr])
            dw[f] = np.array([u @ (dgrad[r * n : (r + 1) * n] @ dqp) + grad[r] @ du for r in rr])
            if float(np.linalg.norm(w[f])) <= tiny:
                return False
            j = k.frictional[f]
            slip[[f, g]], dslip[[f, g]] = unit(w[f], dw[f], mu[j], dmu[j])
        # the force law with the directions s0 (SustainedSteps._forces), and its tangent
        on = np.flatnonzero(act)
        dirs = grad.copy()
        # a slipping cone's two tangents both (one may slip by 0: its own column is not 0)
        slipping = [f for f in range(nf) if slip[f] or (k.partner[f] >= 0 and slip[k.partner[f]])]
        for f in slipping:
            j = k.frictional[f]
            dirs[[r for r in on if k.row_contact[r] == j]] += slip[f] * grad[rows[f]]
        jac = np.block([[mass, -dirs[on].T], [grad[on], np.zeros((on.size, on.size))]])
        sol = np.linalg.solve(jac, np.concatenate([rhs, -curv[on]]))
        acc, lam = sol[:n], np.zeros(k.r)
        lam[on] = sol[n:]
        lam_t = lam.copy()  # the stick rows carry slip_f times their contact's normal force
        normal = {}
        for f in slipping:  # a cone tangent whose slip is 0 (sliding along the other) has its own column too
            j = k.frictional[f]
            normal[f] = sum(lam[r] for r in on if k.row_contact[r] == j)
            lam_t[rows[f]] += slip[f] * normal[f]
        dres = tg.get("d_forces")(q, u, acc, lam_t, par)[0]
        d_state = np.vstack([dq, du, self._par0])
        d_state[2 * n :] += out  # the one-tangent slips (par's friction slots)
        df = dres[np.r_[np.arange(n), n + on]] @ d_state
        for f, s in normal.items():  # the slips' own columns: -N_f grad t_f dslip_f
            df[:n] -= s * np.outer(grad[rows[f]], dslip[f])
        dsol = -np.linalg.solve(jac, df)
        dacc = dsol[:n]
        for f, g in cones:
            rr = [rows[f], rows[g]]
            raw = np.array([grad[r] @ acc + curv[r] for r in rr])
            turn = 0.5 * tau * raw
            dturn = 0.5 * tau * np.array([dres[n + r] @ d_state + grad[r] @ dacc for r in rr])
            if dtau is not None:  # the aim over what is left of the step after an event
                dturn = dturn + 0.5 * np.outer(raw, dtau[0, :K])
            j = k.frictional[f]
            s0, ds0 = slip[[f, g]], dslip[[f, g]]
            have = par[fs + np.array([f, g])]
            scale = 1e-9 * max(mu[j], 1e-300)
            if float(np.linalg.norm(w[f] + turn)) > tiny:
                s1, ds1 = unit(w[f] + turn, dw[f] + dturn, mu[j], dmu[j])
                if np.abs(have - s1).max() <= scale:
                    out[fs + f], out[fs + g] = ds1
                    continue
            if np.abs(have - s0).max() <= scale:
                out[fs + f], out[fs + g] = ds0
                continue
            return False
        return True

    def _dvel(self, q, v_in, a, mass0, par, dpar) -> np.ndarray:
        """Tangent of ``vel = v_in + a``, ``a = M(q, v_in)^-1 (p - mom(q, v_in))`` (``Stepper._velocity``, one
        Newton step of the inverse Legendre transform), ``dq``, ``dp``, ``dvin`` the segment's tangents."""
        dmom0, dma0 = self.tg.get("d_legendre")(q, v_in, a, par)
        d0 = np.vstack([self.dq, self.dvin, dpar])
        return self.dvin + np.linalg.solve(mass0, self.dp - dmom0 @ d0 - dma0 @ d0)

    @_guarded
    def plastic(self, seg, v_in, tight, slides=None) -> None:
        """A plastic impact (``SustainedSteps._plastic_entry``) on the rows ``tight`` (those with an impulse,
        a landing contact's stick row where it sticks): ``p+ = p~- + D^T Lam``, ``G M^-1 D^T Lam = -G vel``
        (the impulse law, target velocity 0; ``D`` along ``slides`` as in :meth:`_impulse`: a landing
        contact sliding on an edge of its cone), ``vel`` one Newton step of the inverse Legendre transform
        from ``v_in``, ``G`` and ``M`` at ``(q~, vel)``: ``dp`` becomes the tangent of ``p+`` (the rest of the
        step starts there)."""
        if not self.active:
            return
        self._impulse(seg.q, v_in, seg.p_in, tight, [-1] * len(tight), slides)

    @_event_hook
    def impulse(self, q, v, p, tight, contact, slides=None) -> None:
        """An impact while rows are held (``SustainedSteps._chain_impact``, after :meth:`event`): the impulse
        law on the rows ``tight`` (those with an impulse), each row's target ``-e g_r.vel`` (``contact[l]``
        the contact whose restitution ``e`` it takes, ``-1``: target 0, an active or plastic row);
        ``slides[l]``: a normal row of a contact slipping on through the impact, its sliding impulse along
        (:meth:`_impulse`), or None."""
        if self.active:
            self._impulse(q, v, p, tight, contact, slides)

    def _impulse(self, q, v_in, p_in, tight, contact, slides=None) -> None:
        """``p+ = p + D^T Lam``, ``G M^-1 D^T Lam = b``, ``b_l = -(1 + e_l) g_l.vel`` (``e_l = 0`` where
        ``contact[l] < 0``), ``vel`` one Newton step of the inverse Legendre transform from ``v_in`` (its
        tangent ``self.dvin``), ``G`` and ``M`` at ``(q, vel)``: ``self.dp`` becomes the tangent of ``p+``.
        ``D = G`` but on the normal rows of a contact slipping on through the impact (``slides[l] = (sr, sgn,
        j)``, ``SustainedSteps._law_slips``): ``d_l = g_l + sgn mu_j g_sr``, Coulomb's sliding impulse along
        the stick row ``sr`` of the slip's owner, ``mu_j`` (contact ``j``'s) moving with the parameters
        (``d_friction``), the sign fixed within the mode."""
        k, n = self.k, self.n
        par, dpar = self.par(self.t_seg), self.dpar(self.dt)  # at the impact point
        mom0, mass0 = k.legendre(q, v_in)
        a = np.linalg.solve(mass0, p_in - mom0)
        vel = v_in + a
        dvel = self._dvel(q, v_in, a, mass0, par, dpar)
        mass1 = k.legendre(q, vel)[1]
        rows = k.rows(q, vel)[1]
        grad = rows[tight]  # (na, n)
        dgrad = self.tg.get("d_rows")(q, vel, par)[0]
        dq_par = np.vstack([self.dq, dpar])
        dg = [dgrad[r * n : (r + 1) * n] @ dq_par for r in tight]  # each (n, K)
        dirs, ddirs = grad.copy(), list(dg)  # D and its tangent (a landing cone's: but its direction's)
        cones: dict[int, tuple] = {}  # contact j of a sliding landing cone: (t1, t2, w_hat, its rows)
        if slides is not None and any(s is not None for s in slides):
            mu = k.friction(q)[0]
            dmu = self.tg.get("d_friction")(q, par)[0] @ dpar  # (m, K)
            for c, slide in enumerate(slides):
                if slide is not None and len(slide) == 4:  # (t1, t2, w_hat, j): -mu N w_hat on t1, t2
                    t1, t2, what, j = slide
                    cones.setdefault(j, (t1, t2, np.asarray(what, float), []))[3].append(c)
                    gt = rows[[t1, t2]]
                    dirs[c] = grad[c] - mu[j] * (what @ gt)
                    dgt = [dgrad[t * n : (t + 1) * n] @ dq_par for t in (t1, t2)]
                    ddirs[c] = dg[c] - mu[j] * (what[0] * dgt[0] + what[1] * dgt[1])
                    ddirs[c] = ddirs[c] - np.outer(what @ gt, dmu[j])
                elif slide is not None:
                    sr, sgn, j = slide
                    dirs[c] = grad[c] + sgn * mu[j] * rows[sr]
                    dgt = dgrad[sr * n : (sr + 1) * n] @ dq_par
                    ddirs[c] = dg[c] + sgn * mu[j] * dgt + sgn * np.outer(rows[sr], dmu[j])
        y = np.linalg.solve(mass1, dirs.T)  # M^-1 D^T, (n, na)
        dleg = self.tg.get("d_legendre")
        dy = []
        for c in range(len(tight)):
            dma = dleg(q, vel, y[:, c], par)[1]
            dy.append(np.linalg.solve(mass1, ddirs[c] - dma @ np.vstack([self.dq, dvel, dpar])))
        rest = k.restitution() if any(j >= 0 for j in contact) else None
        de = self.tg.get("d_restitution")(par)[0] @ dpar if rest is not None else None
        coef = np.array([1.0 + (float(rest[j]) if j >= 0 else 0.0) for j in contact])
        w = grad @ y
        slid = slides is not None and any(s is not None for s in slides)
        least = not slid and _spanned(grad, range(len(tight)), [True] * len(tight))  # a least split
        lam = _split(grad, w, -coef * (grad @ vel)) if least else np.linalg.solve(w, -coef * (grad @ vel))
        db = -coef[:, None] * np.array([vel @ dg[c] + grad[c] @ dvel for c in range(len(tight))])
        for c, j in enumerate(contact):  # a restitution target moves with e
            if j >= 0:
                db[c] -= de[j] * float(grad[c] @ vel)
        dw_lam = np.array(
            [
                sum((y[:, e] @ dg[c] + grad[c] @ dy[e]) * lam[e] for e in range(len(tight)))
                for c in range(len(tight))
            ]
        )
        if cones:  # their directions w_hat = w+ / |w+| move with the velocity after: solved with dLam
            dlam, ddirs = self._cone_slides(cones, q, vel, dvel, par, dq_par, mass1, grad, dg, y, dy, w, lam,
                                            db - dw_lam, ddirs, mu, rows, dgrad)  # fmt: skip
            if dlam is None:
                return
        elif least:
            dlam = _least_tangent(grad, w, y, dg, dy, lam, db - dw_lam)
        else:
            dlam = np.linalg.solve(w, db - dw_lam)
        self.dp = self.dp + sum(ddirs[c] * lam[c] + np.outer(dirs[c], dlam[c]) for c in range(len(tight)))

    def _cone_slides(self, cones, q, vel, dvel, par, dq_par, mass1, grad, dg, y, dy, w, lam, rhs, ddirs, mu,
                     rows, dgrad):  # fmt: skip
        """:meth:`_impulse` with landing cones sliding through it (``cones``: per contact ``j`` ``(t1, t2,
        w_hat, its normal rows' indices in tight)``): their impulse ``-mu_j N_j w_hat`` turns with ``w+ = G_t
        vel+``, ``vel+ = vel + M^-1 D^T Lam``, ``w_hat = w+ / |w+|``. The tangents ``dLam`` and ``dw_hat_j``
        solve together ``W dLam + sum_j N_j G M^-1 E_j dw_j = rhs`` (``E_j = -mu_j G_t^T``, the part of
        ``d D`` the direction's tangent makes) and ``dw_j = P_j / |w+_j| d(w+_j)`` (``P_j = I - w_hat
        w_hat^T``, ``d(w+) = dG_t vel+ + G_t (dvel + sum_e dy_e Lam_e + M^-1 E dw N + y dLam)``). Returns
        ``(dLam, ddirs)`` (``ddirs`` with the directions' tangents), or ``(None, None)`` where a cone's
        sliding after is 0 (to round-off): its direction has no tangent (``"friction at an impact"``)."""
        n, na, cols = self.n, len(lam), dq_par.shape[1]
        vel_p = vel + y @ lam
        dvel_p0 = dvel + sum(dy[e] * lam[e] for e in range(na))  # without the directions' tangents
        keys = sorted(cones)
        size = na + 2 * len(keys)
        mat, rhs_all = np.zeros((size, size)), np.zeros((size, cols))
        mat[:na, :na], rhs_all[:na] = w, rhs
        zs = []
        for j in keys:
            t1, t2, _, own = cones[j]
            e_j = -mu[j] * rows[[t1, t2]].T  # (n, 2)
            zs.append((np.linalg.solve(mass1, e_j), float(sum(lam[c] for c in own)), e_j))
        for i, j in enumerate(keys):
            t1, t2, what, own = cones[j]
            gt = rows[[t1, t2]]
            wp = gt @ vel_p
            size_w = float(np.hypot(*wp))
            if not size_w > SLIDE_EPS * (1.0 + float(np.max(np.abs(vel_p)))):
                self.lose("friction at an impact")
                return None, None
            proj = (np.eye(2) - np.outer(what, what)) / size_w
            at = na + 2 * i
            mat[:na, at : at + 2] = zs[i][1] * (grad @ zs[i][0])
            mat[at : at + 2, at : at + 2] = np.eye(2)
            for i2, (z2, n2, _) in enumerate(zs):
                mat[at : at + 2, na + 2 * i2 : na + 2 * i2 + 2] -= proj @ gt @ z2 * n2
            mat[at : at + 2, :na] = -proj @ gt @ y
            dgt_v = np.array([vel_p @ (dgrad[t * n : (t + 1) * n] @ dq_par) for t in (t1, t2)])
            rhs_all[at : at + 2] = proj @ (dgt_v + gt @ dvel_p0)
        sol = np.linalg.solve(mat, rhs_all)
        ddirs = list(ddirs)
        for i, j in enumerate(keys):
            for c in cones[j][3]:
                ddirs[c] = ddirs[c] + zs[i][2] @ sol[na + 2 * i : na + 2 * i + 2]
        return sol[:na], ddirs

    @_guarded
    def held(self, q, p, tau: float, v, lam, lam1, lam_m, u1, act, entry: bool = False) -> None:
        """A held grid step with a fixed active set (MATH.md *Sustained contact*): ``S_k+1``.

        ``rattle``, unknowns ``x = (v, Lam)`` given ``(q_k, p_k, tau, act, par)``, then ``rattle_project``,
        unknowns ``y = (u1, Lam')`` given ``(q_k+1, p+, act, par)``, ``q_k+1 = q_k + tau v``,
        ``p+ = p+(q_k, v, tau)``; ``p_k+1 = dL/dqdot(q_k+1, u1)`` (``= p+ + G1^T Lam'``). The active set and
        the multipliers off it are held fixed (their columns 0): the derivative of the step for its mode.
        With internal points held on the rows (lobatto3, ``derive.held_internal_points``) ``x = (v, Lam,
        Lam_m, u)`` (``lam_m`` the internal points' multipliers, ``u`` recovered) and ``p+`` is routine
        ``rattle_end``'s (:meth:`_held_sub`).
        ``entry``: the rest of a step after a plastic impact (:meth:`plastic`), from the impact point ``q~``,
        ``p+``, its time and the rest of the step (the segment's tangents ``dq, dp, dt, dtau``).
        """
        if not self.active:
            return
        n = self.n
        dq, dp, dtau, dt, t = self._start(entry)
        self._slots = self._friction_slots(q, dq, act, t)
        if self._slots is not None and not self._cone_slots(q, p, dq, dp, tau, act, t, self._slots, dtau):
            self._slots = None
            self.lose("a phase without a tangent")
            return
        try:
            dq1, du1, dpar = self._held_sub(q, p, tau, v, lam, lam1, lam_m, u1, act, dq, dp, dtau, dt, t)
        finally:
            self._slots = None
        dmom, _ = self.tg.get("d_legendre")(q + tau * v, u1, np.zeros(n), self.par(t))
        self.next = np.vstack([dq1, dmom @ np.vstack([dq1, du1, dpar])])

    def _held_sub(self, q, p, tau: float, v, lam, lam1, lam_m, u1, act, dq, dp, dtau, dt, t):
        """Tangents ``(dq1, du1, dpar)`` of a constrained segment ``(q, p, tau)`` from ``t`` (``rattle`` then
        ``rattle_project``, the active set ``act`` fixed); the columns are those of ``dq`` (any number).

        With internal points held on the rows (``lam_m`` their multipliers, stage after stage) ``rattle``'s
        unknowns are ``(v, Lam, Lam_m, u)``: ``u`` is recovered at the solution (:meth:`Tangents.internal`,
        Newton on the stationarity rows ``l_u + G_m^T Lam_m = 0`` at the given ``Lam_m``), all of them are
        unknowns of the implicit-function theorem, and ``p+`` is ``rattle_end(q, v, tau, u, Lam_m, act)``
        (``D2 L_d`` with the internal multipliers' share), its partials ``d_rattle_end`` chained with
        ``(dq, dv, dtau, du, dLam_m, 0, dpar)``."""
        n, cols = self.n, dq.shape[1]
        nr = len(act)
        actf = np.asarray(act, dtype=float)
        par = self.par(t)
        dpar = self.dpar(dt)
        if dpar.shape[1] != cols:
            dpar = np.hstack([dpar, np.zeros((dpar.shape[0], cols - dpar.shape[1]))])
        zr = np.zeros((nr, cols))
        data = (q, p, [tau], actf)
        x = np.concatenate([v, lam, lam_m])
        u = self.tg.internal("rattle", x, data, par)
        dx = self._ift("rattle", np.concatenate([x, u]), data, np.vstack([dq, dp, dtau, zr, dpar]), t)
        dv = self._sub_dv = dx[:n]  # the sub-step's velocity (an impulse law after it starts from it)
        q1 = q + tau * v
        dq1 = dq + np.outer(v, dtau) + tau * dv
        if self.tg.ns:  # p+ of the segment with its internal points held (rattle_end)
            nx = x.size
            dlm, du = dx[n + nr : nx], dx[nx:]
            ins = (q, v, [tau], u, lam_m, actf, par)
            p_plus = self.tg.get("rattle_end")(*ins)[0][:, 0]
            dpp = self.tg.get("d_rattle_end")(*ins)[0] @ np.vstack([dq, dv, dtau, du, dlm, zr, dpar])
        else:
            p_plus = self.k.segment(q, v, tau)[1]
            _, dpp, _ = self._segment_cols(q, v, tau, t, dq, dv, dtau, dpar)
        y = np.concatenate([u1, lam1])
        dy = self._ift("rattle_project", y, (q1, p_plus, actf), np.vstack([dq1, dpp, zr, dpar]), t)
        return dq1, dy[:n], dpar

    def _segment_cols(self, q, v, tau: float, t: float, dq, dv, dtau, dpar, u=None, du=None):
        """:meth:`_segment` with ``dpar`` given (any number of columns)."""
        if self.tg.ns:  # d_segment(q0, v, tau, u, par): its u columns chained with du
            dpm, dpp, de = self.tg.get("d_segment")(q, v, tau, u, self.par(t))
            d = np.vstack([dq, dv, dtau, du, dpar])
            return dpm @ d, dpp @ d, de @ d
        dpm, dpp, de = self.tg.get("d_segment")(q, v, tau, self.par(t))
        d = np.vstack([dq, dv, dtau, dpar])
        return dpm @ d, dpp @ d, de @ d

    @_guarded
    def liftoff(self, sub, r: int, s: float, tau: float, free, entry: bool = False) -> None:
        """A held grid step whose row ``r`` lifts off at fraction ``s`` (MATH.md *Sustained contact*), then a
        free rest (46) to the grid time: ``S_k+1`` for this mode sequence.

        ``sub = (q, p, v, lam, lam1, u1, act)``: the constrained sub-step over ``tau_s = s tau`` from the
        grid point (``tau = h``), ``act`` its active rows (``r`` among them). The lift-off fraction is the
        root of ``g(s) = lambda_r(q1(s), u1(s), par)`` (``SustainedSteps._liftoff_fraction``): by the
        implicit-function theorem ``d tau_s = -(dg|_{tau_s}) / (dg/d tau_s)``, both through the sub-step's
        tangent (one extra column: ``d/d tau_s``). ``free = (q_l, p_l, w)``: the smooth step (46) over
        ``tau - tau_s`` from the lift-off point, its start time and duration chained. ``entry``: the rest of
        a step after a plastic impact (:meth:`plastic`), from the impact point, its time and the rest of the
        step (the segment's tangents ``dq, dp, dt, dtau``), as :meth:`held`.
        """
        if not self.active:
            return
        dq0, dp0, dtau0, dt0, t = self._start(entry)
        dq_l, dp_l, _, dtau_s = self._located(sub, r, s, tau, "lift", dq0, dp0, dt0, t)
        dt_l = dtau_s[0] if dt0 is None else dt0 + dtau_s[0]
        self._free_end(free, tau - s * tau, t + s * tau, dq_l, dp_l, dtau0 - dtau_s, dt_l)

    def _located(self, sub, r: int, s: float, tau: float, kind: str, dq0, dp0, dt0, t):
        """The constrained sub-step ``sub = (q, p, v, lam, lam1, lam_m, u1, act)`` over ``tau_s = s tau`` from
        ``t`` to an event of row ``r`` (``kind``: ``"lift"``, the root of its force, :meth:`_dforce`;
        ``"cross"``, the root of its value ``psi_r(q1)``, ``d_psi``; a friction switch ``"stop"``
        or ``"slide"`` of stick row ``r``, :meth:`SwitchTangents._switch_root`), with one extra column
        ``d/d tau_s``, and the root's ``d tau_s = -(dg|_{tau_s}) / (dg/d tau_s)``: ``(dq_l, dp_l, dv_l,
        dtau_s)`` at the event (``dv_l``: the sub-step's velocity ``v``, where the impulse law's Newton step
        starts)."""
        n, K = self.n, self.K
        q, p, v, lam, lam1, lam_m, u1, act = sub
        tau_s = s * tau
        dq = np.hstack([dq0, np.zeros((n, 1))])
        dp = np.hstack([dp0, np.zeros((n, 1))])
        dtau = np.zeros((1, K + 1))
        dtau[0, K] = 1.0  # the extra column: d/d tau_s
        dq1, du1, dpar = self._held_sub(q, p, tau_s, v, lam, lam1, lam_m, u1, act, dq, dp, dtau, dt0, t)
        dv = self._sub_dv
        q1 = q + tau_s * v
        t_l = t + tau_s
        dpar_end = dpar.copy()
        if self.timed:
            dpar_end[-1] = dpar[-1] + dtau[0]
        if kind == "lift":
            dg = self._dforce(q1, u1, act, r, self.par(t_l), np.vstack([dq1, du1, dpar_end]))  # (K + 1,)
        elif kind in ("stop", "slide"):  # a friction switch (vcigen.sensitivity_switch)
            dg = self._switch_root(kind, q1, u1, act, r, self.par(t_l), np.vstack([dq1, du1, dpar_end]))
        else:
            dg = self.tg.get("d_psi")(q1, u1, self.par(t_l))[0][r] @ np.vstack([dq1, dpar_end])
        if dg[K] == 0.0:
            raise np.linalg.LinAlgError("the event's root does not move with its fraction")
        dtau_s = (-dg[:K] / dg[K])[None, :]
        dq_l = dq1[:, :K] + np.outer(dq1[:, K], dtau_s)
        du_l = du1[:, :K] + np.outer(du1[:, K], dtau_s)
        dv_l = dv[:, :K] + np.outer(dv[:, K], dtau_s)
        dmom, _ = self.tg.get("d_legendre")(q1, u1, np.zeros(n), self.par(t))
        dp_l = dmom @ np.vstack([dq_l, du_l, dpar[:, :K]])
        return dq_l, dp_l, dv_l, dtau_s

    def _free_end(self, free, tau_r: float, t_l: float, dq_l, dp_l, dtau_r, dt_l) -> None:
        """The free rest (46) ``free = (q_l, p_l, w)`` over ``tau_r`` from ``t_l`` to the grid time, its
        start, start time and duration chained (their tangents ``dq_l, dp_l, dt_l, dtau_r``): ``S_k+1``."""
        ql, pl, w = free
        dd = np.vstack([dq_l, dp_l, dtau_r, self.dpar(dt_l)])
        dw, uw, duw = self._ift_staged("smooth", w, (ql, pl, [tau_r]), dd, t_l)
        dq_end = dq_l + np.outer(w, dtau_r) + tau_r * dw
        _, dp_end, _ = self._segment(ql, w, tau_r, t_l, dq_l, dw, dtau_r, dt_l, uw, duw)
        self.next = np.vstack([dq_end, dp_end])

    def _start(self, entry: bool) -> tuple:
        """The tangents ``(dq, dp, dtau, dt)`` and the time of a held segment's start: the grid point's
        (``S_k``, 0, ``None``: the grid time has no tangent; ``t_k``), or after a plastic impact (``entry``)
        the segment's carried ones."""
        if entry:
            return self.dq, self.dp, self.dtau, self.dt, self.t_seg
        n = self.n
        return self.cur[:n], self.cur[n:], np.zeros((1, self.K)), None, self.t

    # -- events inside a held step (SustainedSteps._chain): the segment's tangents carried event by event --
    def events_begin(self, entry: bool) -> None:
        """Before the first event of a held grid step: its segment's tangents ``(dq, dp, dtau, dt)`` start at
        the grid point (``S_k``, 0, 0, ``t_k``); the rest of a plastic impact's step (``entry``) has them."""
        if not self.active or entry or self._ev_step == self.step:
            return
        n, K = self.n, self.K
        self.dq, self.dp = self.cur[:n].copy(), self.cur[n:].copy()
        self.dtau, self.dt, self.t_seg = np.zeros((1, K)), np.zeros(K), self.t
        self._ev_step = self.step

    @_event_hook
    def event(self, sub, r: int, s: float, tau: float, kind: str) -> None:
        """A constrained sub-step of a held step to an event of row ``r`` at fraction ``s`` of ``tau`` (a
        lift-off, ``"lift"``, an inactive row crossed, ``"cross"``, a friction switch ``"stop"``
        or ``"slide"``, :meth:`_located`; each sub-step with its friction slots, :meth:`_friction_slots`) from
        the segment's tangents: they become the event point's (the rest of the step after it, from
        ``t_seg + s tau``)."""
        if not self.active:
            return
        # friction in its mode over the sub-step: the slots' tangent from its start (_friction_slots), a
        # slipping cone's aimed there over the segment's tau (_cone_slots)
        self._slots = slots = self._friction_slots(sub[0], self.dq, sub[-1], self.t_seg)
        if slots is not None and not self._cone_slots(
            sub[0], sub[1], self.dq, self.dp, tau, sub[-1], self.t_seg, slots, self.dtau
        ):
            self._slots = None
            self.lose("a phase without a tangent")
            return
        try:
            out = self._located(sub, r, s, tau, kind, self.dq, self.dp, self.dt, self.t_seg)
        finally:
            self._slots = None
        dq_l, dp_l, dv_l, dtau_s = out
        self.dq, self.dp, self.dvin = dq_l, dp_l, dv_l
        self.dt, self.dtau, self.t_seg = self.dt + dtau_s[0], self.dtau - dtau_s, self.t_seg + s * tau

    @_event_hook
    def rest_end(self, q, u, force) -> None:
        """Nothing left of a held step after its events (the last within its least sub-step of the step's
        end): ``S_k+1`` is the event point's tangents moved along the flow of the mode the step ends in by the
        tangent ``dtau`` of that empty rest's length (``-dt`` of the event's time), ``dq + u dtau`` and ``dp +
        pdot dtau``, ``pdot = M qddot + (dp/dq) u`` (``force = M qddot = rhs + D^T lambda``, the stepper's).
        A block stopping on a grid point: the stick's tangent after the stop (``p`` 0 for any start)."""
        if not self.active:
            return
        n = self.n
        dmom, _ = self.tg.get("d_legendre")(q, u, np.zeros(n), self.par(self.t_seg))
        pdot = np.asarray(force, dtype=float) + dmom[:, :n] @ u
        self.next = np.vstack([self.dq + np.outer(u, self.dtau[0]), self.dp + np.outer(pdot, self.dtau[0])])

    @_event_hook
    def free_end(self, q, p, w, tau: float) -> None:
        """The free rest (46) of a held step after its events (:meth:`event`), from the segment's tangents."""
        if self.active:
            self._free_end((q, p, w), tau, self.t_seg, self.dq, self.dp, self.dtau, self.dt)

    def _dforce(self, q1, u1, act, r: int, par, dd) -> np.ndarray:
        """The tangent of row ``r``'s force ``lambda_r(q1, u1, par)`` (``SustainedSteps._forces``, the rows
        ``act`` held), ``dd`` the tangent of ``(q1, u1, par)`` (any number of columns): the force law
        ``J (a, lam) = (rhs, -curv)``, ``J = [[M, -D^T], [G, 0]]`` on the active rows, by the
        implicit-function theorem with its derived partials ``d_forces`` (C: ``sens_located``). ``D = G``
        but on the rows of a slipping frictional contact ``f`` (one tangent), whose force pushes along
        ``grad psi_r + slip_f grad t_f`` (``SustainedSteps._dirs``): ``d_forces`` at ``lam~`` (the stick row
        ``t_f`` carrying ``slip_f N_f``, ``N_f`` the contact's normal force) and the slip's own column
        ``-N_f grad t_f dslip_f`` (its tangent: the slot's row of ``dd``)."""
        n, tg, k = self.n, self.tg, self.k
        rows = np.flatnonzero(act)
        _, grad, curv = tg.get("rows")(q1, u1, par)
        rhs = tg.get("dynamics")(q1, u1, par)[0][:, 0]
        mass = tg.get("legendre")(q1, u1, par)[1]
        g, dirs = grad[rows], grad[rows].copy()
        fs = getattr(k, "friction_slot", 0)
        partner = getattr(k, "partner", ())
        slips = [
            (f, j)
            for f, j in enumerate(getattr(k, "frictional", ()))
            if par[fs + f] or (partner[f] >= 0 and par[fs + partner[f]])  # a cone's: both tangents
        ]
        for f, j in slips:
            dirs[np.asarray(k.row_contact)[rows] == j] += par[fs + f] * grad[k.row_stick.index(f)]
        jac = np.block([[mass, -dirs.T], [g, np.zeros((rows.size, rows.size))]])
        sol = np.linalg.solve(jac, np.concatenate([rhs, -curv[rows, 0]]))
        lam = np.zeros(grad.shape[0])
        lam[rows] = sol[n:]
        lam_t = lam.copy()
        normal = {}
        for f, j in slips:
            normal[f] = float(sum(lam[x] for x in rows if k.row_contact[x] == j))
            lam_t[k.row_stick.index(f)] += par[fs + f] * normal[f]
        dres = tg.get("d_forces")(q1, u1, sol[:n], lam_t, par)[0]
        df = dres[np.r_[np.arange(n), n + rows]] @ dd
        for f, _ in slips:  # the slip's own column
            df[:n] -= normal[f] * np.outer(grad[k.row_stick.index(f)], dd[2 * n + fs + f])
        dx = -np.linalg.solve(jac, df)
        return dx[n + int(np.flatnonzero(rows == r)[0])]
