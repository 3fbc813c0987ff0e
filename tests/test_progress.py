"""The progress bar (``vcigen.progress``): silent for short work, a bar with an ETA for long work."""

from __future__ import annotations

import io
import time
from functools import partial

import pytest
from hard_scenes import simulator

import vcigen.backends.cwrap
import vcigen.simulator
from vcigen.progress import Progress, format_seconds


class Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def spin(bar: Progress, seconds: float, total: float = 1.0) -> None:
    """Report progress in proportion to the time spent, for ``seconds``."""
    start = time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        bar.update(total * elapsed / seconds)
        time.sleep(0.005)
    bar.update(total)


def test_silent_when_projected_under_min_seconds() -> None:
    out = io.StringIO()
    with Progress(1.0, "short", stream=out, min_seconds=2.0) as bar:
        spin(bar, 0.4)
    assert out.getvalue() == ""


def test_disabled_is_silent_however_long() -> None:
    out = io.StringIO()
    with Progress(1.0, "off", stream=out, enabled=False, min_seconds=0.0) as bar:
        spin(bar, 0.3)
    assert out.getvalue() == ""


def test_long_work_on_a_terminal_redraws_one_line_with_eta() -> None:
    """Projected over min_seconds: redrawn in place (\\r), at most ~5 times a second, ending at 100%."""
    out = Tty()
    with Progress(1.0, "long", stream=out, min_seconds=0.3) as bar:
        spin(bar, 0.9)
    text = out.getvalue()
    draws = text.count("\r")
    assert 1 <= draws <= 0.9 / 0.2 + 2
    assert "ETA" in text and "100.0%" in text.rsplit("\r", 1)[1]
    assert text.endswith("\n") and text.count("\n") == 1 and "long: [" in text


def test_long_work_on_a_log_writes_a_few_plain_lines() -> None:
    out = io.StringIO()
    with Progress(10.0, "log", stream=out, min_seconds=0.3) as bar:
        spin(bar, 1.2, total=10.0)
    lines = out.getvalue().splitlines()
    assert 2 <= len(lines) <= 5 and "\r" not in out.getvalue()
    assert lines[-1].startswith("log: [########################] 100.0%")


@pytest.mark.parametrize(
    ("s", "text"), [(4.21, "4.2s"), (185, "3m05s"), (3720, "1h02m"), (float("inf"), "?")]
)
def test_format_seconds(s: float, text: str) -> None:
    assert format_seconds(s) == text


def test_simulate_shows_progress_only_when_long_and_asked(monkeypatch, capsys) -> None:
    """A 0.01 s run prints nothing by default (no per-chunk lines); a run longer than the threshold
    (lowered to 0 here: any run) shows the bar on stderr, and not with progress=False."""
    sim = simulator("ball", "casadi")
    sim.simulate([0.0, 1.0], [0.0, 0.0], 0.01, t_end=0.05)
    assert capsys.readouterr() == ("", "")
    for module in (vcigen.simulator, vcigen.backends.cwrap):  # simulate; the C backend's simulate_many
        monkeypatch.setattr(module, "Progress", partial(Progress, min_seconds=0.0))
    sim.simulate([0.0, 1.0], [0.0, 0.0], 0.005, t_end=5.0, params={"e": 1.0})
    err = capsys.readouterr().err
    assert "simulate ball: [" in err and "100.0%" in err
    sim.simulate([0.0, 1.0], [0.0, 0.0], 0.005, t_end=5.0, params={"e": 1.0}, progress=False)
    assert capsys.readouterr() == ("", "")
    csim = simulator("ball", "c")  # the C loop reports between its calls
    csim.simulate([0.0, 1.0], [0.0, 0.0], 0.005, t_end=5.0, params={"e": 1.0})
    assert "100.0%" in capsys.readouterr().err
    csim.simulate_many([[0.0, 1.0]] * 3, [[0.0, 0.0]] * 3, 0.005, t_end=5.0)
    assert "simulate_many ball: [" in capsys.readouterr().err
    csim.simulate_many([[0.0, 1.0]] * 3, [[0.0, 0.0]] * 3, 0.005, t_end=5.0, progress=False)
    assert capsys.readouterr() == ("", "")
