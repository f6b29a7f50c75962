"""The API reference (docs/mkdocs.yml) builds without a warning and documents every module.

The build runs here, not only in .ci/run, so that the test suite, which is what a change is
checked with, also catches a docstring that breaks the strict build.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow  # about 5 s


def public_modules() -> set[str]:
    """Dotted names of the package's modules, found from the files (no import), without
    private ones (a ``_`` name anywhere in the path)."""
    names = set()
    for path in (REPO / "hybrid_force").rglob("*.py"):
        parts = list(path.relative_to(REPO).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        if not any(part.startswith("_") for part in parts):
            names.add(".".join(parts))
    return names


def test_api_reference_builds_strictly_and_documents_every_public_module(
    tmp_path: Path,
) -> None:
    site = tmp_path / "site"
    command = [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", "docs/mkdocs.yml"]
    build = subprocess.run(
        [*command, "-d", str(site)],
        cwd=REPO,
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr
    assert "WARNING" not in build.stderr, build.stderr
    anchors: set[str] = set()
    for page in (site / "api").glob("*.html"):
        text = page.read_text()
        anchors |= set(re.findall(r'id="(hybrid_force[\w.]*)"', text))
        # Sphinx roles of the docstrings are shown as code (docs/_griffe_roles.py)
        assert not re.search(r":(class|func|meth|mod|attr|exc):", text), page.name
    modules = public_modules()
    assert {"hybrid_force.sim.loop", "hybrid_force.geometry.surfaces"} <= modules
    missing = sorted(modules - anchors - {"hybrid_force"})
    assert not missing, f"modules without an API page (add one in docs/api/): {missing}"
    # the guides are pages of the site too
    for guide in ("index", "scenarios", "robots", "sweep", "compare", "replay"):
        assert (site / f"{guide}.html").is_file(), guide
