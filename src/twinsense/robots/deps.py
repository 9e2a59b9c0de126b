"""Optional dependencies of the robot loaders (the ``robots`` extra)."""

from __future__ import annotations

import importlib
from types import ModuleType

from twinsense.errors import ConfigError

EXTRA = "robots"
INSTALL_HINT = f"pip install twinsense[{EXTRA}]"


def require(module: str, purpose: str) -> ModuleType:
    """Import ``module`` or raise ConfigError naming the extra that installs it."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is not None and exc.name.split(".")[0] != module.split(".")[0]:
            raise  # a broken install of the module itself, not a missing one
        raise ConfigError(f"{EXTRA} extra", module, f"the {module!r} package installed for {purpose}: "
                          f"{INSTALL_HINT}") from None
