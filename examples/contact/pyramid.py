"""Three disks in a pyramid: bodies resting on bodies, on a frictionless and on a rough floor.

Three unit disks of radius R = 0.5 (particles in the plane, each pair a contact |q_j - q_i| - 2R, each
disk the floor y - R; e = 0.3 everywhere, a parameter as mu is), two on the floor touching and one on top of
them.

* Frictionless floor (mu = 0): the top pushes the lower disks apart and leaves both at once, where the force
  on them vanishes. Reduced to the angle theta of each lower-to-top line (the motion is symmetric), L = 2 R^2
  theta'^2 (2 cos^2 theta + sin^2 theta) - 2 g R cos theta, and the lower disks' acceleration (the force) is
  proportional to cos theta theta'' - sin theta theta'^2: scipy locates its zero (1e-12). Printed: the
  release time against it at three steps with its order; then the top falls between the lower disks to the
  floor.
* Rough floor (mu = 0.5): the top dropped 0.05 onto them settles; at rest the floor carries 3 m g / 2 under
  each lower disk and the top's two contacts m g / (2 cos beta) each, beta their angle from the vertical
  (statics). Printed against those.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import sympy as sp
from _common import args, build, kinds, save, simulate
from matplotlib.patches import Circle
from scipy.integrate import solve_ivp

import vcigen
from vcigen.analysis import fit_order

G, R, E = 9.81, 0.5, 0.3
PAIRS = {"p12": (0, 1), "p13": (0, 2), "p23": (1, 2)}
STEPS = (0.01, 0.005, 0.0025)
APEX = [-R, R, R, R, 0.0, R + math.sqrt(3) * R]  # the lower disks touching, the top on both
SETUP = {"q0": APEX[:5] + [APEX[5] + 0.05], "v0": [0.0] * 6, "h": 0.005, "t_end": 3.0}  # the rough run


def model() -> vcigen.Model:
    q, v = sp.symbols("x1 y1 x2 y2 x3 y3"), sp.symbols("a1 b1 a2 b2 a3 b3")
    mu, e = sp.Symbol("mu", nonnegative=True), sp.Symbol("e", nonnegative=True)

    def pair(i: int, j: int):
        return sp.sqrt((q[2 * j] - q[2 * i]) ** 2 + (q[2 * j + 1] - q[2 * i + 1]) ** 2) - 2 * R

    contacts = {"f1": q[1] - R, "f2": q[3] - R, "f3": q[5] - R} | {n: pair(*ij) for n, ij in PAIRS.items()}
    return vcigen.Model(
        name="pyramid",
        q=list(q),
        qdot=list(v),
        lagrangian=sum(x**2 for x in v) / 2 - G * (q[1] + q[3] + q[5]),
        contacts=contacts,
        params={mu: 0.5, e: E},
        restitution={name: e for name in contacts},
        friction={"f1": (mu, q[0]), "f2": (mu, q[2]), "f3": (mu, q[4])},
    )


def release_time() -> float:
    """When the top of the symmetric pyramid (at rest, frictionless floor) leaves both lower disks: scipy on
    the angle theta from pi / 6, the event cos theta theta'' - sin theta theta'^2 = 0 (1e-12)."""
    t, th, w = sp.Symbol("t"), sp.Symbol("th"), sp.Symbol("w")
    f = sp.Function("f")(t)
    lag = 2 * R**2 * f.diff(t) ** 2 * (2 * sp.cos(f) ** 2 + sp.sin(f) ** 2) - 2 * G * R * sp.cos(f)
    euler = sp.diff(lag.diff(f.diff(t)), t) - lag.diff(f)
    acc = sp.solve(euler, f.diff(t, 2))[0].subs(f.diff(t), w).subs(f, th)
    accel = sp.lambdify((th, w), acc)
    force = sp.lambdify((th, w), sp.cos(th) * acc - sp.sin(th) * w**2)

    def event(_, s):
        return force(s[0], s[1])

    event.terminal, event.direction = True, -1
    sol = solve_ivp(
        lambda _, s: [s[1], accel(*s)], (0, 5), [math.pi / 6, 0.0], events=event, rtol=1e-12, atol=1e-12
    )
    return float(sol.t_events[0][0])


def gaps(q: np.ndarray) -> np.ndarray:
    """Every contact's gap at every grid point: the three floors, then the three pairs."""
    out = [q[:, 2 * i + 1] - R for i in range(3)]
    out += [
        np.hypot(q[:, 2 * j] - q[:, 2 * i], q[:, 2 * j + 1] - q[:, 2 * i + 1]) - 2 * R
        for i, j in PAIRS.values()
    ]
    return np.column_stack(out)


def frictionless(sim: vcigen.Simulator) -> vcigen.Result:
    exact = release_time()
    runs = {h: simulate(sim, q0=APEX, v0=[0.0] * 6, h=h, t_end=2.0, params={"mu": 0.0}) for h in STEPS}
    errors = []
    for h, res in runs.items():
        released = {name: t for t, name in res.liftoffs}
        errors.append(abs(released["p13"] - exact))
        print(
            f"h = {h}: the top leaves both at t = {released['p13']:.8f} (p23 at {released['p23']:.8f}; scipy "
            f"{exact:.8f}), error {errors[-1]:.1e}"
        )
    print(f"observed order of the release: {fit_order(list(runs), errors):.2f} (expected 2)")
    res = runs[STEPS[1]]
    print(f"frictionless, h = {res.h}: {kinds(res)}; lowest gap {gaps(res.q).min():.1e}")
    sym = np.abs(res.q[:, 0] + res.q[:, 2]).max()
    print(f"symmetric: max |x1 + x2| {sym:.1e}, max |x3| {np.abs(res.q[:, 4]).max():.1e}")
    return res


def rough(sim: vcigen.Simulator) -> vcigen.Result:
    res = simulate(sim, **SETUP, params={"mu": 0.5})
    q = res.q[-1]
    cos_b = (q[5] - q[1]) / (2 * R)
    want = np.array([1.5 * G, 1.5 * G, 0.0, 0.0, G / (2 * cos_b), G / (2 * cos_b)])
    print(f"rough (mu = 0.5), h = {res.h}: {kinds(res)}; lowest gap {gaps(res.q).min():.1e}")
    print(f"at rest: |p| {np.abs(res.p[-1]).max():.1e}; the lower disks {q[2] - q[0] - 2 * R:.2e} apart")
    print(
        "forces at the end (f1, f2, f3, p12, p13, p23):", np.array2string(res.contact_force[-1], precision=6)
    )
    print(" statics (3 g / 2 under each, g / (2 cos beta) from the top):", np.array2string(want, precision=6))
    print(f" max deviation {np.abs(res.contact_force[-1] - want).max():.1e}")
    return res


def plot(slide: vcigen.Result, rest: vcigen.Result, out: str, backend: str) -> None:
    fig, (d_ax, f_ax) = plt.subplots(1, 2, figsize=(10, 4.2), dpi=110)
    for k, t in enumerate((0.0, 0.35, 0.55, 0.75)):
        i = int(np.searchsorted(slide.t, t))
        for j in range(3):
            x, y = slide.q[i, 2 * j], slide.q[i, 2 * j + 1]
            d_ax.add_patch(
                Circle((x, y), R, fill=False, color=f"C{k}", lw=1.0, label=f"t = {t}" if j == 0 else None)
            )
    d_ax.axhline(0, color="k", lw=0.8)
    d_ax.set_xlim(-2.2, 2.2)
    d_ax.set_ylim(-0.1, 2.0)
    d_ax.set_aspect("equal")
    d_ax.legend(loc="upper right", fontsize=7)
    d_ax.set_title(f"frictionless floor, h = {slide.h}: {kinds(slide)}", fontsize=9)
    for j, name in enumerate(["f1", "f2", "f3", *PAIRS]):
        f_ax.plot(rest.t[:-1], rest.contact_force[:, j], lw=0.9, label=name)
    f_ax.set_xlabel("t")
    f_ax.set_ylabel("contact force")
    f_ax.legend(loc="upper right", fontsize=7, ncol=2)
    f_ax.set_title(f"rough floor (mu = 0.5), h = {rest.h}: settling, then statics", fontsize=9)
    fig.suptitle(f"a pyramid of three disks [{backend}]", fontsize=10)
    save(fig, out, f"pyramid_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    sim = build(model(), a.backend)
    slide = frictionless(sim)
    rest = rough(sim)
    plot(slide, rest, a.out, a.backend)
