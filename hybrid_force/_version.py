"""The version of hybrid_force, as installed (one source: pyproject.toml's, read through
importlib.metadata on first use: ~0.02 s that ``import hybrid_force`` does not pay)."""

from __future__ import annotations

__all__ = ["installed_version"]

_FOUND: list[str] = []


def installed_version() -> str:
    """The version in pyproject.toml, as installed; ``"0+unknown"`` in a source tree that is
    not installed."""
    if not _FOUND:
        from importlib.metadata import PackageNotFoundError, version

        try:
            _FOUND.append(version("hybrid_force"))
        except PackageNotFoundError:  # run from a source tree that is not installed
            _FOUND.append("0+unknown")
    return _FOUND[0]
