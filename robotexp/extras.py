"""Optional dependencies: the install extra that brings each, and the one-line error when it is missing.

The base install runs explorations, campaigns, reports and figures on this machine and on real robots;
`robotexp[cluster]` adds Dask (campaign run --cluster), `robotexp[video]` adds imageio and its ffmpeg
(robotexp video).
"""

from __future__ import annotations

import importlib
from types import ModuleType

from robotexp.errors import ConfigError

__all__ = ["EXTRAS", "require"]

# import name -> (distribution, extra)
EXTRAS: dict[str, tuple[str, str]] = {
    "dask": ("dask", "cluster"),
    "distributed": ("distributed", "cluster"),
    "imageio": ("imageio", "video"),
    "imageio_ffmpeg": ("imageio-ffmpeg", "video"),
}


def require(module: str, feature: str) -> ModuleType:
    """Import `module`, a dependency of an install extra (`EXTRAS`), for `feature` (what the user asked
    for, e.g. "--cluster").

    Raises:
        ConfigError: the module is not installed: one line naming the extra to install.
    """
    try:
        return importlib.import_module(module)
    except ImportError:
        dist, extra = EXTRAS[module]
        raise ConfigError(f"{feature} needs {dist}, which the base install leaves out; install it with "
                          f"pip install 'robotexp[{extra}]'") from None
