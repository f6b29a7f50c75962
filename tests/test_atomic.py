"""Atomic writes: complete new file or untouched old one, usual permissions, no leftovers."""

from __future__ import annotations

import os
import stat

import pytest

from hybrid_force._atomic import atomic_file


def test_writes_the_file_with_the_usual_permissions(tmp_path) -> None:
    target = tmp_path / "out.txt"
    old = os.umask(0o022)
    try:
        with atomic_file(target, "w", encoding="utf-8") as fh:
            fh.write("hello")
    finally:
        os.umask(old)
    assert target.read_text(encoding="utf-8") == "hello"
    assert stat.S_IMODE(target.stat().st_mode) == 0o644  # not mkstemp's 0600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_an_interrupted_write_leaves_the_old_file_and_no_temp(tmp_path, error) -> None:
    target = tmp_path / "out.bin"
    target.write_bytes(b"old content")
    with pytest.raises(error), atomic_file(target) as fh:
        fh.write(b"half of the new")
        raise error()
    assert target.read_bytes() == b"old content"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]
