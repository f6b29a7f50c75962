"""Griffe extension of the API reference: Sphinx roles in the docstrings as code.

The docstrings name objects the Sphinx way (``:class:`~hybrid_force.result.Result```), which
Markdown would show as ``:class:~hybrid_force.result.Result``. This writes such a role as the
code ``Result`` (``~`` keeps the last name, as in Sphinx), without a link: many targets are
outside the package (numpy, Pinocchio) or relative to the class, and a strict build refuses a
link it cannot resolve.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const):`(~?)([^`]+)`")


def _as_code(match: re.Match[str]) -> str:
    name = match.group(2)
    return f"`{name.rsplit('.', 1)[-1] if match.group(1) else name}`"


class SphinxRolesAsCode(griffe.Extension):
    """Rewrite every object's docstring before it is parsed."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(_as_code, obj.docstring.value)
