"""The package surface: every public name resolves, and importing it stays light."""

from __future__ import annotations

import ast
import importlib
import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest

import hybrid_force

REPO = Path(__file__).resolve().parents[1]


def test_every_public_name_resolves() -> None:
    for name in hybrid_force.__all__:
        assert getattr(hybrid_force, name) is not None, name
    assert set(hybrid_force.__all__) <= set(dir(hybrid_force))


def test_import_does_not_load_plotting_viewer_or_cluster_libraries() -> None:
    # nor Numba (the kernels load on first use), SciPy, or the package metadata (__version__)
    code = (
        "import sys, hybrid_force; "
        "print(','.join(m for m in ('matplotlib', 'meshcat', 'dask', 'distributed', 'zmq', "
        "'playwright', 'hybrid_force.viz.plots', 'hybrid_force.viz.replay', "
        "'hybrid_force.studies.sweep', 'numba', 'scipy', 'importlib.metadata') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_a_command_loads_numba_without_scipy_and_runs_the_same(tmp_path) -> None:
    # A command compiles only the kernels, so Numba's check for SciPy's BLAS (importing
    # scipy.linalg), its import of CFFI (and pycparser) and its look for extensions in every
    # package's entry points are skipped there (hybrid_force._jit.own_kernels_only); the run
    # is the same as in a process that imports hybrid_force and keeps Numba's defaults.
    import importlib.util

    import numpy as np

    from hybrid_force.result import load_result
    from hybrid_force.scenario.loader import load_scenario
    from hybrid_force.sim.loop import simulate

    has_cffi = importlib.util.find_spec("cffi") is not None  # optional: not every env has it
    scenario = Path(__file__).parents[1] / "scenarios" / "paper_contact.toml"
    code = (
        "import sys, importlib.metadata as md\n"
        "scans, entry_points = [], md.entry_points\n"  # Numba's look for its extensions
        "md.entry_points = lambda *a, **k: scans.append(a) or entry_points(*a, **k)\n"
        "from hybrid_force import cli\n"
        f"status = cli.main(['run', {str(scenario)!r}, '--set', 'sim.duration=0.05', "
        f"'--out', {str(tmp_path)!r}, '--quiet'])\n"
        "import numba.np.arraymath as am\n"
        "print(status, 'scipy.linalg' in sys.modules, am._HAVE_BLAS)\n"
        "print(len(scans))\n"
        "import numba.core.typing.cffi_utils as cu\n"
        "print('cffi' in sys.modules, 'pycparser' in sys.modules, cu.SUPPORTED)\n"
        "import scipy.linalg.cython_blas\n"  # still importable: the mark was taken off
        + ("import cffi\n" if has_cffi else "")  # likewise (when installed at all)
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["0", "False", "False", "0", "False", "False", "False"]
    # a Python program keeps Numba's defaults (SciPy's BLAS found, CFFI supported)
    code = (
        "import hybrid_force.sim._kernels, numba.np.arraymath as am\n"
        "import numba.core.typing.cffi_utils as cu\n"
        "print(am._HAVE_BLAS, cu.SUPPORTED)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.split() == ["True", str(has_cffi)], out.stderr
    there = load_result(tmp_path / "result.npz")
    here = simulate(load_scenario(scenario, {"sim.duration": 0.05}))
    for name in ("t", "q", "v", "u", "f"):
        assert np.array_equal(getattr(there, name), getattr(here, name)), name


def test_a_command_loads_cached_kernels_without_numbas_lowering(tmp_path: Path) -> None:
    # Under own_kernels_only a kernel found in Numba's cache is loaded without the lowering
    # registries (numba.cpython.listobj is one of their modules), and a kernel not in the
    # cache still compiles (Numba's own load: refresh, then compile): the same answer,
    # 3·2 + 1 = 7, both times.
    import os

    (tmp_path / "tiny_kernel.py").write_text(
        "from hybrid_force._jit import jit\n\n\n@jit\ndef f(x, y):\n    return x * y + 1.0\n"
    )
    code = (
        f"import sys\nsys.path.insert(0, {str(tmp_path)!r})\n"
        "from hybrid_force._jit import own_kernels_only\n"
        "with own_kernels_only():\n"
        "    import tiny_kernel\n"
        "    print(tiny_kernel.f(3.0, 2.0))\n"
        "print('numba.cpython.listobj' in sys.modules)\n"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    runs = [
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
        for _ in range(2)
    ]
    for run in runs:
        assert run.returncode == 0, run.stderr
    assert runs[0].stdout.split() == ["7.0", "True"]  # compiled: Numba's registries loaded
    assert runs[1].stdout.split() == ["7.0", "False"]  # loaded from the cache without them


#: A plain ``hybrid-force run`` of an analytic scenario with a bundled URDF arm imports none
#: of these: numpy.ma (Numba's typeof asked for it, hybrid_force._jit), the figures', replay's
#: and sweeps' libraries (matplotlib, meshcat, dask), the mesh parts' (trimesh, igl), the other
#: model readers' (yourdfpy, xacro, mujoco), SciPy's linear algebra and CFFI (hybrid_force._jit).
NOT_IMPORTED_BY_A_RUN = (
    "numpy.ma", "matplotlib", "meshcat", "dask", "trimesh", "igl", "yourdfpy", "xacro",
    "mujoco", "scipy.linalg", "cffi", "pycparser",
)  # fmt: skip


@pytest.fixture(scope="module")
def plain_run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """What a command's process imported and looked up: ``hybrid-force run`` (its console
    script's ``main``) of scenarios/paper_contact.toml for 0.01 s, each ``importlib.metadata``
    look-up of a distribution recorded; with its output folder."""
    out = tmp_path_factory.mktemp("plain_run")
    code = (
        "import json, sys, importlib.metadata as md\n"
        "looked = []\n"
        "def recorded(real):\n"
        "    return lambda name, *a, **k: looked.append(name) or real(name, *a, **k)\n"
        "md.version, md.distribution = recorded(md.version), recorded(md.distribution)\n"
        "from hybrid_force.cli import main\n"
        f"status = main(['run', {str(REPO / 'scenarios' / 'paper_contact.toml')!r}, "
        f"'--set', 'sim.duration=0.01', '--out', {str(out)!r}, '--quiet'])\n"
        "print(json.dumps({'status': status, 'modules': sorted(sys.modules), "
        "'looked_up': looked}))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    report: dict[str, Any] = json.loads(done.stdout.splitlines()[-1])
    report["out"] = out
    return report


@pytest.mark.parametrize("module", NOT_IMPORTED_BY_A_RUN)
def test_a_plain_run_does_not_import(plain_run: dict[str, Any], module: str) -> None:
    assert plain_run["status"] == 0
    assert "numba" in plain_run["modules"]  # the kernels did load: the run is a real one
    assert [m for m in plain_run["modules"] if m == module or m.startswith(module + ".")] == []


def test_a_plain_run_reads_its_version_without_importlib_metadata(
    plain_run: dict[str, Any],
) -> None:
    # the result's versions come from hybrid_force/_version.py (the test of its one source);
    # the installed metadata says the same (importlib.metadata, read here, in this process)
    import importlib.metadata

    from hybrid_force.result import load_result

    assert "hybrid_force" not in plain_run["looked_up"]
    versions = load_result(plain_run["out"] / "result.npz").meta["versions"]
    assert versions["hybrid_force"] == importlib.metadata.version("hybrid_force")


def test_a_commands_typeof_of_plain_arrays_is_numbas() -> None:
    # Under own_kernels_only a plain np.ndarray is typed without numpy.ma (hybrid_force._jit);
    # its Numba type is the one Numba's own ndarray typeof gives (dtype, dimensions, layout,
    # read-only), and every other array (a subclass, a masked array, an unsupported dtype)
    # still goes to Numba's: the same type or the same error.
    code = """
import sys
import numpy as np
from hybrid_force import _jit
with _jit.own_kernels_only():
    _jit.jit(_jit._no_op)  # Numba set up as in a command
import numba
from numba.core.typing import typeof as nt
base = np.arange(24.0).reshape(4, 6)
frozen = np.ones(3)
frozen.flags.writeable = False
plain = [base, base.T, base[:, ::2], np.ones(()), frozen, np.zeros(5), np.zeros((2, 3), np.int32),
         np.zeros(5, np.complex128), np.zeros(4, bool), np.zeros((2, 2, 2), np.float32, order="F")]
ours = [numba.typeof(a) for a in plain]
print("numpy.ma" in sys.modules)
context = nt._TypeofContext(nt.Purpose.argument)
print(all(t == nt._typeof_ndarray(a, context) for t, a in zip(ours, plain)))
print(len(set(ours)))
class Sub(np.ndarray):
    pass
others = [base.view(Sub), np.ma.masked_array([1.0, 2.0]), np.zeros(2, dtype="V8")]
for a in others:
    try:
        mine = repr(numba.typeof(a))
    except Exception as exc:
        mine = type(exc).__name__ + " " + str(exc)
    try:
        theirs = repr(nt._typeof_ndarray(a, context))
    except Exception as exc:
        theirs = type(exc).__name__ + " " + str(exc)
    print(mine == theirs, mine.split()[0])
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[:2] == ["False", "True"]
    assert int(lines[2]) == 10  # ten different types: every case above is a distinct one
    assert [line.split()[0] for line in lines[3:]] == ["True", "True", "True"]
    assert [line.split()[1] for line in lines[3:]] == [
        "Array(float64,",  # the subclass: typed as an array by Numba (repr)
        "NumbaTypeError",  # the masked array: refused by Numba
        "NumbaValueError",  # a dtype Numba has no type for
    ]


def test_module_paths_of_before_the_layers_are_gone() -> None:
    # no alias of a 0.1 module path (hybrid_force.robot, hybrid_force.simulate, ...) is kept
    code = (
        "import importlib, hybrid_force\n"
        "for old in ('robot', 'simulate', 'sweep', 'replay', 'plots', 'supervisor', '_compat'):\n"
        "    try:\n"
        "        importlib.import_module('hybrid_force.' + old)\n"
        "    except ModuleNotFoundError:\n"
        "        continue\n"
        "    raise SystemExit(old)\n"
        "assert callable(hybrid_force.simulate) and hybrid_force.simulate.__name__ == 'simulate'\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr + out.stdout
    assert out.stdout.strip() == "ok"


def test_version_has_one_source_which_the_installed_metadata_reads() -> None:
    # written in hybrid_force/_version.py alone: pyproject.toml declares the version dynamic
    # and hatchling reads that file, so the installed metadata (importlib.metadata) says the
    # same as hybrid_force.__version__, which a command reads without importlib.metadata
    import importlib.metadata

    from hybrid_force import _version

    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert "version" not in pyproject["project"] and "version" in pyproject["project"]["dynamic"]
    assert pyproject["tool"]["hatch"]["version"]["path"] == "hybrid_force/_version.py"
    assert re.fullmatch(r"\d+\.\d+\.\d+", _version.VERSION)
    assert hybrid_force.__version__ == _version.VERSION
    assert importlib.metadata.version("hybrid_force") == _version.VERSION


def _defined_names(tree: ast.Module) -> set[str]:
    """The names a module's own statements bind at module level (not its imports)."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
    return names


def test_every_name_has_one_home() -> None:
    """A module's ``__all__`` lists only what it defines; ``hybrid_force.__all__`` (at most 50
    names) lists names defined elsewhere, each read from the module that defines it."""
    package = Path(hybrid_force.__file__).parent
    for path in sorted(package.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        exported = [
            ast.literal_eval(node.value)
            for node in tree.body
            if isinstance(node, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets)
        ]
        if path == package / "__init__.py" or not exported:
            continue
        foreign = sorted(set(exported[0]) - _defined_names(tree))
        assert not foreign, f"{path.relative_to(package)} re-exports {foreign}"
    assert len(hybrid_force.__all__) <= 50
    for name in hybrid_force.__all__:
        value = getattr(hybrid_force, name)
        home = getattr(value, "__module__", None)
        if name != "__version__" and home is not None:
            module = importlib.import_module(home)
            assert name in _defined_names(ast.parse(Path(str(module.__file__)).read_text()))
    for name in ("sim", "control", "scenario", "viz"):  # the packages hold no names
        module = importlib.import_module(f"hybrid_force.{name}")
        assert not hasattr(module, "__all__"), name


def _project() -> dict:
    return tomllib.loads((REPO / "pyproject.toml").read_text())["project"]


def test_citation_file_and_changelog_name_the_version_of_the_metadata() -> None:
    import yaml  # PyYAML comes with mkdocs (the test extra)

    version = hybrid_force.__version__  # the one source (the test above)
    citation = yaml.safe_load((REPO / "CITATION.cff").read_text())
    assert citation["cff-version"] == "1.2.0"
    assert citation["version"] == version
    assert citation["license"] == _project()["license"] == "BSD-3-Clause"
    titles = [ref["title"].strip().lower() for ref in citation["references"]]
    assert titles == [
        "modified position-force control for a manipulator geometrically constrained by round "
        "obstacles"
    ]
    changelog = (REPO / "CHANGELOG.md").read_text()
    headings = re.findall(r"^## \[([^\]]+)\]", changelog, flags=re.MULTILINE)
    assert headings[0] == "Unreleased"
    assert version in headings
    assert re.search(rf"^## \[{re.escape(version)}\] - \d{{4}}-\d{{2}}-\d{{2}}$", changelog, re.M)


def test_licence_file_is_the_bsd_3_clause_text_named_by_the_metadata() -> None:
    project = _project()
    assert project["license-files"] == ["LICENSE"]
    text = " ".join((REPO / "LICENSE").read_text().split())
    assert text.startswith("BSD 3-Clause License Copyright (c) 2026, the hybrid_force developers")
    clauses = [
        "1. Redistributions of source code must retain the above copyright notice, this list of "
        "conditions and the following disclaimer.",
        "2. Redistributions in binary form must reproduce the above copyright notice, this list "
        "of conditions and the following disclaimer in the documentation and/or other materials "
        "provided with the distribution.",
        "3. Neither the name of the copyright holder nor the names of its contributors may be "
        "used to endorse or promote products derived from this software without specific prior "
        "written permission.",
    ]
    positions = [text.find(clause) for clause in clauses]
    assert -1 not in positions and positions == sorted(positions), positions
    assert "4." not in text  # three clauses, not the four of the original BSD licence
    assert 'THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS "AS IS"' in text
    assert text.endswith("EVEN IF ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.")
    # PEP 639: no licence classifier beside a licence expression
    assert not [c for c in project["classifiers"] if c.startswith("License ::")]


def test_at_most_twelve_exception_classes_each_with_its_attributes() -> None:
    import inspect

    import hybrid_force.errors as errors
    from hybrid_force import _checks

    classes = [
        value
        for value in vars(errors).values()
        if inspect.isclass(value)
        and issubclass(value, Exception | Warning)
        and value.__module__ == errors.__name__
    ]
    assert len(classes) <= 12, [c.__name__ for c in classes]
    assert set(errors.__all__) >= {c.__name__ for c in classes}
    assert set(errors.OWN_WARNINGS) == {c for c in classes if issubclass(c, Warning)}
    bad = errors.BadInputError("m", key="surface.radius", value=-1.0, file="x.toml", choices="ab")
    assert (bad.key, bad.value, bad.file, bad.choices) == (
        "surface.radius",
        -1.0,
        "x.toml",
        ("a", "b"),
    )
    with pytest.raises(errors.ScenarioError) as info:
        _checks.one_of("spline", "sim.integrator", errors.ScenarioError, ("rk4", "euler"))
    assert info.value.value == "spline" and info.value.choices == ("rk4", "euler")
    failed = errors.RunFailedError("m", reason="interrupted")
    assert (failed.reason, failed.result, failed.signal) == ("interrupted", None, "SIGINT")
    assert (
        errors.RunFailedError("m").reason == "error" and errors.RunFailedError("m").signal is None
    )
    missing = errors.MissingExtraError("m", module="matplotlib", extra="plots")
    assert (missing.module, missing.extra, missing.key, missing.value) == (
        "matplotlib", "plots", "extra", "plots"
    )  # fmt: skip
