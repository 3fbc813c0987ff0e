"""The impact log as arrays (issue 13): ``res.impact_table`` and the lazy ``res.impacts``.

The C backend keeps its impact records as arrays and makes :class:`vcigen.Impact` objects only when
they are read; they must be the objects the records say (every column in its place), in time order,
of the kinds the C stepper counted, and behave as the list they replace. The Python stepper keeps a
list and exposes the same table.
"""

from __future__ import annotations

import pickle
from collections import Counter

import numpy as np
import pytest
from hard_scenes import backend_param, simulator

import vcigen
from vcigen.impacts import KINDS, Impacts, ImpactTable


def lossy_ball_run(backend: str) -> vcigen.Result:
    """A lossy ball bouncing to rest: restitution impacts, then a plastic one (sustained contact)."""
    return simulator("ball", backend).simulate([0.0, 1.0], [0.3, 0.0], 0.005, t_end=1.6, params={"e": 0.5})


@pytest.mark.parametrize("backend", [backend_param("c"), backend_param("casadi")])
def test_impacts_are_consistent_with_the_grid_and_the_kind_counts(backend: str) -> None:
    """Each impact: t = t_step + alpha h with 0 <= alpha <= 1, on the floor (q_y = 0), in time order,
    E_after < E_before (e = 0.5); the kinds counted by the stepper are the kinds of the log."""
    res = lossy_ball_run(backend)
    tab = res.impact_table
    assert len(tab) == res.n_impacts > 5
    ims = list(res.impacts)
    for im in ims:
        assert im.t == pytest.approx(res.t[im.step] + im.alpha * res.h, abs=1e-12)
        assert 0.0 <= im.alpha <= 1.0
        assert im.q[1] == pytest.approx(0.0, abs=1e-9)
        assert im.contact == "floor" and im.kind in KINDS
        assert im.energy_after < im.energy_before and im.impulse > 0
    assert all(a.t <= b.t for a, b in zip(ims, ims[1:]))
    kinds = Counter(im.kind for im in ims)
    assert kinds["restitution"] > 0 and kinds["plastic"] >= 1
    for kind in KINDS:
        assert kinds[kind] == res.stats[f"impacts_{kind}"], kind
    # the table's columns are the objects' attributes
    assert np.array_equal(tab.t, [im.t for im in ims])
    assert np.array_equal(tab.q, np.array([im.q for im in ims]))
    assert [tab.contact_names[c] for c in tab.contact] == [im.contact for im in ims]
    assert [KINDS[k] for k in tab.kind] == [im.kind for im in ims]
    for name in ("step", "alpha", "impulse", "energy_before", "energy_after"):
        assert np.array_equal(getattr(tab, name), [getattr(im, name) for im in ims]), name


def test_c_and_python_impact_tables_agree() -> None:
    """The same run on both backends: the same table (to the agreement of the two steppers)."""
    sim_c, sim_py = simulator("ball", "c"), simulator("ball", "casadi")
    a = sim_c.simulate([0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=4, params={"e": 0.8})
    b = sim_py.simulate([0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=4, params={"e": 0.8})
    ta, tb = a.impact_table, b.impact_table
    assert isinstance(a.impacts, Impacts) and isinstance(b.impacts, list)
    assert len(ta) == len(tb) == 4
    for name in ("step", "contact", "kind"):
        assert np.array_equal(getattr(ta, name), getattr(tb, name)), name
    for name in ("t", "q", "alpha", "impulse", "energy_before", "energy_after"):
        np.testing.assert_allclose(getattr(ta, name), getattr(tb, name), rtol=1e-9, atol=1e-12, err_msg=name)


def test_lazy_impacts_behave_as_the_eager_list() -> None:
    """len, indices (negative too), slices, iteration, equality with the eager list of the records."""
    res = simulator("ball", "c").simulate([0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=7, params={"e": 1.0})
    lazy = res.impacts
    rec = np.column_stack(
        [
            res.impact_table.t,
            res.impact_table.contact,
            res.impact_table.step,
            res.impact_table.alpha,
            res.impact_table.impulse,
            res.impact_table.energy_before,
            res.impact_table.energy_after,
            res.impact_table.q,
            res.impact_table.kind,
        ]
    )
    eager = [  # the C record layout read as the old wrapper read it, one object per row
        vcigen.Impact(
            t=float(r[0]),
            contact=("floor",)[int(r[1])],
            q=r[7:-1].copy(),
            alpha=float(r[3]),
            impulse=float(r[4]),
            step=int(r[2]),
            energy_before=float(r[5]),
            energy_after=float(r[6]),
            kind=KINDS[int(r[-1])],
        )
        for r in rec
    ]
    assert len(lazy) == 7 and lazy == eager and eager == lazy
    assert lazy[-1] == eager[-1] and lazy[2] == eager[2]
    assert lazy[1:5] == eager[1:5] and lazy[::-2] == eager[::-2]
    assert list(lazy) == eager and [im.t for im in lazy] == [im.t for im in eager]
    assert lazy != eager[:-1] and lazy != [*eager[:-1], eager[0]]
    with pytest.raises(IndexError):
        lazy[7]
    assert bool(lazy) and res.n_impacts == 7


def test_impact_equality_compares_every_attribute() -> None:
    base = dict(t=1.0, contact="c", q=np.array([1.0, 2.0]), alpha=0.5, impulse=2.0, step=3,
                energy_before=1.0, energy_after=1.0, kind="elastic")  # fmt: skip
    a = vcigen.Impact(**base)
    assert a == vcigen.Impact(**{**base, "q": np.array([1.0, 2.0])})
    for key, other in (("q", np.array([1.0, 2.5])), ("t", 1.5), ("kind", "grazing"), ("step", 4)):
        assert a != vcigen.Impact(**{**base, key: other}), key


def test_empty_log_and_pickled_result() -> None:
    """No impact: an empty table of the right shapes. A Result pickles (sweep ships them) with its v."""
    res = simulator("ball", "c").simulate([0.0, 1.0], [0.0, 0.0], 0.01, t_end=0.2)
    assert res.n_impacts == 0 and res.impact_table.q.shape == (0, 2) and list(res.impacts) == []
    back = pickle.loads(pickle.dumps(res))
    assert np.array_equal(back.q, res.q) and back.impacts == res.impacts
    assert np.array_equal(back.v, res.v)


def test_table_from_impacts_round_trip() -> None:
    res = lossy_ball_run("casadi")
    tab = ImpactTable.from_impacts(res.impacts, ("floor",), 2)
    assert Impacts(tab) == res.impacts


@pytest.mark.parametrize("backend", [backend_param("c"), backend_param("casadi")])
def test_too_many_impacts_in_a_step_names_the_tolerance(backend: str) -> None:
    """A particle between walls 1e-3 apart at h = 0.01 has ~20 genuine impacts per step: over the
    limit, the error names ``Tolerances.max_impacts_per_step`` and does not guess chattering."""
    sim = simulator("walls", backend, tol=vcigen.Tolerances(max_impacts_per_step=4))
    with pytest.raises(vcigen.SolverError) as info:
        sim.simulate(q0=[0.0005, 0.0], v0=[1.0, 0.0], h=0.01, t_end=0.05, params={"d": 0.001})
    msg = str(info.value)
    assert "more than 4 impacts in one step" in msg and "Tolerances.max_impacts_per_step" in msg
    assert "chattering" not in msg
