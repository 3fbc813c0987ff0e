"""The wheel: it carries the templates, and an installed copy builds and runs the C backend on its own."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

RUN = """
import sys, vcigen
from vcigen.backends import c
assert vcigen.__file__.startswith(sys.argv[1]), vcigen.__file__
assert str(c.template_dir()).startswith(sys.argv[1]), c.template_dir()
import sympy as sp
x, y, xd, yd = sp.symbols("x y xd yd")
model = vcigen.Model(name="particle", q=[x, y], qdot=[xd, yd], lagrangian=(xd**2 + yd**2) / 2 - 9.81 * y,
                     contacts={"floor": y})
res = vcigen.build(model, backend="c").simulate([0.0, 1.0], [-2.0, 0.0], 0.01, n_impacts=10)
print(res.n_impacts, res.max_energy_deviation())
"""


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_installed_wheel_carries_the_templates_and_runs_c(tmp_path: Path) -> None:
    wheels = tmp_path / "wheels"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(wheels)],
        check=True,
        capture_output=True,
    )
    (wheel,) = wheels.glob("vcigen-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    templates = {f"vcigen/templates/{p.name}" for p in (ROOT / "templates").glob("*.j2")}
    assert templates and templates <= names, templates - names
    assert {"vcigen/explicit.py", "vcigen/backends/cwrap.py"} <= names
    site = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(site), str(wheel)],
        check=True,
        capture_output=True,
    )
    env = dict(os.environ, PYTHONPATH=str(site), VCIGEN_CACHE=str(tmp_path / "cache"))
    run = subprocess.run(
        [sys.executable, "-c", RUN, str(site)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    impacts, deviation = run.stdout.split()
    assert int(impacts) == 10 and float(deviation) < 1e-3
