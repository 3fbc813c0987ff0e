"""The benchmark sweep (bench/run.py) on a tiny configuration: files, columns, one ranking."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench import run  # noqa: E402


def test_tiny_sweep_writes_csv_and_ranks_vcigen_above_naive_verlet(tmp_path: Path) -> None:
    argv = [
        "--scenes",
        "star_nonlinear",
        "--methods",
        "vcigen_casadi_trapezoid,verlet_full_flip",
        "--hs",
        "0.01,0.005",
        "--phases",
        "2",
        "--no-long",
        "--out",
        str(tmp_path),
    ]
    assert run.main(argv) == 0
    with (tmp_path / "star_nonlinear.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0].keys()) == run.CSV_COLUMNS
    assert [(r["method"], float(r["h_or_tol"])) for r in rows] == [
        ("vcigen_casadi_trapezoid", 0.01),
        ("vcigen_casadi_trapezoid", 0.005),
        ("verlet_full_flip", 0.01),
        ("verlet_full_flip", 0.005),
    ]
    err = {(r["method"], float(r["h_or_tol"])): float(r["err_first"]) for r in rows}
    for h in (0.01, 0.005):
        assert err[("vcigen_casadi_trapezoid", h)] < err[("verlet_full_flip", h)]
    for r in rows:
        assert float(r["wall_s"]) > 0
        assert r["phases"] == "2"
    vc = [r for r in rows if r["method"].startswith("vcigen")]
    assert all(float(r["max_violation"]) <= 1e-9 and float(r["missed"]) == 0 for r in vc)
    summary = (tmp_path / "summary.md").read_text()
    assert "Machine: nproc" in summary and "star_nonlinear" in summary
    assert (tmp_path / "wp_star_nonlinear.png").stat().st_size > 0


def test_impact_matching_and_wall_interpolation() -> None:
    assert run.match_impacts([1.0, 2.0], [1.01, 1.5, 2.02]) == (0, 1)
    assert run.match_impacts([1.0, 1.009], [1.0]) == (1, 0)
    rows = [
        run.Row("s", "m", h, 1, wall=w, err_first=e)
        for h, w, e in ((0.01, 1.0, 1e-2), (0.005, 2.0, 1e-3), (0.0025, 4.0, 1e-4))
    ]
    w, flag = run.wall_at(rows, 1e-4)
    assert flag == "" and abs(w - 4.0) < 1e-9
    w, flag = run.wall_at(rows, 1e-5)
    assert flag == "~" and abs(w - 8.0) < 1e-9
    assert abs(run.order_of(rows) - run.order_of(rows[:2])) < 1e-9
    # a flat curve (naive Verlet on a loaded machine: error 1.24e-1 -> 1.239e-1 for twice the time) is not
    # reached, not an OverflowError
    pts = ((0.01, 1.0, 0.124), (0.005, 2.0, 0.1239))
    flat = [run.Row("s", "m", h, 1, wall=w, err_first=e) for h, w, e in pts]
    w, flag = run.wall_at(flat, 1e-4)
    assert flag == "not reached" and w != w


def test_update_readme_copies_the_headline_between_markers(tmp_path):
    from bench.run import README_END, README_START, update_readme

    summary = tmp_path / "summary.md"
    summary.write_text(
        "Machine: test box\n\n## star\n\nWall time at matched accuracy x2\n\n"
        "## Long runs: energy\n\n| a |\n|---|\n| 1 |\n\n![energy](e.png)\n"
    )
    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{README_START}\nold\n{README_END}\noutro\n")
    assert update_readme(summary, readme)
    text = readme.read_text()
    assert "old" not in text and text.startswith("intro\n") and text.endswith("outro\n")
    assert "- **star**: Wall time at matched accuracy x2" in text and "| 1 |" in text
    assert "Machine: test box" in text and "e.png" not in text
    readme.write_text("no markers")
    assert not update_readme(summary, readme)


def test_fine_steps_only_for_compiled_vcigen_and_two_accuracies_in_the_summary(tmp_path: Path) -> None:
    setup = run.SETUPS["star_nonlinear"]
    assert setup.hs_for("vcigen_casadi_trapezoid") == setup.hs == setup.hs_for("verlet_full_flip")
    fine = setup.hs_for("vcigen_c_trapezoid")
    assert fine[: len(setup.hs)] == setup.hs and min(fine) < min(setup.hs) / 100
    argv = ["--scenes", "particle", "--methods", "vcigen_casadi_trapezoid", "--hs", "0.01,0.001"]
    argv += ["--phases", "1", "--no-long", "--targets", "1e-3,1e-9", "--out", str(tmp_path)]
    assert run.main(argv) == 0
    summary = (tmp_path / "summary.md").read_text()
    assert "| wall @ 0.001 | wall @ 1e-09 |" in summary
    assert "matched accuracy (0.001 at" in summary and "matched accuracy (1e-09 at" in summary


def test_lobatto3_in_the_sweep_to_1e10_and_in_the_long_and_drift_runs(tmp_path: Path) -> None:
    """Issue 12 item 5: lobatto3 runs in the long runs (energy and drift) beside trapezoid, and its own h
    sweep goes fine enough on every scene for errors of 1e-10 (order 4 from its coarsest step)."""
    import vcigen
    from bench.long_runs import DRIFT_METHODS

    assert "vcigen_c_lobatto3" in DRIFT_METHODS
    for name, setup in run.SETUPS.items():
        hs = setup.hs_for("vcigen_c_lobatto3")
        assert hs == setup.high_order_hs, name
        assert vcigen.RULES["lobatto3"].order == 4
        # measured (bench/run.py --methods vcigen_c_lobatto3): 4.8e-12 on star_nonlinear at 0.1/128, 6.1e-10
        # on pendulum_wall at 0.1/128, hence one halving more there
        assert min(hs) <= (0.1 / 256 if name == "pendulum_wall" else 0.1 / 128), name
    argv = ["--scenes", "particle", "--methods", "vcigen_c_trapezoid,vcigen_c_lobatto3", "--hs", "0.01"]
    argv += ["--phases", "1", "--long-steps", "3000", "--drift-steps", "4000", "--out", str(tmp_path)]
    assert run.main(argv) == 0
    with (tmp_path / "longrun.csv").open() as fh:
        rows = [r for r in csv.DictReader(fh) if r["method"] == "vcigen_c_lobatto3"]
    assert [int(r["steps"]) for r in rows] == [2999, 3999]  # the energy run, then the drift run
    for r in rows:
        assert int(r["impacts"]) > 0 and r["note"] == ""
        # linear gravity: lobatto3's E_d is kept to round-off, through every impact
        assert float(r["energy_dev"]) < 1e-12
    summary = (tmp_path / "summary.md").read_text()
    assert "| particle | vcigen C, lobatto3 (order 4) | 0.01 | 2999 |" in summary
