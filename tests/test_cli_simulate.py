"""``vcigen simulate FILE``: its files hold the run ``simulate`` gives; bad input exits 1 with a message."""

from __future__ import annotations

import csv
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import vcigen
from vcigen.cli import main

ROOT = Path(__file__).resolve().parents[1]
PARTICLE = str(ROOT / "examples" / "particle.py")


def read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open() as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def read_trajectory(path: Path) -> tuple[list[str], np.ndarray]:
    header, rows = read_csv(path)
    return header, np.array(rows, dtype=float)


@pytest.fixture(scope="module")
def particle_sim():
    from scenes import load_example

    return vcigen.build(load_example("particle").model(), backend="c")


def test_simulate_writes_the_run_and_prints_the_summary(tmp_path, capsys, particle_sim):
    argv = ["simulate", PARTICLE, "--h", "0.005", "--t-end", "2.5", "--out", str(tmp_path)]
    argv += ["--v0", "-1", "0.5", "--param", "g=3.7"]
    assert main(argv) == 0
    want = particle_sim.simulate(q0=[0.0, 1.0], v0=[-1.0, 0.5], h=0.005, t_end=2.5, params={"g": 3.7})
    header, data = read_trajectory(tmp_path / "particle_c_trapezoid.csv")
    assert header == ["t", "x", "y", "p_x", "p_y", "energy"]
    np.testing.assert_array_equal(data[:, 0], want.t)
    np.testing.assert_array_equal(data[:, 1:3], want.q)
    np.testing.assert_array_equal(data[:-1, 5], want.energy)
    _, impacts = read_csv(tmp_path / "particle_c_trapezoid_impacts.csv")
    assert [float(r[0]) for r in impacts] == [im.t for im in want.impacts]
    assert (tmp_path / "particle_c_trapezoid_energy.png").stat().st_size > 1000
    out = capsys.readouterr().out
    assert f"particle [c, trapezoid]: {want.n_impacts} impacts, {want.t.size - 1} steps" in out
    assert "particle_c_trapezoid_energy.png" in out


def test_simulate_takes_setup_from_the_file_and_the_rule_and_backend_from_the_line(tmp_path, capsys):
    assert (
        main(
            [
                "simulate",
                PARTICLE,
                "--n-impacts",
                "2",
                "--backend",
                "casadi",
                "--rule",
                "midpoint",
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    _, impacts = read_csv(tmp_path / "particle_casadi_midpoint_impacts.csv")
    assert len(impacts) == 2
    _, data = read_trajectory(tmp_path / "particle_casadi_midpoint.csv")
    np.testing.assert_array_equal(data[0, 1:3], [0.0, 1.0])  # SETUP's q0
    assert np.isclose(data[1, 0] - data[0, 0], 0.01)  # SETUP's h
    assert "particle [casadi, midpoint]: 2 impacts" in capsys.readouterr().out


NO_MODEL = "import math\n"
NO_SETUP = (ROOT / "examples" / "particle.py").read_text().replace("SETUP = {", "_UNUSED = {")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["simulate", "no_such_file.py"], "no such example file: no_such_file.py"),
        (["simulate", "{no_model}"], "does not define model()"),
        (["simulate", "{broken}"], "cannot import .*ZeroDivisionError"),
        (["simulate", "{no_setup}", "--t-end", "1"], "no q0, v0, h: the file has no SETUP giving them"),
        (["simulate", PARTICLE, "--q0", "0", "-1"], "q0 violates contact 'floor'"),
        (["simulate", PARTICLE, "--h", "-0.1"], "h = -0.1 must be > 0"),
        (["simulate", PARTICLE, "--q0", "1", "2", "3"], "q0 has 3 entries but the model has 2"),
        (["simulate", PARTICLE, "--param", "zz=1"], "unknown parameter 'zz'"),
        (["simulate", PARTICLE, "--t-end", "1", "--param", "g=1e308"], "step 0 .* solve failed"),
    ],
)
def test_bad_input_exits_1_with_a_message(tmp_path, capsys, argv, message):
    files = {"no_model": NO_MODEL, "broken": "x = 1 / 0\n", "no_setup": NO_SETUP}
    for key, text in files.items():
        (tmp_path / f"{key}.py").write_text(text)
    argv = [a.format(**{k: str(tmp_path / f"{k}.py") for k in files}) for a in argv]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("bad", [["--h", "abc"], ["--param", "g"], ["--rule", "euler"]])
def test_bad_arguments_exit_1_with_the_usage(capsys, bad):
    with pytest.raises(SystemExit) as info:
        main(["simulate", PARTICLE, *bad])
    assert info.value.code == 1
    assert "usage: vcigen simulate" in capsys.readouterr().err


def test_the_console_exit_status_is_1_on_bad_input(tmp_path):
    cmd = [sys.executable, "-c", "from vcigen.cli import main; raise SystemExit(main())", "simulate"]
    proc = subprocess.run([*cmd, "missing.py"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "no such example file: missing.py" in proc.stderr
    proc = subprocess.run([*cmd, "--help"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0
    for option in (
        "--h",
        "--t-end",
        "--n-impacts",
        "--q0",
        "--v0",
        "--param",
        "--backend",
        "--rule",
        "--out",
    ):
        assert option in proc.stdout
