"""The package surface: every public name resolves, and importing it stays light."""

from __future__ import annotations

import subprocess
import sys

import hybrid_force


def test_every_public_name_resolves() -> None:
    for name in hybrid_force.__all__:
        assert getattr(hybrid_force, name) is not None, name
    assert set(hybrid_force.__all__) <= set(dir(hybrid_force))


def test_import_does_not_load_plotting_viewer_or_cluster_libraries() -> None:
    code = (
        "import sys, hybrid_force; "
        "print(','.join(m for m in ('matplotlib', 'meshcat', 'dask', 'distributed', 'zmq', "
        "'playwright', 'hybrid_force.viz.plots', 'hybrid_force.viz.replay', "
        "'hybrid_force.studies.sweep') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_module_paths_of_before_the_layers_still_import_the_same_modules() -> None:
    # A fresh interpreter: the old names must work whatever was imported before.
    code = (
        "import importlib, sys\n"
        "from hybrid_force._compat import MOVED\n"
        "import hybrid_force\n"
        "for old, new in MOVED.items():\n"
        "    assert importlib.import_module(old) is importlib.import_module(new), old\n"
        "from hybrid_force.simulate import Scenario, SimSettings\n"
        "from hybrid_force.control import Gains, arimoto_law\n"
        "from hybrid_force.scenario import load_scenario\n"
        "assert callable(hybrid_force.simulate) and hybrid_force.simulate.__name__ == 'simulate'\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_version_has_one_source_the_project_metadata() -> None:
    import tomllib
    from pathlib import Path

    import hybrid_force

    pyproject = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    assert hybrid_force.__version__ == pyproject["project"]["version"]
