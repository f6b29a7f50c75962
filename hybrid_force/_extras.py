"""The optional extras: the library each heavy edge of the toolkit needs, and the check.

The core (load a scenario, run it, save ``result.npz`` and ``summary.json``, sweep on the
process pool) imports none of them. Figures need matplotlib (extra ``plots``), the 3D replay
meshcat (``replay``), the Dask engine dask and distributed (``dask``); ``all`` installs the
three. :func:`require` is called where one of them is first needed, so that a missing library
is one :class:`~hybrid_force.errors.MissingExtraError` naming the extra, not an ImportError
from deep inside a figure or a scene.
"""

from __future__ import annotations

import importlib

from hybrid_force.errors import MissingExtraError

#: The libraries of each extra, in the order they are imported.
EXTRAS: dict[str, tuple[str, ...]] = {
    "plots": ("matplotlib",),
    "replay": ("meshcat",),
    "dask": ("dask", "distributed"),
}


def require(extra: str, feature: str) -> None:
    """Import the libraries of ``extra`` for ``feature`` (e.g. "figures").

    Raises:
        MissingExtraError: one of them cannot be imported; the message names ``feature``, the
            library and the extra to install.
    """
    for module in EXTRAS[extra]:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise MissingExtraError(
                f"{feature}: {module} cannot be imported ({exc}); install the extra "
                f'{extra!r}: pip install "hybrid_force[{extra}]" (".[{extra}]" in the source '
                "tree)",
                module=module,
                extra=extra,
            ) from exc


def available(extra: str) -> bool:
    """True when every library of ``extra`` imports (it is then imported)."""
    try:
        require(extra, extra)
    except MissingExtraError:
        return False
    return True
