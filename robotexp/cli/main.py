"""The `robotexp` command group: every command module registered on it.

Exit codes: 0 ok; 1 a run failed (robot or script error); 2 bad input (world, method, parameter);
130 interrupted by Ctrl-C, 143 by SIGTERM (the partial result is written first, the robot stopped). Each
command module imports the library inside its command, so `robotexp --help` stays cheap (no pybullet, numba,
lupa or pymavlink).
"""

from __future__ import annotations

import click

from robotexp.cli.bag import figure, replay, video
from robotexp.cli.bench import bench
from robotexp.cli.campaign import campaign
from robotexp.cli.common import handle_errors, watch_signals
from robotexp.cli.explore import explore
from robotexp.cli.lua import run_lua
from robotexp.cli.map import map_command
from robotexp.cli.plugins import plugins
from robotexp.cli.robots import connect, emulate
from robotexp.cli.worlds import worlds

__all__ = ["main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--debug", is_flag=True, help="Show Python tracebacks on errors.")
@click.version_option(package_name="robotexp")
def main(debug: bool) -> None:
    """Mobile-robot exploration experiments, on the embedded simulator or a real robot."""
    watch_signals()


for _command in (explore, worlds, plugins, campaign, run_lua, emulate, connect, bench):
    main.add_command(_command)
# commands defined without the error handling of the others
for _command in (replay, video, figure, map_command):
    _command.callback = handle_errors(_command.callback)  # type: ignore[type-var]
    main.add_command(_command)
