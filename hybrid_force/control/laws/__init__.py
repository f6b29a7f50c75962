"""The control laws: :mod:`.base` (what a law is, the registry) and one module per law, which
registers it where it is defined. Importing this package imports every law module in it
(a name without a leading underscore), so the registry is complete; their kernels load lazily.
"""

import importlib
import pkgutil

for _module in pkgutil.iter_modules(__path__):
    if not _module.name.startswith("_") and _module.name != "base":
        importlib.import_module(f"{__name__}.{_module.name}")
