"""bench.sens_fuzz: its test of a column (smooth, wrong, at a kink) on maps known in closed form, and a few
random rough drops into a V-groove, whose tangents match central differences on both backends."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench import sens_fuzz

EPS = 1e-6


def _ends(f, x0: float, eps: float = EPS) -> tuple[np.ndarray, dict[float, np.ndarray]]:
    return f(x0), {dx: f(x0 + dx) for dx in (eps, -eps, eps / 4, -eps / 4)}


def smooth(x: float) -> np.ndarray:
    return np.array([math.sin(3 * x), x**3, math.exp(x)])


def smooth_slope(x: float) -> np.ndarray:
    return np.array([3 * math.cos(3 * x), 3 * x**2, math.exp(x)])


def test_a_smooth_map_is_checked_and_its_exact_slope_passes():
    base, ends = _ends(smooth, 0.7)
    kind, err = sens_fuzz.classify(base, ends, EPS, smooth_slope(0.7))
    assert kind == "checked" and err < 1e-8


def test_a_slope_off_by_one_percent_is_an_error_of_one_percent():
    base, ends = _ends(smooth, 0.7)
    slope = smooth_slope(0.7)
    assert np.argmax(np.abs(slope)) == 2  # the column's scale: the larger of that entry's two values
    kind, err = sens_fuzz.classify(base, ends, EPS, slope * [1.0, 1.0, 1.01])
    assert kind == "checked"
    assert err == pytest.approx(0.01 / 1.01, rel=1e-5)


def test_a_tangent_not_finite_is_an_error():
    base, ends = _ends(smooth, 0.7)
    assert sens_fuzz.classify(base, ends, EPS, smooth_slope(0.7) * [1.0, np.nan, 1.0]) == (
        "checked",
        math.inf,
    )


def test_a_kink_is_not_checked():
    """``|x|`` at 0 (one-sided slopes 1 and -1), and a kink of 1e-3 of the slope beside a smooth part: the
    central difference is the mean of the one-sided ones, which no tangent of one side matches."""

    def kinked(x: float) -> np.ndarray:
        return smooth(x) + np.array([abs(x), 0.0, 1e-3 * abs(x)])

    base, ends = _ends(lambda x: np.array([abs(x), x]), 0.0)
    assert sens_fuzz.classify(base, ends, EPS, np.array([1.0, 1.0]))[0] == "kink"
    base, ends = _ends(kinked, 0.0)
    assert sens_fuzz.classify(base, ends, EPS, smooth_slope(0.0))[0] == "kink"


def test_a_kink_below_the_tolerance_is_checked_with_an_error_below_it():
    def kinked(x: float) -> np.ndarray:
        return smooth(x) + np.array([0.0, 0.0, 1e-6 * abs(x)])

    base, ends = _ends(kinked, 0.0)
    kind, err = sens_fuzz.classify(base, ends, EPS, smooth_slope(0.0))
    assert kind == "checked" and err < sens_fuzz.AGREE


def test_moved_moves_one_column_of_the_start():
    start = ([1.0, 2.0], [3.0, 4.0], {"mu": 0.5, "e": 0.2})
    names = ["q0[x]", "q0[y]", "v0[x]", "v0[y]", "mu", "e"]
    assert sens_fuzz.moved(start, names, 1, 0.5) == ([1.0, 2.5], [3.0, 4.0], {"mu": 0.5, "e": 0.2})
    assert sens_fuzz.moved(start, names, 2, 0.5) == ([1.0, 2.0], [3.5, 4.0], {"mu": 0.5, "e": 0.2})
    assert sens_fuzz.moved(start, names, 5, 0.5) == ([1.0, 2.0], [3.0, 4.0], {"mu": 0.5, "e": 0.7})
    assert start == ([1.0, 2.0], [3.0, 4.0], {"mu": 0.5, "e": 0.2})  # not changed
    assert [sens_fuzz.value(start, names, j) for j in range(6)] == [1.0, 2.0, 3.0, 4.0, 0.5, 0.2]


@pytest.mark.parametrize("backend", ["c", "casadi"])
def test_rough_drops_into_a_groove_match_central_differences(backend):
    """A particle dropped into a rough V (``bench.groove_drops``' draws: impacts with friction, held on one
    wall or both, sliding and sticking): every column's tangent, up to its first break, within 1e-4 of the
    central differences wherever the moved runs keep its mode sequence, and most columns checked."""
    out = sens_fuzz.fuzz("groove", 4 if backend == "c" else 2, 2, backend)
    tally = out["tally"]
    assert out["errors"] == 0
    assert tally["checked"] >= 0.8 * sum(tally.values())
    assert out["worst"] and out["worst"][0][0] < 1e-4


def test_frictionless_drops_into_a_groove_under_lobatto3_match_central_differences():
    """The same draws on the frictionless groove (``mu`` left out) under the fourth-order rule, in C: impacts,
    held steps on one wall or both and lift-offs, every column within 1e-4."""
    out = sens_fuzz.fuzz("groove_smooth", 3, 2, "c", rule="lobatto3")
    assert out["errors"] == 0 and out["through"]["impacts"] > 0 and out["through"]["held"] > 0
    assert out["tally"]["checked"] >= 0.8 * sum(out["tally"].values())
    assert out["worst"][0][0] < 1e-4


def test_a_smooth_variant_leaves_out_the_parameters_its_model_has_not():
    _, draw, onto = sens_fuzz.scene("groove_smooth", "c")
    _, rough, _ = sens_fuzz.scene("groove", "c")
    a, b = draw(np.random.default_rng(3)), rough(np.random.default_rng(3))
    assert a[:2] == b[:2] and "mu" in b[2] and a[2] == {k: v for k, v in b[2].items() if k != "mu"}
    assert onto is None  # no constraints


def test_a_moved_start_of_a_chain_is_taken_onto_its_rods():
    """The double pendulum of ``bench.chains_fuzz`` (two unit rods): a start moved off the rods comes back
    onto them, its velocity tangent to them, and a start on them is kept."""
    _, draw, onto = sens_fuzz.scene("pendulum", "c")
    q0, v0, params = draw(np.random.default_rng(4))
    q, v, _ = onto(([x + 0.01 for x in q0], [x + 0.3 for x in v0], params))
    assert abs(q[0] ** 2 + q[1] ** 2 - 1) < 1e-14 and abs((q[2] - q[0]) ** 2 + (q[3] - q[1]) ** 2 - 1) < 1e-14
    assert abs(q[0] * v[0] + q[1] * v[1]) < 1e-14
    assert abs((q[2] - q[0]) * (v[2] - v[0]) + (q[3] - q[1]) * (v[3] - v[1])) < 1e-14
    q, v, _ = onto((q, v, params))
    assert np.allclose(onto((q, v, params))[0], q, atol=1e-15, rtol=0)


def test_chains_match_central_differences_along_their_rods():
    """Random double pendulums on two rods over a rough floor (``bench.chains_fuzz``' draws): each column's
    path taken onto the rods, ``S dz`` within 1e-4 of the central differences, ``q0`` and ``v0`` columns
    among those checked."""
    sim, draw, onto = sens_fuzz.scene("pendulum", "c")
    rng = np.random.default_rng(1)
    kinds = {}
    for _ in range(3):
        out = sens_fuzz.check_draw(sim, onto(draw(rng)), 0.01, 2.0, onto)
        assert out is not None
        for name, (kind, err) in out["columns"].items():
            kinds.setdefault(kind, []).append(name)
            assert kind != "checked" or err < 1e-4, (name, err)
    assert len(kinds["checked"]) >= 0.8 * sum(len(v) for v in kinds.values())
    assert any(c.startswith("q0") for c in kinds["checked"]) and any(
        c.startswith("v0") for c in kinds["checked"]
    )


def test_the_kink_of_a_hoop_started_rolling_exactly_shrinks_as_h_squared():
    """``bench.hoop_drops``' seed 1, draw 4 starts rolling exactly: moved in ``v0[x]`` either way it slips and
    stops inside the first step, and the one-sided derivatives of ``(q, p)`` at t = 0.02 part by a gap that
    quarters as ``h`` halves (the discrete map's kink, O(h^2)), the tangent (the rolling mode's) within a
    fraction of it of their mean: why ``classify`` leaves kinks unchecked."""
    widths = sens_fuzz.kink_widths("hoop", 1, 4, "v0[x]", 0.02, sens_fuzz.KINK_HS)
    gaps = [gap for _, gap, _ in widths]
    assert gaps[0] > 1e-2  # a kink at h = 0.01, not round-off
    for a, b in zip(gaps, gaps[1:]):
        assert 3.5 < a / b < 4.5
    assert all(off < 0.1 * gap for _, gap, off in widths)


def test_the_backends_tangents_agree_on_rough_groove_drops():
    """``--agree``: C's tangent (the generated loop's) and CasADi's (the Python stepper's) on the same draws,
    the same breaks and the tangents within 1e-10 of each other up to the first."""
    out = sens_fuzz.agree("groove", 3, 2)
    assert out["errors"] == 0 and len(out["rows"]) == 3
    for gap_s, _, k, gap_q, same, _, _ in out["rows"]:
        assert same and k > 10 and gap_s < 1e-10 and gap_q < 1e-10


def test_the_backends_break_at_the_same_step_where_a_box_stops_pinned_at_a_grid_point():
    """A rough box landing its second corner in the V (``box_v`` seed 1, draws 26 and 59) is pinned by its
    three rows and ends the step at rest: its slipping corner's sliding at the segment's end is round-off's
    (6.9e-19 on CasADi), whose sign the stop test read. C located a stop there and broke in that step, CasADi
    met it at the next step's start and broke there; a sliding within ``SLIDE_EPS`` of 0 at the end is a stop
    at the end on both (``SustainedSteps._friction_events``): the same breaks, the tangents alike."""
    out = sens_fuzz.agree("box_v", 60, 1, only=[26, 59])
    assert out["errors"] == 0 and sorted(r[1] for r in out["rows"]) == [26, 59]
    for gap_s, _, k, gap_q, same, ba, bb in out["rows"]:
        assert same, (ba, bb)
        assert k >= 40 and gap_s < 1e-8 and gap_q < 1e-10
