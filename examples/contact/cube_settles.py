"""A unit cube dropped spinning onto a smooth floor lands on a corner, rocks onto a face and slides on it.

The cube (mass 1, inertia 1/6, ZYX Euler angles ``(psi, theta, phi)``) has its four lower vertices as contacts
with restitution e = 0.3, frictionless. On its face the four rows' normals are dependent (rank 3): three are
held, the fourth rides at phi = 0 (README, *Dependent normals*); before stop 29 the landing on the face ended
the run ("Newton did not converge"). h = 0.005, q0 = (0, 0, 0.9, 0.4, 0.3, 0.1),
v0 = (0.6, 0.25, -0.5, 1.0, 0.5, -0.3).

Printed: the impacts and lift-offs; the horizontal momentum against its start (no horizontal force: exact
throughout); when it is flat on its face; on it, the turn about z at a constant rate (the vertical axis is a
symmetry of the face's contacts) and the floor carrying m g; the vertical and tilting kinetic energy left;
the lowest vertex over the run.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import sympy as sp
from _common import args, build, kinds, mark_impacts, save, simulate

import vcigen

M, G, A, E = 1.0, 9.81, 1.0, 0.3
INERTIA = M * A**2 / 6
CORNERS = [(sx, sy) for sx in (1, -1) for sy in (1, -1)]
SETUP = {
    "q0": [0.0, 0.0, 0.9, 0.4, 0.3, 0.1],
    "v0": [0.6, 0.25, -0.5, 1.0, 0.5, -0.3],
    "h": 0.005,
    "t_end": 3.0,
}


def model(mu: float | None = None) -> vcigen.Model:
    """The cube; with ``mu`` each vertex on a rough floor, an isotropic cone (tangents: its x and y), as
    ``bench/cube_drops.py`` runs it."""
    x, y, z, ps, th, ph = sp.symbols("x y z psi theta phi")
    xd, yd, zd, psd, thd, phd = sp.symbols("xd yd zd psid thetad phid")
    e, m_u = sp.symbols("e mu")
    c, s = sp.cos, sp.sin
    rot = (
        sp.Matrix([[c(ps), -s(ps), 0], [s(ps), c(ps), 0], [0, 0, 1]])
        * sp.Matrix([[c(th), 0, s(th)], [0, 1, 0], [-s(th), 0, c(th)]])
        * sp.Matrix([[1, 0, 0], [0, c(ph), -s(ph)], [0, s(ph), c(ph)]])
    )
    corners = [rot * sp.Matrix([sx * A / 2, sy * A / 2, -A / 2]) for sx, sy in CORNERS]
    contacts = {f"v{i}": z + k[2] for i, k in enumerate(corners)}
    cones = {j: (m_u, (x + k[0], y + k[1])) for j, k in zip(contacts, corners)} if mu is not None else {}
    omega2 = phd**2 + thd**2 + psd**2 - 2 * phd * psd * sp.sin(th)  # |omega|^2 in ZYX rates
    return vcigen.Model(
        name="cube_settles" if mu is None else "cube_rough",
        q=[x, y, z, ps, th, ph],
        qdot=[xd, yd, zd, psd, thd, phd],
        lagrangian=M / 2 * (xd**2 + yd**2 + zd**2) + INERTIA / 2 * omega2 - M * G * z,
        contacts=contacts,
        params={e: E} if mu is None else {e: E, m_u: mu},
        restitution=dict.fromkeys(contacts, e),
        friction=cones,
    )


def heights(q: np.ndarray) -> np.ndarray:
    """The four lower vertices' heights along ``q`` (rows: grid points)."""
    th, ph = q[:, 4], q[:, 5]
    out = [-np.sin(th) * sx + np.cos(th) * np.sin(ph) * sy - np.cos(th) * np.cos(ph) for sx, sy in CORNERS]
    return q[:, 2:3] + np.array(out).T * A / 2


def tilt_energy(res: vcigen.Result) -> np.ndarray:
    """Kinetic energy of the vertical and tilting motion: ``p_z^2 / 2m`` and the ``(theta, phi)`` part."""
    inv = np.linalg.inv
    out = []
    for q, p in zip(res.q, res.p):
        s = math.sin(q[4])
        mass = INERTIA * np.array([[1.0, 0.0, -s], [0.0, 1.0, 0.0], [-s, 0.0, 1.0]])  # (psi, theta, phi)
        w = inv(mass) @ p[3:]
        out.append(p[2] ** 2 / (2 * M) + INERTIA / 2 * (w[1] ** 2 + w[2] ** 2))
    return np.array(out)


def report(res: vcigen.Result) -> None:
    print(f"impacts: {kinds(res)}; lift-offs: {len(res.liftoffs)}")
    for im in res.impacts:
        print(f"  t = {im.t:.5f}  {im.contact}  {im.kind:<11}  impulse {im.impulse:.6f}")
    mom = res.p[:, :2] - M * np.array(SETUP["v0"][:2])
    print(f"horizontal momentum: max |p_xy - m v0_xy| = {np.abs(mom).max():.1e} (no horizontal force)")
    flat = (np.abs(heights(res.q)).max(axis=1) < 1e-9) & (np.abs(res.p[:, [2, 4, 5]]).max(axis=1) < 1e-9)
    k = int(np.flatnonzero(~flat)[-1] + 1)
    rate = res.p[k:, 3] / INERTIA
    print(
        f"flat on its face from t = {res.t[k]:.4f}; turning about z at {rate.mean():.12f} rad/s "
        f"(max dev {np.abs(rate - rate.mean()).max():.1e})"
    )
    total = res.contact_force[k:].sum(axis=1)
    print(
        f"on its face: floor force {total.mean():.12f} vs m g = {M * G:.12f} (max dev "
        f"{np.abs(total - M * G).max():.1e}); vertices held at the end: "
        f"{', '.join(n for n, on in zip(res.contact_names, res.active[-1]) if on)}"
    )
    ke = tilt_energy(res)
    print(f"vertical + tilting kinetic energy end/start: {ke[-1] / ke[0]:.1e} (target < 1e-9)")
    print(f"lowest vertex over the run: {heights(res.q).min():.1e} (>= -1e-9)")


def plot(res: vcigen.Result, out: str, backend: str) -> None:
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), dpi=110, sharex=True)
    h_ax, f_ax, e_ax = axes
    hs = heights(res.q)
    for i, name in enumerate(res.contact_names):
        h_ax.plot(res.t, hs[:, i], lw=0.8, label=name)
        f_ax.plot(res.t[1:], res.contact_force[:, i], lw=0.8, label=name)
    mark_impacts(h_ax, res, [0.0] * len(res.impacts), size=12)
    h_ax.set_ylabel("vertex height")
    h_ax.legend(loc="upper right", fontsize=7, ncol=2)
    f_ax.plot(res.t[1:], res.contact_force.sum(axis=1), lw=1.0, color="k", label="sum")
    f_ax.axhline(M * G, ls=":", lw=0.7, color="C3")
    f_ax.set_ylabel("normal force (m g dotted)")
    f_ax.legend(loc="upper right", fontsize=7, ncol=3)
    e_ax.semilogy(res.t, np.maximum(tilt_energy(res), 1e-300), lw=0.8, color="k")
    e_ax.set_ylabel("vertical + tilting KE")
    e_ax.set_xlabel("t")
    h_ax.set_title(f"cube, e = {E}, h = {SETUP['h']} [{backend}]: {kinds(res)}", fontsize=10)
    save(fig, out, f"cube_settles_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    res = simulate(build(model(), a.backend), **SETUP)
    report(res)
    plot(res, a.out, a.backend)
