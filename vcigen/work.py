"""The discrete work of the forces (Lagrange-d'Alembert, MATH.md *Forcing*), booked per grid step.

A segment ``(q0, v, tau)`` starting at ``t0`` carries the discrete forces ``f_d-`` (at its start) and
``f_d+`` (at its end); ``(f_d- + f_d+) . v`` is exactly the difference of its end energies
(``vcigen.derive.Segment``). Across an impact the energy at the end of one segment is the energy at the
start of the next (the alpha-variation with (37)), so there the segments' work is exact.

At a grid node the time is not varied and the two energies differ: the node joins a segment ``(v-, f_d+)``
to the next ``(v+, f_d-)`` through the DEL ``p+(seg-) = p-(seg+)``, i.e. the conservative map followed by
the kick ``J = f_d+ + f_d-``. A kick ``J`` changes the kinetic energy ``1/2 p M^-1 p`` by exactly
``J . (v- + v+)/2`` (M constant), so the node's work is ``J . (v- + v+)/2``, not the old
``f_d+ . v- + f_d- . v+``; the two differ by

    c = (f_d+ - f_d-) . (v+ - v-) / 2,

which for damping ``F = -c v`` (trapezoid) is ``c h/4 |v+ - v-|^2 >= 0``: O(h^3) a node, of one sign, an
O(h^2) drift over a run. With it the force part of the balance telescopes exactly, for both rules, and
what is left of ``E_k - E_0 - sum W + losses`` is the conservative mismatch of the discrete energy: for a
quadratic V it telescopes (trapezoid) or vanishes (midpoint). With a third derivative ``D3V`` of V its
remainder ``-(h^3/12) D3V[v, v, v]`` a step sums, on a forced trajectory, to
``(h^2/6) int grad^2 V(qdot, M^-1 F) dt`` (both rules): where ``L = 1/2 qdot^T M qdot + b . qdot - V(q)``
with ``M``, ``b`` constant and V not quadratic, the kick is booked at
``vbar + (h^2/6) M^-1 grad^2 V(q_k) vbar`` instead, which removes it. For a mass matrix of ``q`` the kick
is booked as its change of the modified Hamiltonian ``H~`` that the rule's conservative map keeps to
O(h^4) (:func:`_modified_hamiltonian`).

Step ``k``'s work is its segments' work plus the correction of the node it starts at (step 0 has none); a
node that is also an impact (a sub-segment of zero length there) takes none. On the steps of an impact the
conservative mismatch no longer telescopes: the nodes join segments of different lengths and (48a) keeps
``E_d`` across the impact; :func:`impact_work` books what is left, ``b = O(h^2)`` an impact (README,
*Forces*), without which the balance drifts in proportion to the number of impacts (with a mass matrix of
``q``: :func:`modified_impact_work`); a plastic impact, or one in a step with a row held, also books the
difference of its logged energy after it to the energy at the start of the segment after. An impact exactly
on a grid node is a segment of length 0 with the node momentum's velocity. Bilateral constraints: the
impulse of the DEL at a node does work (:func:`constraint_impulse`).

A rule with internal points (lobatto3) books only its segments' own quadrature of the work, ``E_end -
E_start`` (``vcigen.rules.StagedForces``), with no node term: the corrections above are O(h^2) ones and its
balance is O(h^4) without them, impact steps included (README *Fourth order*, measured there).
"""

from __future__ import annotations

import numpy as np

from .booking import Booking, Potential
from .result import Result

TINY = 1e-14  # a sub-segment shorter than TINY * h is no segment (simultaneous impacts, an impact on a node)


def _staged_step_work(res: Result, booking: Booking, par) -> np.ndarray:
    """``(N-1,)``: each grid step's segments' own work (split at its impacts) under a rule with internal
    points; no node term (README *Forces*, lobatto3: what that leaves in the balance is measured there)."""
    steps = res.energy.size
    q, t, h = res.q, res.t, res.h
    held = _held_rows(res, booking, par, q[:-1], q[1:], np.arange(steps))
    out = booking.staged(q[:-1], (q[1:] - q[:-1]) / h, np.full(steps, h), t[:-1], par, held).copy()
    ims = [im for im in res.impacts if im.step < steps]
    for k in sorted({im.step for im in ims}):
        here = sorted((im for im in ims if im.step == k), key=lambda im: im.t)
        ts = np.array([t[k], *(im.t for im in here), t[k + 1]])
        qs = np.array([q[k], *(np.asarray(im.q, float) for im in here), q[k + 1]])
        tau = np.diff(ts)
        keep = tau > TINY * h
        vs = (qs[1:] - qs[:-1])[keep] / tau[keep, None]
        ends = qs[:-1][keep], qs[1:][keep]
        act = _held_rows(res, booking, par, *ends, np.full(int(keep.sum()), k), either=True)
        out[k] = float(np.sum(booking.staged(ends[0], vs, tau[keep], ts[:-1][keep], par, act)))
        # an impact with a row held after it (a plastic entry, an impact while held) logs E_d less its loss,
        # not the energy at the start of the constrained segment that follows: the difference is the step's
        for m, im in enumerate(here, start=1):  # segment m starts at impact m
            j = int(np.sum(keep[:m]))  # its index among the kept segments
            if keep[m] and act is not None and act[j].any():
                at = (ends[0][j : j + 1], vs[j : j + 1], tau[keep][j : j + 1], ts[:-1][keep][j : j + 1])
                out[k] += float(booking.staged(*at, par, act[j : j + 1], start=True)[0]) - im.energy_after
    return out


HELD_PSI = 1e-10  # a row this close to 0 at both ends of a segment of a step its contact is held over is held


def _held_rows(
    res: Result, booking: Booking, par, q0: np.ndarray, q1: np.ndarray, step: np.ndarray, either: bool = False
):
    """``(K, r)``: the rows segments ``(q0, q1)`` of grid steps ``step`` held their internal points on (the
    constrained step's): the constraints, and a contact's rows at ``|psi| <= HELD_PSI`` at both ends where the
    contact is active at both grid points of the step (``res.active``; ``either``: at one of them, for the
    segments of a step split at its impacts, a plastic entry or a lift-off among them); ``None`` without
    rows."""
    if booking.rows is None:
        return None
    psi_fn, contact = booking.rows
    near = (np.abs(psi_fn(q0, par)) <= HELD_PSI) & (np.abs(psi_fn(q1, par)) <= HELD_PSI)
    act = np.zeros(near.shape)
    for r, j in enumerate(contact):
        if j < 0:  # a constraint: always held
            act[:, r] = 1.0
            continue
        now, nxt = res.active[step, j], res.active[step + 1, j]
        act[:, r] = near[:, r] & ((now | nxt) if either else (now & nxt))
    return act


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("kn,kn->k", a, b)


def step_work(res: Result, booking: Booking | None, par) -> np.ndarray:
    """``(N-1,)``: the discrete work over each grid step: its segments' ``(f_d- + f_d+) . v`` (split at its
    impacts) plus, at the grid node it starts at, ``(f_d+ - f_d-) . (v+ - v-) / 2`` and, with a curvature,
    ``(h^2/6) J . M^-1 grad^2 V vbar`` (with a mass matrix of ``q``: the kick's change of ``H~`` less the
    segments' ``f_d . v`` instead), and on the steps of an impact :func:`impact_work` and the plastic
    impacts' energy difference (module docstring). Exactly 0 without forces."""
    steps = res.energy.size
    if booking is None or steps == 0:
        return np.zeros(steps)
    if booking.staged is not None:
        return _staged_step_work(res, booking, par)
    forces = booking.forces
    q, t, h = res.q, res.t, res.h
    v = (q[1:] - q[:-1]) / h
    fm, fp = forces(q[:-1], v, np.full(steps, h), t[:-1], par)
    out = _dot(fm + fp, v)
    # the segments either side of each grid node: the last of step k-1 (v_end, f_end, tau_end) and the first
    # of step k (v_start, f_start, tau_start)
    v_start, f_start, v_end, f_end = v.copy(), fm.copy(), v.copy(), fp.copy()
    tau_start, tau_end = np.full(steps, h), np.full(steps, h)
    on_node = np.zeros(steps + 1, dtype=bool)  # an impact sits on grid node k
    ims = [im for im in res.impacts if im.step < steps]
    if ims:  # the impact steps, split at their impacts: all their sub-segments in one call
        hit = np.array([im.step for im in ims])
        ks = np.unique(hit)
        owner = np.concatenate([ks, hit, ks])
        place = np.concatenate(
            [np.zeros(ks.size), np.ones(hit.size), np.full(ks.size, 2.0)]
        )  # start, hit, end
        ts = np.concatenate([t[ks], [im.t for im in ims], t[ks + 1]])
        qs = np.concatenate([q[ks], np.array([im.q for im in ims]).reshape(hit.size, -1), q[ks + 1]])
        order = np.lexsort((ts, place, owner))
        owner, ts, qs = owner[order], ts[order], qs[order]
        tau = np.diff(ts)
        inside = owner[1:] == owner[:-1]  # consecutive points of one step bound a segment
        keep = inside & (tau > TINY * h)
        first, last = np.flatnonzero(place[order][:-1] == 0), np.flatnonzero(place[order][1:] == 2)
        zero = np.zeros(tau.size, dtype=bool)  # an impact on a grid node: a segment of length 0 there
        if booking.legendre is not None:
            zero[first], zero[last] = ~keep[first], ~keep[last]
            keep |= zero
        on_node[ks] |= ~keep[first]
        on_node[ks + 1] |= ~keep[last]
        seg = np.flatnonzero(keep)
        vs = (qs[seg + 1] - qs[seg]) / np.maximum(tau[seg, None], TINY * h)
        if zero.any():  # its velocity from its momentum, the node's: before the impact at a step's start,
            z = np.flatnonzero(zero[seg])  # after it at its end
            node = np.where(place[order][seg[z]] == 0, owner[seg[z]], owner[seg[z]] + 1)
            vs[z] = booking.legendre(q[node], res.p[node], par)
            tau[seg[z]] = 0.0
        gm, gp = forces(qs[seg], vs, tau[seg], ts[seg], par)
        out[ks] = 0.0
        np.add.at(out, owner[seg], _dot(gm + gp, vs))
        _, head = np.unique(owner[seg], return_index=True)  # the first kept segment of each impact step
        _, tail = np.unique(owner[seg][::-1], return_index=True)
        tail = seg.size - 1 - tail  # and the last
        k = owner[seg][head]
        v_start[k], f_start[k], v_end[k], f_end[k] = vs[head], gm[head], vs[tail], gp[tail]
        tau_start[k], tau_end[k] = tau[seg][head], tau[seg][tail]
    node = _dot(f_end[:-1] - f_start[1:], v_start[1:] - v_end[:-1]) / 2  # grid nodes 1 .. steps-1
    bilateral = res.constraint_force is not None and res.constraint_force.size > 0
    impulse = np.zeros((max(steps - 1, 0), q.shape[1]))  # the bilateral constraints' impulse at each node
    if bilateral and booking.momenta is not None and steps > 1:
        impulse = constraint_impulse(booking, res, (v_start, tau_start, v_end, tau_end), par)
        node += _dot(impulse, (v_start[1:] + v_end[:-1]) / 2)
    if booking.curvature is not None and steps > 1:  # the kick at vbar + h^2/6 M^-1 grad^2 V vbar
        kick, vbar = f_end[:-1] + f_start[1:] + impulse, (v_start[1:] + v_end[:-1]) / 2
        node += h * h / 6 * np.einsum("kn,knm,km->k", kick, booking.curvature(q[1:steps], par), vbar)
    if booking.modified is not None and steps > 1:  # the kick's change of H~, in place of J . vbar
        mom = res.p[1:steps]
        lo, hi = mom - f_end[:-1], mom + f_start[1:]  # p before and after the kick f_d+ + f_d-
        gain = booking.modified(q[1:steps], hi, h, par) - booking.modified(q[1:steps], lo, h, par)
        node = gain - _dot(f_end[:-1], v_end[:-1]) - _dot(f_start[1:], v_start[1:])
    out[1:] += np.where(on_node[1:steps], 0.0, node)
    if ims and booking.potential is not None:
        held = np.full(steps, bilateral)  # the steps with a row held: their DEL holds its impulse
        if res.contact_force is not None and res.contact_force.size:
            held |= np.any(res.contact_force != 0.0, axis=1)
        sub = (owner[seg], qs[seg], vs, tau[seg])
        ends = (v_start, tau_start, v_end, tau_end, f_end[:-1] + f_start[1:])
        curved = booking.curvature is not None
        out += impact_work(booking.potential, curved, q, h, ks, sub, ends, held, on_node, par)
        # a plastic impact's logged energy after it is E_d less its loss, not the energy at the start of the
        # constrained segment that follows: the difference is the step's too
        plastic = np.array([im.kind == "plastic" or held[im.step] for im in ims])[
            order[place[order] == 1] - ks.size
        ]
        after = np.array([im.energy_after for im in ims])[order[place[order] == 1] - ks.size]
        rows = np.flatnonzero(place[order] == 1)[plastic]  # the plastic impacts' points
        i = np.searchsorted(seg, rows)
        found = (i < seg.size) & (seg[np.minimum(i, seg.size - 1)] == rows)  # a segment starts there
        if found.any():
            j = i[found]
            e0 = booking.start(qs[seg[j]], vs[j], tau[seg[j]], ts[seg[j]], par)
            np.add.at(out, owner[seg[j]], e0 - after[plastic][found])
    elif ims and booking.modified is not None and steps > 1 and not bilateral:
        first, last = (v_start, tau_start, t[:-1]), (v_end, tau_end, t[1:] - tau_end)
        out += modified_impact_work(booking, res, h, ks, first, last, on_node, par)
    return out


def constraint_impulse(booking: Booking, res: Result, ends: tuple[np.ndarray, ...], par) -> np.ndarray:
    """``(N-2, n)``: at grid nodes 1 .. N-2 the bilateral constraints' impulse ``K``, the mismatch of the DEL
    there, ``K = p-(seg+) - p+(seg-)`` (RATTLE: ``(Lam' + Lam) grad psi``). As a kick it changes
    ``1/2 p.M^-1 p`` by ``K . (v- + v+)/2`` (M constant; README, *Forces*), not 0: the discrete path leaves
    ``q_k`` off the tangent, ``grad psi . v+- = -+(tau/2) v.Hess psi v``, so a node books
    ``(h^2/4) lambda (v-.Hess psi v- - v+.Hess psi v+)``, O(h^3); without forces it sums to a bounded
    O(h^2) (the tension a function of the state), with damping to a drift, O(h^2) times the dissipated
    energy. It is also part of the kick of the h^2 term with V not quadratic (``q'' = M^-1 (F - g + G^T
    lambda)`` in the integration by parts)."""
    v_start, tau_start, v_end, tau_end = ends
    steps = res.energy.size
    q, t = res.q[1:steps], res.t[1:steps]
    p_next, _ = booking.momenta(q, v_start[1:], tau_start[1:], t, False, par)
    p_prev, _ = booking.momenta(q, v_end[:-1], tau_end[:-1], t - tau_end[:-1], True, par)
    return p_next - p_prev


def modified_impact_work(
    booking: Booking,
    res: Result,
    h: float,
    ks: np.ndarray,
    first: tuple[np.ndarray, ...],
    last: tuple[np.ndarray, ...],
    on_node: np.ndarray,
    par,
) -> np.ndarray:
    """``(N-1,)``: the impacts' ``b`` for a mass matrix of ``q`` (README, *Forces*), where a node's kick is
    booked as its change of the modified Hamiltonian ``H~`` (:func:`_modified_hamiltonian`).

    With the node booking ``H~(q, p + f_d-) - H~(q, p - f_d+) - f_d+ . v- - f_d- . v+``, a grid node leaves
    in ``E_k - E_0 - sum W`` exactly ``D(s+) - D'(s-)``, with ``D(s) = E_d(s) - H~_h(q0, p0)`` at the start
    of segment ``s`` and ``D'(s) = E_d(s) - H~_h(q1, p1)`` at its end (``p0 = -D1 L_d``, ``p1 = D2 L_d``:
    the momenta of its conservative map). Over a segment of length ``h`` the map keeps ``H~_h`` to O(h^5),
    so ``D(s) - D'(s)`` is that defect and the nodes telescope; an impact (48a) keeps ``E_d``, not ``D``, and
    its sub-segments' maps keep ``H~`` of their own lengths. Per step with an impact the nodes leave

        b = D(first segment) [node k a grid node] - D'(last segment) [node k+1 a grid node],

    O(h^2), booked on the step (a segment between two impacts leaves nothing). An impact on a grid node makes
    the steps either side impact steps for this count. Steps in sustained contact (the node's DEL holds the
    contact impulse) book none."""
    steps = res.energy.size
    out = np.zeros(steps)
    touched = np.zeros(steps, dtype=bool)
    touched[ks] = True
    touched[:-1] |= on_node[1:steps]  # the step ending on an impact node
    touched |= on_node[:steps]  # and the one starting there
    if res.contact_force is not None and res.contact_force.size:
        touched &= ~np.any(res.contact_force != 0.0, axis=1)
    grid = np.zeros(steps + 1, dtype=bool)
    grid[1:steps] = ~on_node[1:steps]  # the grid nodes (not an impact, not the run's ends)
    head = np.flatnonzero(touched & grid[:-1])  # steps whose first segment starts at a grid node
    tail = np.flatnonzero(touched & grid[1:])  # steps whose last segment ends at one
    mom = res.p
    for rows, (v, tau, t0), at, sign in ((head, first, 0, 1.0), (tail, last, 1, -1.0)):
        if not rows.size:
            continue
        node, seg_tau, seg_t0 = rows + at, tau[rows], t0[rows]
        vel = booking.velocity(res.q[node], mom[node], v[rows], seg_tau, seg_t0, bool(at), par)
        start = res.q[node] - seg_tau[:, None] * vel if at else res.q[node]
        fm, fp = booking.forces(start, vel, seg_tau, seg_t0, par)
        energy = booking.start(start, vel, seg_tau, seg_t0, par) + _dot(fm, vel)
        p = mom[node] + fm if at == 0 else mom[node] - fp  # the conservative map's momentum
        np.add.at(out, rows, sign * (energy - booking.modified(res.q[node], p, h, par)))
    return out


def impact_work(
    potential: Potential,
    curved: bool,
    q: np.ndarray,
    h: float,
    ks: np.ndarray,
    sub: tuple[np.ndarray, ...],
    ends: tuple[np.ndarray, ...],
    held: np.ndarray,
    on_node: np.ndarray,
    par,
) -> np.ndarray:
    """``(N-1,)``: what the grid nodes' bookings miss on the steps of an impact, whose sub-segments are not
    ``h`` long (README, *Forces*; MATH.md (46), (48a)).

    The work booked at a node makes the forces cancel from the balance; what is left there is the
    conservative mismatch of ``E_d``. For segments of lengths ``t1``, ``t2`` and velocities ``v1``, ``v2``
    meeting at a node ``q`` it is, with ``g = grad V``, ``H = grad^2 V`` (exact for quadratic ``V``),

        trapezoid: 1/4 (t2^2 v2.H v2 - t1^2 v1.H v1) + 1/4 (t2 - t1) g(q) . (v2 - v1)
        midpoint:  1/4 (t2 - t1) (g(q - t1 v1/2) . v2 - g(q + t2 v2/2) . v1)

    With ``t1 = t2 = h`` the first telescopes over a run into ``1/4 h^2 v.H v`` of the last segment (bounded)
    and the rest vanishes. On an impact step the lengths differ, and across an impact (48a) keeps ``E_d``,
    not ``E_d - 1/4 t^2 v.H v``: per impact the balance keeps

        b = 1/4 (tA^2 vA.H vA - tB^2 vB.H vB)
            + 1/4 (tA - h) g(q_k) . (vA - v-) + 1/4 (h - tB) g(q_k+1) . (v+ - vB),

    O(h^2), of mean ``(h^2/12) [qdot.H qdot - g . M^-1 F]`` taken before less after the impact (trapezoid;
    over the impact's fraction ``alpha``), a drift proportional to the impacts' count wherever restitution
    or a force of the velocity changes that. ``b`` is booked: the nodes' terms on the step each node starts,
    the impacts' (trapezoid) on their step. Between free segments ``v2 - v1`` is taken from the DEL at the
    node, ``M (v2 - v1) = J - (t1 g(q) + t2 g(q))/2`` (trapezoid; midpoint ``J - (t1 g1 + t2 g2)/2``) with the
    kick ``J``, not from the positions: a sub-segment ``alpha h`` of round-off length would magnify their
    round-off. Next to a step ``held`` in sustained contact the node's DEL holds the contact's impulse too:
    there ``v2 - v1`` is taken from the positions.

    ``curved`` (the kick booked at ``vbar + (h^2/6) M^-1 grad^2 V vbar``, V not quadratic): that h^2 term
    equals the conservative remainder ``-(h^3/12) D3V[v, v, v]`` a step only up to the difference of
    ``-(h^2/12) (qdot.H qdot + g.M^-1 g)`` between the ends of each smooth stretch (integration by parts of
    ``D3V[qdot, qdot, qdot] = d/dt(qdot.H qdot) - 2 qdot.H qddot``). Across an impact ``qdot`` jumps: each
    impact also books ``(h^2/12) (vB.H vB - vA.H vA)``, with the velocity of a neighbouring segment for a
    sub-segment shorter than ``1e-3 h``.

    Impacts on a grid node take none."""
    steps = held.size
    out = np.zeros(steps)
    owner, qs, vs, tau = sub
    v_start, tau_start, v_end, tau_end, kick = ends
    pair = np.flatnonzero(owner[1:] == owner[:-1])  # the impacts inside a step: sub-segments pair, pair + 1
    if pair.size and (curved or potential.rule == "trapezoid"):
        hess = potential.hess(qs[pair + 1], par)
        jump = np.zeros(pair.size)
        if potential.rule == "trapezoid":  # 1/4 (tA^2 vA.H vA - tB^2 vB.H vB)
            a, b = vs[pair] * tau[pair, None], vs[pair + 1] * tau[pair + 1, None]
            jump += (_quad(a, hess) - _quad(b, hess)) / 4
        if curved:  # the jump of the h^2 term's boundary value -(h^2/12) qdot.H qdot (both rules)
            va, vb = _impact_velocities(pair, owner, vs, tau, v_start, v_end, h)
            jump += h * h / 12 * (_quad(vb, hess) - _quad(va, hess))
        np.add.at(out, owner[pair + 1], jump)
    nodes = np.unique(np.concatenate([ks, ks + 1]))
    nodes = nodes[(nodes >= 1) & (nodes < steps)]
    nodes = nodes[~on_node[nodes]]
    if nodes.size:
        t1, t2 = tau_end[nodes - 1, None], tau_start[nodes, None]
        v1, v2, qn, J = v_end[nodes - 1], v_start[nodes], q[nodes], kick[nodes - 1]
        minv = potential.minv(qn, par)
        contact = (held[nodes - 1] | held[nodes])[:, None]  # the DEL holds a contact impulse: positions
        if potential.rule == "trapezoid":
            g = potential.grad(qn, par)
            dv = np.where(contact, v2 - v1, np.einsum("knm,km->kn", minv, J - (t1 + t2) / 2 * g))
            mis = _dot(g, dv)
        else:  # g1 . v2 - g2 . v1 = g1 . (v2 - v1) + (g1 - g2) . v1 = g2 . (v2 - v1) + (g1 - g2) . v2
            g1, g2 = potential.grad(qn - v1 * t1 / 2, par), potential.grad(qn + v2 * t2 / 2, par)
            dv = np.where(contact, v2 - v1, np.einsum("knm,km->kn", minv, J - (t1 * g1 + t2 * g2) / 2))
            longer = t1 >= t2  # the velocity of the longer segment: the better conditioned
            mis = np.where(longer[:, 0], _dot(g1, dv) + _dot(g1 - g2, v1), _dot(g2, dv) + _dot(g1 - g2, v2))
        out[nodes] += (t2 - t1)[:, 0] / 4 * mis
    return out


def _quad(v: np.ndarray, mat: np.ndarray) -> np.ndarray:
    return np.einsum("kn,knm,km->k", v, mat, v)


def _impact_velocities(pair, owner, vs, tau, v_start, v_end, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The velocities before and after the impacts between sub-segments ``pair`` and ``pair + 1``: theirs, or
    for one shorter than ``1e-3 h`` (its velocity, a difference of positions over its length, carries
    magnified round-off) that of the segment before it (after it), to O(h)."""
    short = tau < 1e-3 * h
    own = owner[pair]
    first = np.r_[True, owner[1:] != owner[:-1]]  # the first sub-segment of its step
    last = np.r_[owner[1:] != owner[:-1], True]
    prev = np.where(first[pair, None], v_end[np.maximum(own - 1, 0)], vs[np.maximum(pair - 1, 0)])
    nxt_seg = vs[np.minimum(pair + 2, vs.shape[0] - 1)]
    nxt = np.where(last[pair + 1, None], v_start[np.minimum(own + 1, v_start.shape[0] - 1)], nxt_seg)
    va = np.where(short[pair, None], prev, vs[pair])
    vb = np.where(short[pair + 1, None], nxt, vs[pair + 1])
    return va, vb


def friction_work(res: Result, tangents, mu_f, par) -> np.ndarray:
    """``(N-1,)``: the work of Coulomb friction in sustained contact, ``-mu_f lambda h |t . v|`` per step with
    the mean normal force ``lambda`` of ``res.contact_force`` and the tangent gradient ``t`` at the step's
    midpoint (0 while a contact sticks, to round-off). Friction at impacts is in each impact's energy loss.
    On the step a contact lands in (an impact of it, not held at the step's start) only the motion after its
    last impact there is sliding under its force: ``-mu_f lambda h / tau |t . (q_k+1 - q*)|``, ``q*`` the
    impact point, ``tau`` the rest of the step (``lambda h / tau`` the force's mean over it), ``t`` at the
    middle of that rest."""
    steps = res.energy.size
    if tangents is None or steps == 0 or res.contact_force is None:
        return np.zeros(steps)
    q = res.q
    h = float(res.t[1] - res.t[0]) if res.t.size > 1 else 0.0
    landed = {}  # (step, contact): its last impact there, for a contact not held at the step's start
    names = list(res.contact_names)
    for im in res.impacts:
        j, k = names.index(im.contact) if im.contact in names else -1, im.step
        if j >= 0 and k < steps and mu_f[j] > 0.0 and res.contact_force[k, j] != 0.0:
            if (res.active is None or not res.active[k, j]) and res.t[k + 1] > im.t:
                landed[k, j] = im
    mid = 0.5 * (q[:-1] + q[1:])
    grads = tangents(mid, par)
    out = np.zeros(steps)
    for j, mu in enumerate(mu_f):
        lam = res.contact_force[:, j]
        held = lam != 0.0
        held[[k for k, c in landed if c == j]] = False  # those below
        if held.any() and mu > 0.0:
            out[held] -= mu_f[j] * lam[held] * _slide(grads[held, j], q[1:][held] - q[:-1][held])
    for (k, j), im in landed.items():  # the rest of the step after the impact, its force's mean over it
        tau = float(res.t[k + 1] - im.t)
        rest = tangents(0.5 * (im.q + q[k + 1])[None, :], par)[0, j]
        slide = _slide(rest[None], (q[k + 1] - im.q)[None, :])[0]
        out[k] -= mu_f[j] * res.contact_force[k, j] * h / tau * slide
    return out


def _slide(grads: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Per row of ``dq``, the sliding ``|t . dq|`` (one tangent, ``grads`` ``(k, n)``) or its length over
    two (an isotropic cone, ``(k, 2, n)``)."""
    if grads.ndim == 2:
        return np.abs(np.einsum("kn,kn->k", grads, dq))
    return np.hypot(*np.einsum("kdn,kn->dk", grads, dq))
