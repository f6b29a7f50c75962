"""The package's import graph: layered, without a cycle, and imports inside functions only where
they defer a heavy optional library on purpose.

The graph is built from the source with ``ast`` (no import): every ``import`` statement of
``hybrid_force/**/*.py`` counts, at module level, under ``if TYPE_CHECKING:`` and inside
functions, except a function-level import of a deferred module (below), which is the point of
that import. The layers, each importing only from the ones before it: errors.py and the small
shared helpers, ``model/``, ``geometry/``, ``control/``, ``sim/``, the result modules, then the
edges (``scenario/``, ``viz/``, ``studies/``, the command line).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "hybrid_force"

#: Libraries imported inside functions on purpose: each is heavy (numba, trimesh, libigl,
#: yourdfpy and xacro cost 0.1-1 s) or an optional extra (matplotlib, meshcat and the viewer
#: server's libraries, dask, playwright, mujoco), so that ``import hybrid_force`` and a plain
#: command do not pay for it; importlib.metadata: the version, read on first use.
DEFERRED_LIBRARIES = {
    "IPython",
    "coal",
    "dask",
    "distributed",
    "igl",
    "importlib.metadata",
    "matplotlib",
    "meshcat",
    "mujoco",
    "numba",
    "playwright",
    "tornado",
    "trimesh",
    "umsgpack",
    "xacro",
    "yourdfpy",
    "zmq",
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))}


#: Modules of the package imported inside functions on purpose: the edges of the optional
#: extras (viz/: matplotlib and meshcat; studies/: dask), which the command line loads only for
#: the subcommand that needs them (about 60 ms of a command's start otherwise), the MJCF reader
#: and the xacro evaluator (15 ms, only for those models), the model report (``robots --check``).
DEFERRED_MODULES = ("hybrid_force.viz", "hybrid_force.studies", "hybrid_force.model.mjcf",
                    "hybrid_force.model.xacro_eval", "hybrid_force.model.report")  # fmt: skip


def is_deferred(module: str) -> bool:
    """A deferred library or module, or a compiled-kernel module of the package (Numba, loaded
    lazily: ``import hybrid_force`` does not import Numba)."""
    if module.startswith("hybrid_force."):
        if module.rsplit(".", 1)[-1].endswith("kernels"):
            return True
        return any(module == m or module.startswith(m + ".") for m in DEFERRED_MODULES)
    return any(module == lib or module.startswith(lib + ".") for lib in DEFERRED_LIBRARIES)


def imports(tree: ast.Module) -> Iterator[tuple[ast.Import | ast.ImportFrom, bool]]:
    """Every import statement of a module, and whether it sits inside a function."""

    def walk(
        node: ast.AST, in_function: bool
    ) -> Iterator[tuple[ast.Import | ast.ImportFrom, bool]]:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import | ast.ImportFrom):
                yield child, in_function
            inside = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            yield from walk(child, inside)

    yield from walk(tree, False)


def targets(node: ast.Import | ast.ImportFrom, here: str) -> list[str]:
    """The modules a statement imports (``from pkg import sub`` imports the module pkg.sub)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    base = node.module or ""
    if node.level:
        package = here if MODULES[here].name == "__init__.py" else here.rsplit(".", 1)[0]
        for _ in range(node.level - 1):
            package = package.rsplit(".", 1)[0]
        base = f"{package}.{base}" if base else package
    found = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES]
    if len(found) < len(node.names):
        found.append(base)
    return found


def graph() -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {name: set() for name in MODULES}
    for name, path in MODULES.items():
        for node, in_function in imports(ast.parse(path.read_text(encoding="utf-8"))):
            for target in targets(node, name):
                if target in MODULES and not (in_function and is_deferred(target)):
                    edges[name].add(target)
    return edges


def find_cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph as [a, b, ..., a], or None (depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(edges[node]):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (cycle := visit(nxt)) is not None:
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(edges):
        if node not in state and (cycle := visit(node)) is not None:
            return cycle
    return None


def test_the_package_has_no_import_cycle() -> None:
    edges = graph()
    cycle = find_cycle(edges)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_imports_inside_functions_only_defer_heavy_optional_libraries() -> None:
    found = []
    for name, path in MODULES.items():
        for node, in_function in imports(ast.parse(path.read_text(encoding="utf-8"))):
            if in_function and not all(is_deferred(t) for t in targets(node, name)):
                found.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}")
    assert not found, f"{len(found)} imports inside functions: {', '.join(found)}"


def test_the_cycle_finder_finds_a_cycle_and_the_kernels_are_deferred() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None
    assert is_deferred("hybrid_force.sim._kernels") and is_deferred("matplotlib.pyplot")
    assert is_deferred("hybrid_force.viz.replay") and is_deferred("hybrid_force.studies._dask_warm")
    assert not is_deferred("hybrid_force.sim.loop") and not is_deferred("numpy")
    assert not is_deferred("hybrid_force.model.mjcf_extra")
