"""Where a command's kernel cache loads go (issue 32, item 4: the fixed cost).

Run from the repository root, with Numba's cache warm (any earlier run):

    python benchmarks/study_kernel_loads.py [SCENARIO]

Runs ``hybrid-force run SCENARIO --set sim.duration=0.01`` in this process with Numba's
loading steps wrapped with a clock (the pinned 0.68 series' ``CPUCodeLibrary._unserialize``
and what it calls: ``llvmlite.binding.parse_bitcode``, the JIT engine's symbol scan, the object
code's finalisation) and prints their totals and each kernel's load with the sizes of its
cached object code and "shared" bitcode. Not part of the test suite.
"""

from __future__ import annotations

import collections
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> int:
    import numba.core.codegen as cg

    args = sys.argv[1:] if argv is None else argv
    scenario = args[0] if args else str(ROOT / "scenarios" / "paper_contact.toml")
    clock = time.perf_counter
    total: collections.Counter[str] = collections.Counter()
    count: collections.Counter[str] = collections.Counter()

    def timed(owner: Any, name: str, label: str) -> None:
        inner: Callable[..., Any] = getattr(owner, name)

        def wrapper(*a: Any, **k: Any) -> Any:
            t0 = clock()
            try:
                return inner(*a, **k)
            finally:
                total[label] += clock() - t0
                count[label] += 1

        setattr(owner, name, wrapper)

    timed(cg.ll, "parse_bitcode", "llvmlite parse_bitcode")
    timed(cg.JitEngine, "_load_defined_symbols", "the engine's symbol scan")
    timed(cg.JITCodeLibrary, "_finalize_specific", "object code finalised")
    loads: list[tuple[float, str, int, int]] = []
    unserialize = cg.CPUCodeLibrary._unserialize.__func__  # type: ignore[attr-defined]

    def load(cls: Any, codegen: Any, state: Any) -> Any:
        name, _, data = state
        t0 = clock()
        library = unserialize(cls, codegen, state)
        loads.append((clock() - t0, name, len(data[0]), len(data[1])))
        return library

    cg.CPUCodeLibrary._unserialize = classmethod(load)  # type: ignore[method-assign,assignment]

    from hybrid_force.cli import main as cli

    with tempfile.TemporaryDirectory() as tmp:
        t0 = clock()
        cli(["run", scenario, "--set", "sim.duration=0.01", "--out", str(Path(tmp) / "out")])
        wall = clock() - t0
    print(f"\nthe command in process: {wall:.3f} s; {len(loads)} kernels loaded from the cache")
    print(f"  CodeLibrary._unserialize (all)      {1e3 * sum(x[0] for x in loads):7.1f} ms")
    for label in total:
        print(f"  {label:34s}  {1e3 * total[label]:7.1f} ms ({count[label]} calls)")
    print("per kernel: ms, object code kB, shared bitcode kB")
    for dt, name, obj, bitcode in sorted(loads, reverse=True):
        kernel = name.split(".")[-1][:60]
        print(f"  {1e3 * dt:6.1f} {obj / 1e3:7.1f} {bitcode / 1e3:7.1f}  {kernel}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
