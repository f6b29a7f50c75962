"""hybrid_force.studies.progress: the progress line and its estimate of the time left; the sweep
command draws it on stderr only, and only on a terminal unless asked."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from hybrid_force.studies.progress import ProgressReporter, format_duration, progress_enabled


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_time_left_is_the_mean_interval_since_the_first_item_times_what_is_left() -> None:
    clock = _Clock()
    stream = _Terminal()
    report = ProgressReporter(10, done=2, stream=stream, clock=clock, min_interval=0.0)
    assert report.remaining_time() is None  # no item of this session yet
    clock.now += 7.0  # start-up: not spread over the items
    report.advance()
    assert report.remaining_time() is None  # one item gives no interval
    for dt in (1.0, 2.0, 3.0):
        clock.now += dt
        report.advance(ok=dt != 2.0)
    # 4 new items, 3 intervals over 6 s: 2 s each; 10 - 6 = 4 left
    assert report.remaining_time() == pytest.approx(8.0)
    line = report.line()
    assert "6/10" in line and " 60%" in line and "left 00:08" in line and "not ok: 1" in line
    assert "elapsed 00:13" in line
    for _ in range(4):
        clock.now += 1.0
        report.advance()
    assert report.remaining_time() == 0.0 and "left done" in report.line()
    report.close()
    text = stream.getvalue()
    assert text.startswith("\r") and text.endswith("\n") and text.count("\n") == 1


def test_redraws_are_throttled_but_the_last_item_always_draws() -> None:
    clock = _Clock()
    stream = _Terminal()
    report = ProgressReporter(3, stream=stream, clock=clock, min_interval=1.0)
    report.draw()
    for _ in range(2):
        clock.now += 0.1
        report.advance()
    assert stream.getvalue().count("\r") == 1  # both within 1 s of the first draw
    clock.now += 0.1
    report.advance()  # the last one
    assert stream.getvalue().count("\r") == 2 and "3/3" in stream.getvalue()


def test_drawn_only_on_a_terminal_unless_forced() -> None:
    plain = io.StringIO()
    assert not progress_enabled(True, plain) and progress_enabled("force", plain)
    assert progress_enabled(True, _Terminal()) and not progress_enabled(False, _Terminal())
    with ProgressReporter(2, stream=plain) as report:
        report.advance()
        report.advance()
    assert plain.getvalue() == ""
    forced = io.StringIO()
    with ProgressReporter(1, stream=forced, progress="force", label="sweep") as report:
        report.advance()
    assert forced.getvalue().startswith("\rsweep [") and forced.getvalue().endswith("\n")


@pytest.mark.parametrize(
    ("seconds", "text"), [(0, "00:00"), (59.4, "00:59"), (61, "01:01"), (3725, "1:02:05")]
)
def test_format_duration(seconds: float, text: str) -> None:
    assert format_duration(seconds) == text


def test_sweep_command_draws_progress_on_stderr_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from hybrid_force.cli import main

    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "paper_contact.toml"
    common = ["sweep", str(scenario), "--grid", "control.Lambda=2,3", "--grid", "sim.duration=0.05"]
    common += ["--workers", "1"]
    assert main([*common, "--out", str(tmp_path / "a"), "--progress"]) == 0
    forced = capsys.readouterr()
    assert "\rsweep [" in forced.err and "2/2 100%" in forced.err and "left done" in forced.err
    assert "\r" not in forced.out and "sweep: 2 runs (2 ok)" in forced.out
    assert (
        main([*common, "--out", str(tmp_path / "b"), "--no-progress", "--start-method", "spawn"])
        == 0
    )
    quiet = capsys.readouterr()
    assert "\r" not in quiet.err
    # stdout is the same machine-readable summary either way (but for its wall time)
    assert [line for line in forced.out.splitlines() if "new in" not in line] == [
        line.replace(str(tmp_path / "b"), str(tmp_path / "a"))
        for line in quiet.out.splitlines()
        if "new in" not in line
    ]
