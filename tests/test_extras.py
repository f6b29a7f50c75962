"""The core works without the optional extras, and asking for one names the extra to install.

One subprocess whose ``sys.meta_path`` refuses matplotlib, meshcat, dask and distributed (as an
install without the ``plots``, ``replay`` and ``dask`` extras would) runs the command line: a
run and a sweep on the process pool must work and write their files; figures, a replay and the
Dask engine must each be refused with one error line (exit status 2) naming the extra, before
anything is written; ``compare`` writes its table and says once that it skipped the figures.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow  # one interpreter, a few 20 ms runs: about 10 s

#: The extra that installs each library, as pyproject.toml declares them.
EXTRA_OF = {"matplotlib": "plots", "meshcat": "replay", "dask": "dask"}

_SCRIPT = r"""
import contextlib, importlib.abc, io, json, sys

BLOCKED = ("matplotlib", "meshcat", "dask", "distributed")


class Refuse(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"No module named {name!r} (refused by the test)", name=name)
        return None


sys.meta_path.insert(0, Refuse())

from hybrid_force.cli import main
from hybrid_force.errors import MissingExtraError

scenario, out = sys.argv[1], sys.argv[2]
short = ["--set", "sim.duration=0.02"]
commands = {
    "run": ["run", scenario, *short, "--out", f"{out}/run", "--quiet"],
    "run_plot": ["run", scenario, *short, "--out", f"{out}/run_plot", "--plot", "--quiet"],
    "run_html": ["run", scenario, *short, "--out", f"{out}/run_html", "--html", f"{out}/r.html"],
    "plot": ["plot", f"{out}/run/result.npz", "--out", f"{out}/figures"],
    "replay": ["replay", f"{out}/run/result.npz", "--html", f"{out}/replay.html"],
    "sweep_dask": ["sweep", scenario, "--grid", "sim.duration=0.02", "--out", f"{out}/dask",
                   "--scheduler", "local", "--no-progress"],
    "sweep": ["sweep", scenario, "--grid", "sim.duration=0.02,0.03", "--out", f"{out}/sweep",
              "--workers", "1", "--start-method", "fork", "--no-progress"],
    "compare": ["compare", scenario, "--laws", "arimoto", *short, "--out", f"{out}/compare",
                "--workers", "1", "--start-method", "fork", "--no-progress"],
}
report = {}
for name, argv in commands.items():
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        status = main(argv)
    report[name] = {"status": status, "stderr": err.getvalue()}

# the Python API: the error carries the library and the extra
from hybrid_force.result import Result
from hybrid_force.studies.sweep import run_sweep
from hybrid_force.viz.run_figures import plot_result
from hybrid_force.viz.replay import write_html

result = Result.load(f"{out}/run/result.npz")
calls = {
    "plot_result": lambda: plot_result(result, f"{out}/api_figures"),
    "write_html": lambda: write_html(result, f"{out}/api.html"),
    "run_sweep": lambda: run_sweep(scenario, [{}], scheduler="local", out_dir=f"{out}/api_dask"),
}
for name, call in calls.items():
    try:
        call()
    except MissingExtraError as exc:
        report[name] = {"module": exc.module, "extra": exc.extra, "key": exc.key}
report["loaded"] = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
print(json.dumps(report))
"""


@pytest.fixture(scope="module")
def without_extras(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path]:
    out = tmp_path_factory.mktemp("no_extras")
    done = subprocess.run(
        [sys.executable, "-c", _SCRIPT, str(REPO / "scenarios" / "paper_contact.toml"), str(out)],
        capture_output=True,
        text=True,
        cwd=out,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1]), out


def test_run_and_process_pool_sweep_work_without_the_extras(
    without_extras: tuple[dict, Path],
) -> None:
    report, out = without_extras
    assert report["run"]["status"] == 0, report["run"]["stderr"]
    assert (out / "run" / "result.npz").is_file() and (out / "run" / "summary.json").is_file()
    summary = json.loads((out / "run" / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["n_samples"] == round(0.02 / 0.001) + 1
    assert report["sweep"]["status"] == 0, report["sweep"]["stderr"]
    with (out / "sweep" / "sweep.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["status"], float(r["t_end"])) for r in rows] == [("ok", 0.02), ("ok", 0.03)]
    assert report["loaded"] == []  # nothing of the extras slipped in past the refusal


@pytest.mark.parametrize(
    ("command", "library", "not_written"),
    [
        ("run_plot", "matplotlib", "run_plot"),
        ("run_html", "meshcat", "run_html"),
        ("plot", "matplotlib", "figures"),
        ("replay", "meshcat", "replay.html"),
        ("sweep_dask", "dask", "dask"),
    ],
)
def test_asking_for_an_extra_is_one_error_line_naming_it(
    without_extras: tuple[dict, Path], command: str, library: str, not_written: str
) -> None:
    report, out = without_extras
    status, stderr = report[command]["status"], report[command]["stderr"]
    assert status == 2, stderr
    lines = stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    extra = EXTRA_OF[library]
    assert library in lines[0] and f'pip install "hybrid_force[{extra}]"' in lines[0]
    assert not (out / not_written).exists()  # refused before anything was written


def test_compare_writes_its_table_and_says_once_the_figures_were_skipped(
    without_extras: tuple[dict, Path],
) -> None:
    report, out = without_extras
    assert report["compare"]["status"] == 0, report["compare"]["stderr"]
    assert (out / "compare" / "compare.csv").is_file()
    assert not list((out / "compare").glob("*.png"))
    notes = [line for line in report["compare"]["stderr"].splitlines() if "figures" in line]
    assert len(notes) == 1 and "hybrid_force[plots]" in notes[0]


def test_the_python_api_raises_missing_extra_error_with_library_and_extra(
    without_extras: tuple[dict, Path],
) -> None:
    report, out = without_extras
    expected = {"plot_result": "matplotlib", "write_html": "meshcat", "run_sweep": "dask"}
    for call, library in expected.items():
        assert report[call] == {"module": library, "extra": EXTRA_OF[library], "key": "extra"}
    assert not (out / "api_figures").exists() and not (out / "api_dask").exists()
