"""Cost of a grid step in sustained contact against a free step of the same model (C and CasADi).

    .venv/bin/python -m bench.sustained_cost [--steps 200000] [--casadi-steps 1000] [--repeats 5]
        [--scenes bowl ...]

Target (the issue): a sustained-contact step in C costs at most 3x a free step.

Scenes (h = 1e-3; "sustained" starts on the contact and stays active the whole run, checked
through ``res.active``; "free" never touches it, checked through ``res.active`` and the impacts):

* ``particle``: ``L = (xd^2 + yd^2)/2 - 9.81 y``, floor ``y``. Sustained: ``q0 = (0, 0)``,
  ``v0 = (1, 0)`` (slides); free: ``q0 = (0, 1e6)``, ``v0 = (1, 0)``.
* ``spring_polar``: a particle on a spring ``k/2 (r - l0)^2`` (k = 5, l0 = 1) from the origin, in
  polar coordinates (mass ``diag(1, r^2)``: the free step is a Newton solve), floor ``y = -c``.
  Sustained: ``c = 1``, ``q0 = (r, theta) = (1, -pi/2)``, ``v0 = (0, 1)`` (Cartesian (1, 0)): it
  slides to and fro along the floor, the spring pulling it back, normal force
  ``g - k (r - l0)/r > 0``; free: ``c = 10`` (the same code, the floor out of reach: the swing
  stays above ``y = -5``), the same start.
* ``box``: a 2 x 1 rectangle with a contact at each vertex, sliding on its long face (``q0 = (0, 0.5, 0)``,
  ``v0 = (1, 0, 0)``: two vertex rows held) against free high up.
* ``bowl``: a particle inside a circular bowl, contact ``r - |q|``: sustained ``r = 1``, released at rest at
  ``q0 = (0.6, -0.8)`` on the wall, it slides to and fro along it (a curved row that moves: the previous
  multipliers never solve the held step, whose second evaluation is at the line start of ``vcigen.held``);
  free: ``r = 1e9``, ``q0 = 0``, ``v0 = (1, 0)``
  (falls 2e5 m in 200 s, far from the wall).
* ``star``: the star of ``examples/star.py`` resting on a face (``q0 = (0, 0.5, 0)``,
  ``v0 = (1, 0, 0)``, slides) against free high up (``q0 = (0, 1e6, 0)``, same ``v0``).

The particle's, the bowl's, the box's and the star's free step is the C backend's explicit straight-line grid
step (constant diagonal mass), and their sustained step the held grid step (``vcigen.held``: straight-line
code in the held rows' multipliers). Their ``*_general`` variants multiply the kinetic energy by
``(1 + eps x)`` with the parameter ``eps = 0``: the same dynamics (checked: same end state), but
the mass is configuration-dependent to the code generator, so every free step takes the general
path (damped Newton on (46), no explicit grid step; in contact the constrained chain, two Newton solves
on ``n + R`` unknowns). The table gives, per backend, ns per step of
each run (best of ``--repeats``, all runs of a backend interleaved round-robin), the ratio sustained/free,
and for the explicit scenes also sustained / free of the ``_general`` variant. Times are the
simulator's own loop time (``res.stats["wall_time"]``: the C loop, or the CasADi stepper's loop),
not the Python set-up of ``simulate``; for C also the CPU time of that loop (``time.thread_time``
around ``<model>_run_many``), which a loaded machine does not inflate. Writes
``bench/results/sustained_cost.csv``.
"""

from __future__ import annotations

import argparse
import csv
import ctypes
import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen
from vcigen.cli import load_example

HERE = Path(__file__).resolve().parent
H = 1e-3
G = 9.81


def particle(general: bool = False) -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    eps = sp.Symbol("eps")
    kinetic = (xd**2 + yd**2) / 2
    return vcigen.Model(
        name="sc_particle_general" if general else "sc_particle",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=kinetic * ((1 + eps * x) if general else 1) - G * y,
        contacts={"floor": y},
        params={eps: 0.0} if general else {},
    )


def box(general: bool = False) -> vcigen.Model:
    """A 2 x 1 rectangle (unit mass) with a contact at each vertex: on its long face two rows are held."""
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    eps = sp.Symbol("eps")
    kinetic = (xd**2 + yd**2) / 2 + sp.Rational(5, 24) * thd**2
    corners = [(1.0, -0.5), (-1.0, -0.5), (1.0, 0.5), (-1.0, 0.5)]
    return vcigen.Model(
        name="sc_box_general" if general else "sc_box",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=kinetic * ((1 + eps * x) if general else 1) - G * y,
        contacts={f"v{i}": y + a * sp.sin(th) + b * sp.cos(th) for i, (a, b) in enumerate(corners)},
        params={eps: 0.0} if general else {},
    )


def spring_polar() -> vcigen.Model:
    r, th, rd, thd = sp.symbols("r theta rd thetad")
    k, l0, c = sp.symbols("k l0 c", positive=True)
    return vcigen.Model(
        name="sc_spring_polar",
        q=[r, th],
        qdot=[rd, thd],
        lagrangian=(rd**2 + r**2 * thd**2) / 2 - k / 2 * (r - l0) ** 2 - G * r * sp.sin(th),
        contacts={"floor": r * sp.sin(th) + c},
        params={k: 5.0, l0: 1.0, c: 1.0},
    )


def bowl() -> vcigen.Model:
    """A particle inside a circular bowl of radius ``r`` about the origin (contact ``r - |q|``): a curved row
    that moves, so that the held step's Newton iterates (the previous multipliers do not solve it)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    r = sp.Symbol("r", positive=True)
    return vcigen.Model(
        name="sc_bowl",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"bowl": r - sp.sqrt(x**2 + y**2)},
        params={r: 1.0},
    )


def star(general: bool = False) -> vcigen.Model:
    if not general:
        return load_example(HERE.parent / "examples" / "star.py").model()
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    m, g, L, eps = sp.symbols("m g L eps")
    inertia = sp.Rational(29, 192) * m * L**2
    kinetic = m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2
    return vcigen.Model(
        name="sc_star_general",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=kinetic * (1 + eps * x) - m * g * y,
        contacts={"floor": y - L / 2 * (sp.Abs(sp.sin(th)) + sp.Abs(sp.cos(th)))},
        params={m: 1.0, g: 9.81, L: 1.0, eps: 0.0},
    )


@dataclass
class Scene:
    name: str
    model: object  # factory
    sustained: dict
    free: dict
    reference: str | None = None  # the explicit scene a "_general" variant mirrors
    sims: dict = field(default_factory=dict)


SCENES = [
    Scene("particle", particle, dict(q0=[0.0, 0.0], v0=[1.0, 0.0]), dict(q0=[0.0, 1e6], v0=[1.0, 0.0])),
    Scene(
        "particle_general",
        lambda: particle(True),
        dict(q0=[0.0, 0.0], v0=[1.0, 0.0]),
        dict(q0=[0.0, 1e6], v0=[1.0, 0.0]),
        reference="particle",
    ),
    Scene(
        "spring_polar",
        spring_polar,
        dict(q0=[1.0, -math.pi / 2], v0=[0.0, 1.0], params={"c": 1.0}),
        dict(q0=[1.0, -math.pi / 2], v0=[0.0, 1.0], params={"c": 10.0}),
    ),
    Scene(
        "box", box, dict(q0=[0.0, 0.5, 0.0], v0=[1.0, 0.0, 0.0]), dict(q0=[0.0, 1e6, 0.0], v0=[1.0, 0.0, 0.0])
    ),
    Scene(
        "box_general",
        lambda: box(True),
        dict(q0=[0.0, 0.5, 0.0], v0=[1.0, 0.0, 0.0]),
        dict(q0=[0.0, 1e6, 0.0], v0=[1.0, 0.0, 0.0]),
        reference="box",
    ),
    Scene(
        "bowl",
        bowl,
        dict(q0=[0.6, -0.8], v0=[0.0, 0.0], params={"r": 1.0}),
        dict(q0=[0.0, 0.0], v0=[1.0, 0.0], params={"r": 1e9}),
    ),
    Scene(
        "star",
        star,
        dict(q0=[0.0, 0.5, 0.0], v0=[1.0, 0.0, 0.0]),
        dict(q0=[0.0, 1e6, 0.0], v0=[1.0, 0.0, 0.0]),
    ),
    Scene(
        "star_general",
        lambda: star(True),
        dict(q0=[0.0, 0.5, 0.0], v0=[1.0, 0.0, 0.0]),
        dict(q0=[0.0, 1e6, 0.0], v0=[1.0, 0.0, 0.0]),
        reference="star",
    ),
]


def run(sim: vcigen.Simulator, setup: dict, steps: int) -> vcigen.Result:
    return sim.simulate(setup["q0"], setup["v0"], H, t_end=steps * H, params=setup.get("params"))


def check(scene: str, kind: str, res: vcigen.Result, steps: int) -> str:
    """What the run did; raise if a sustained run is not active throughout or a free one touches."""
    assert res.t.size == steps + 1, (scene, kind, res.t.size)
    if kind == "sustained":
        held = res.active[0]  # the contacts held at the start (the box: two of its four vertices)
        ok = bool(held.any() and (res.active == held).all()) and not res.impacts and not res.liftoffs
        assert ok, f"{scene}: the sustained run left the contact ({len(res.liftoffs)} lift-offs)"
        return f"active throughout, mean force {float(res.contact_force.mean()):.4g}"
    assert not res.active.any() and not res.impacts, f"{scene}: the free run touched the contact"
    return "never touches"


def cpu_clock(sim: vcigen.Simulator) -> list[float]:
    """Count the CPU time of the C loop (``<model>_run_many``, which ``simulate`` calls, and ``<model>_run``)
    of ``sim``'s runs: a loaded machine's wall time holds the time the process waits for a core; its CPU
    time does not."""
    spent = [0.0]

    def timed(loop):
        def call(*args):
            t = time.thread_time()
            rc = loop(*args)
            spent[0] += time.thread_time() - t
            return rc

        return call

    for name in ("run", "run_many"):
        setattr(sim.kernels, name, timed(getattr(sim.kernels, name)))
    return spent


def keep_heap() -> None:
    """Keep freed result buffers in the heap (glibc ``mallopt``): a run's fresh ``Q``, ``P``, ``E``, ``F`` are
    then pages touched before, not first-touch page faults inside the timed C loop (on this VM ~1 us per
    4 kB page, ~10x the particle's free step per step; and the held loop writes more logs per step than the
    free glide, so the faults would bias the ratio too). Best of the repeats is a run on warm pages."""
    try:
        libc = ctypes.CDLL(None)
        libc.mallopt(-3, 1 << 25)  # M_MMAP_THRESHOLD: buffers up to 32 MB from the heap, not mmap
        libc.mallopt(-1, 1 << 30)  # M_TRIM_THRESHOLD: freed heap memory kept
    except (OSError, AttributeError):
        pass


def measure(scenes: list[Scene], backend: str, steps: int, repeats: int) -> list[dict]:
    """Best of ``repeats`` of every (scene, sustained/free) run, all interleaved round-robin: the loop's wall
    time and (C) its CPU time."""
    best = {(sc.name, kind): math.inf for sc in scenes for kind in ("sustained", "free")}
    cpu = dict(best)
    clocks = {sc.name: cpu_clock(sc.sims[backend]) for sc in scenes} if backend == "c" else {}
    notes, ends = {}, {}
    for _ in range(repeats):
        for sc in scenes:
            for kind in ("sustained", "free"):
                before = clocks[sc.name][0] if clocks else 0.0
                res = run(sc.sims[backend], getattr(sc, kind), steps)
                best[sc.name, kind] = min(best[sc.name, kind], res.stats["wall_time"])
                cpu[sc.name, kind] = min(
                    cpu[sc.name, kind], clocks[sc.name][0] - before if clocks else math.nan
                )
                if (sc.name, kind) not in notes:
                    notes[sc.name, kind] = check(sc.name, kind, res, steps)
                    ends[sc.name, kind] = res.q[-1].copy()
    return [
        dict(
            scene=sc.name,
            backend=backend,
            steps=steps,
            ns_sustained=best[sc.name, "sustained"] / steps * 1e9,
            ns_free=best[sc.name, "free"] / steps * 1e9,
            ratio=best[sc.name, "sustained"] / best[sc.name, "free"],
            cpu_ns_sustained=cpu[sc.name, "sustained"] / steps * 1e9,
            cpu_ns_free=cpu[sc.name, "free"] / steps * 1e9,
            cpu_ratio=cpu[sc.name, "sustained"] / cpu[sc.name, "free"],
            notes=f"sustained: {notes[sc.name, 'sustained']}; free: {notes[sc.name, 'free']}",
            ends={kind: ends[sc.name, kind] for kind in ("sustained", "free")},
        )
        for sc in scenes
    ]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200_000, help="grid steps per C run")
    ap.add_argument("--casadi-steps", type=int, default=1_000, help="grid steps per CasADi run")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--backend", nargs="+", default=["c", "casadi"], choices=["c", "casadi"])
    ap.add_argument("--csv", type=Path, default=HERE / "results" / "sustained_cost.csv")
    names = [s.name for s in SCENES]
    ap.add_argument("--scenes", nargs="+", choices=names, help="these scenes only (and the ones they mirror)")
    a = ap.parse_args(argv)
    scenes = [s for s in SCENES if not a.scenes or s.name in a.scenes]
    scenes += [s for s in SCENES if s.name in {x.reference for x in scenes} and s not in scenes]
    warnings.simplefilter("ignore", RuntimeWarning)
    keep_heap()
    rows = []
    for backend in a.backend:
        steps = a.steps if backend == "c" else a.casadi_steps
        for scene in scenes:
            scene.sims[backend] = vcigen.build(scene.model(), backend=backend)
        got = measure(scenes, backend, steps, a.repeats)
        by_name = {r["scene"]: r for r in got}
        for scene, row in zip(scenes, got):
            if scene.reference:  # the same dynamics: the variant must end where its explicit scene does
                ref = by_name[scene.reference]
                for kind in ("sustained", "free"):
                    gap = float(np.max(np.abs(row["ends"][kind] - ref["ends"][kind])))
                    scale = 1.0 + float(np.max(np.abs(ref["ends"][kind])))
                    assert gap <= 1e-6 * scale, (scene.name, kind, gap)
                ref["ns_free_general"] = row["ns_free"]
                ref["ratio_vs_general_free"] = ref["ns_sustained"] / row["ns_free"]
                ref["cpu_ratio_vs_general_free"] = ref["cpu_ns_sustained"] / row["cpu_ns_free"]
        rows += got
    cols = [
        "scene",
        "backend",
        "steps",
        "ns_sustained",
        "ns_free",
        "ratio",
        "ns_free_general",
        "ratio_vs_general_free",
        "cpu_ns_sustained",
        "cpu_ns_free",
        "cpu_ratio",
        "cpu_ratio_vs_general_free",
        "notes",
    ]
    print(
        f"{'scene':<18} {'backend':<7} {'steps':>7} {'sustained ns':>13} {'free ns':>11} {'ratio':>7}"
        f" {'general free ns':>16} {'ratio vs general':>17}"
    )
    for r in rows:
        gen = r.get("ns_free_general")
        print(
            f"{r['scene']:<18} {r['backend']:<7} {r['steps']:>7d} {r['ns_sustained']:>13.1f}"
            f" {r['ns_free']:>11.1f} {r['ratio']:>7.2f} {'' if gen is None else f'{gen:.1f}':>16}"
            f" {'' if gen is None else format(r['ratio_vs_general_free'], '.2f'):>17}"
        )
    print("CPU time of the C loop (the same runs; the ratios to read on a loaded machine):")
    print(f"{'scene':<18} {'sustained ns':>13} {'free ns':>11} {'ratio':>7} {'ratio vs general free':>22}")
    for r in rows:
        if r["backend"] == "c":
            gen = r.get("cpu_ratio_vs_general_free")
            print(
                f"{r['scene']:<18} {r['cpu_ns_sustained']:>13.1f} {r['cpu_ns_free']:>11.1f}"
                f" {r['cpu_ratio']:>7.2f} {'' if gen is None else format(gen, '.2f'):>22}"
            )
    for r in rows:
        print(f"  {r['scene']} ({r['backend']}): {r['notes']}")
    a.csv.parent.mkdir(parents=True, exist_ok=True)
    with a.csv.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(
                {k: (repr(float(v)) if isinstance(v, float) else v) for k, v in r.items() if k in cols}
            )
    print(f"wrote {a.csv}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
