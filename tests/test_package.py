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
        "'playwright', 'hybrid_force.plots', 'hybrid_force.replay', 'hybrid_force.sweep') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
