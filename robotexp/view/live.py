"""The live view for the CLI: its options and `LiveView` (hub, server and observer together)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from robotexp.errors import ConfigError
from robotexp.view.feed import DEFAULT_SPEED, MAX_SPEED, MIN_SPEED, SPEEDS, ViewHub, speed_value

__all__ = ["LiveView", "view_options", "parse_speed", "start_view", "end_view"]


def parse_speed(text: str | None) -> float | None:
    """`--view-speed`: `speed_value` of the text; default DEFAULT_SPEED.

    Raises:
        ConfigError: anything else.
    """
    if text is None:
        return DEFAULT_SPEED
    try:
        return speed_value(text)
    except ValueError:
        raise ConfigError(f"--view-speed {text!r}: expected {SPEEDS}") from None


class LiveView:
    """A hub, its server and an observer for one command's runs.

    Args:
        host, port: where to serve (port 0: a free one).
        speed: robot time per wall time of simulated runs (None: as fast as they go).
        echo: told the page's address once it is served.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, speed: float | None = DEFAULT_SPEED,
                 echo: Callable[[str], None] = click.echo) -> None:
        if not 0 <= port <= 65535:
            raise ConfigError(f"--view-port must be within 0..65535, got {port}")
        from robotexp.view.observer import ViewObserver
        from robotexp.view.server import ViewServer

        self.hub = ViewHub()
        self.observer = ViewObserver(self.hub, speed=speed)
        self.server = ViewServer(self.hub, host, port)
        self.echo = echo

    def start(self) -> LiveView:
        """Serve the page and print `view: URL`."""
        url = self.server.start()
        self.echo(f"view: {url}")
        return self

    def hold(self) -> None:
        """Keep serving the final state until Ctrl-C."""
        import time

        self.echo("view: the run has ended; the page shows its final state until Ctrl-C")
        try:
            while True:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass

    def close(self) -> None:
        """Stop serving."""
        self.server.close()


def view_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The --view, --view-port, --view-host and --view-speed options of a command."""
    func = click.option("--view-speed", default=None, metavar="X|max",
                        help=f"With --view: simulated robot time per wall time, {MIN_SPEED:g}..{MAX_SPEED:g} "
                             f"(default {DEFAULT_SPEED:g}; max: as fast as it goes).")(func)
    func = click.option("--view-host", default="127.0.0.1", show_default=True,
                        help="With --view: the address to serve on (0.0.0.0: every address of this machine; "
                             "the page then answers to an IP address or this machine's name).")(func)
    func = click.option("--view-port", type=int, default=0,
                        help="With --view: the TCP port of the page (default: a free one).")(func)
    func = click.option("--view", is_flag=True,
                        help="Show the run live in the browser (prints the page's address).")(func)
    return func


def start_view(view: bool, host: str, port: int, speed: str | None) -> LiveView | None:
    """The command's live view, served and announced (None without --view); the options are checked
    first (ConfigError)."""
    if not view:
        return None
    return LiveView(host, port, parse_speed(speed)).start()


def end_view(live: LiveView | None, interrupted: bool) -> None:
    """After the command's runs: keep the page up until Ctrl-C (unless the run was interrupted), then stop it."""
    if live is None:
        return
    try:
        if not interrupted:
            live.hold()
    finally:
        live.close()
