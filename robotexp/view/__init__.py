"""The live view: a page in the browser that shows a run as it goes (`robotexp explore --view`).

`ViewHub` (feed.py) holds the newest state of what is shown; `ViewObserver` (observer.py) feeds it
from a run and holds the run's loop for pause / step / pacing; `ViewServer` (server.py) serves the
page (static/) and a websocket on aiohttp in a background thread. `LiveView` (live.py) puts the three
together for the CLI. The stream of `Frame`s is the interface: a replay can publish the same frames.
"""

from __future__ import annotations

from typing import Any

__all__ = ["Frame", "ViewHub", "ViewObserver", "ViewServer", "Pacer", "LiveView"]

_WHERE = {"Frame": "feed", "ViewHub": "feed", "ViewObserver": "observer", "Pacer": "observer",
          "ViewServer": "server", "LiveView": "live"}


def __getattr__(name: str) -> Any:
    """Lazy imports: the CLI reads the options without loading the web server."""
    if name in _WHERE:
        import importlib
        return getattr(importlib.import_module(f"robotexp.view.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'robotexp.view' has no attribute {name!r}")
