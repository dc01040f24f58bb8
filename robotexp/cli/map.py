"""`robotexp map LOG --out DIR`: build a map from a CARMEN laser log, optionally from perturbed odometry
recovered by scan matching, and measure the absolute trajectory error against the logged poses.

`robotexp.cli.main` registers the command and wraps it in its error handling (bad input: one line, exit 2).

The map is named after the log (`intel-corrected.log.gz`: `intel-corrected`), or `NAME_2`, `NAME_3`, ...
when OUT already has a map or a run of that name (`robotexp.output.results.take_name`, as runs are named):
a map never replaces an earlier one, and each record of results.jsonl names its own files. The folder and
the name are checked and taken before the log is read; a command that fails leaves no file of its map."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry

if TYPE_CHECKING:
    from robotexp.localization.logmap import OdometryNoise

__all__ = ["map_command", "_crop_seen"]

MAX_PROBLEMS_SHOWN = 10


def _crop_seen(states: npt.NDArray[np.int8], geo: GridGeometry, margin: int = 10
              ) -> tuple[npt.NDArray[np.int8], GridGeometry]:
    """The states and geometry cut to the cells seen (not -1) plus `margin` cells around them."""
    seen = np.argwhere(states >= 0)
    if len(seen) == 0:
        return states, geo
    r0, c0 = np.maximum(seen.min(axis=0) - margin, 0)
    r1, c1 = np.minimum(seen.max(axis=0) + margin + 1, states.shape)
    sub = np.ascontiguousarray(states[r0:r1, c0:c1])
    return sub, GridGeometry(geo.origin_x + c0 * geo.cell, geo.origin_y + r0 * geo.cell, geo.cell,
                             int(r1 - r0), int(c1 - c0))


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".gz", ".log", ".clf", ".txt"):
        if name.endswith(suffix):
            name = name[: -len(suffix)]
    return name or "map"


MAP_FILES = (".png", ".pgm", ".yaml")      # the files of a map NAME (figure, ROS map image and YAML)


def _claim(path: Path) -> Path:
    """`path`, the file by which `take_name` holds a name (see `robotexp.output.results.run_id`)."""
    return path.with_name(f"{path.name}.coverage.csv")


def _take_map_name(out: Path, base: str) -> str:
    """`base`, or `base_2`, `base_3`, ... the first name whose map files (`MAP_FILES`) are not in `out`
    and that no run has, taken as runs take theirs (`take_name`: its claim file is made exclusively, so a
    map made at the same time in another process gets another name); the caller removes the claim file
    (`_claim(out / name)`) when done.

    Raises:
        OSError: `out` cannot be written.
    """
    from robotexp.output.results import take_name

    passed: list[str] = []          # names with a map file of an earlier map (its PNG gone): held while looking
    try:
        while True:
            name = take_name(out, base)
            if not any(os.path.lexists(out / f"{name}{suffix}") for suffix in MAP_FILES):
                return name
            passed.append(name)
    finally:
        for other in passed:
            _claim(out / other).unlink(missing_ok=True)


@click.command("map")
@click.argument("log", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for NAME.png, NAME.yaml + NAME.pgm and results.jsonl.")
@click.option("--cell", type=float, default=0.05, show_default=True, help="Cell size [m].")
@click.option("--odometry-noise", default="0,0", show_default=True, metavar="DIST,DEG_PER_M",
              help="Perturb the logged poses as odometry: DIST fraction of distance, DEG_PER_M heading "
                   "drift per metre (systematic, plus random of the same size), e.g. 0.02,1.")
@click.option("--localize", type=click.Choice(["none", "scan-match"]), default="scan-match", show_default=True,
              help="Map on the perturbed odometry, or correct it by scan matching first.")
@click.option("--loop-closure/--no-loop-closure", default=True, show_default=True,
              help="With scan matching, also close loops (pose graph) before the map is built.")
@click.option("--range-max", type=float, default=20.0, show_default=True,
              help="Readings beyond this [m] mark free space up to it and no hit.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the odometry noise.")
def map_command(log: Path, out: Path, cell: float, odometry_noise: str, localize: str, loop_closure: bool,
                range_max: float, seed: int) -> None:
    """Build a map (PNG, ROS YAML + PGM) from a CARMEN log (FLASER, ROBOTLASER1, or RAWLASER1 placed by
    ODOM; .gz accepted);
    append a record with ate_m, the RMSE [m] of the estimated path against the logged poses (no
    alignment: both start at the first logged pose), to OUT/results.jsonl and print ATE."""
    from robotexp.localization.logmap import parse_noise
    from robotexp.output.safefile import safe_name, writable_folder

    noise = parse_noise(odometry_noise)
    if not (cell > 0 and range_max > 0):
        raise ConfigError(f"--cell and --range-max must be > 0 m, got {cell} and {range_max}")
    t0 = time.monotonic()
    writable_folder(out)                # before any work: a folder that cannot take the map is refused now
    made = [d for d in (out, *out.parents) if not d.exists()]
    out.mkdir(parents=True, exist_ok=True)
    name = _take_map_name(out, safe_name(_stem(log)))
    done = False
    try:
        said = _make_map(log, out, name, cell=cell, noise=noise, localize=localize, loop_closure=loop_closure,
                         range_max=range_max, seed=seed, t0=t0)
        done = True                                      # its record is written: its files stay, whatever comes
    finally:
        _claim(out / name).unlink(missing_ok=True)       # the map's PNG holds the name from now on
        if not done:                                     # nothing of a map that failed is left
            for suffix in MAP_FILES:
                (out / f"{name}{suffix}").unlink(missing_ok=True)
            for d in made:
                try:
                    d.rmdir()
                except OSError:
                    break
    click.echo(said)


def _make_map(log: Path, out: Path, name: str, *, cell: float, noise: OdometryNoise, localize: str,
              loop_closure: bool, range_max: float, seed: int, t0: float) -> str:
    """Read `log`, build its map and write it as `out`/`name`.png, .yaml + .pgm, and its record; returns what
    to tell the user.

    Raises:
        ConfigError: the log is not one that can be mapped (see `read_carmen`, `map_log`).
    """
    from robotexp.localization.carmen import read_carmen
    from robotexp.localization.logmap import map_log
    from robotexp.localization.posegraph import LoopConfig
    from robotexp.output.figures import apart, figure_title, map_figure, save_figure
    from robotexp.output.results import append_jsonl
    from robotexp.world.rosmap import save_ros_map

    parsed = read_carmen(log)
    for line in parsed.problems[:MAX_PROBLEMS_SHOWN]:
        click.echo(f"robotexp: {line}", err=True)
    if len(parsed.problems) > MAX_PROBLEMS_SHOWN:
        click.echo(f"robotexp: ... and {len(parsed.problems) - MAX_PROBLEMS_SHOWN} more malformed lines", err=True)
    if not parsed.scans:
        if parsed.raw:
            raise ConfigError(f"{log}: {len(parsed.raw)} RAWLASER1 readings but no ODOM line to place them: nothing "
                              "to map (a log with neither FLASER nor ROBOTLASER1 lines needs ODOM lines)")
        raise ConfigError(f"{log}: no FLASER, ROBOTLASER1 or RAWLASER1 line: nothing to map (is it a CARMEN log?)")
    result = map_log(parsed, cell=cell, noise=noise, localize=localize, seed=seed,  # type: ignore[arg-type]
                     range_max=range_max, loops=LoopConfig() if loop_closure else None)
    states, geo = _crop_seen(result.grid.states(), result.grid.geo)
    est = result.estimate[:, :2] if apart(result.estimate, result.truth) else None
    fig = map_figure(states, geo, path=result.truth[:, :2], est_path=est, labels=("logged path", "estimated path"),
                     title=figure_title(name, localize),
                     note=f"cell {cell * 1000:g} mm, {len(parsed.scans)} scans, ATE {result.ate_m:.3f} m")
    save_figure(fig, out / name, ("png",))
    save_ros_map(out / f"{name}.yaml", states, geo)
    record = {
        "run": name,
        "log": str(log),
        "scans": len(parsed.scans),
        "malformed_lines": len(parsed.problems),
        "cell_m": cell,
        "range_max_m": range_max,
        "odometry_noise": [noise.dist, float(np.degrees(noise.heading))],
        "localize": localize,
        "loop_closure": bool(loop_closure and localize == "scan-match"),
        "seed": seed,
        "ate_m": round(result.ate_m, 4),
        "ate_alignment": "none",
        "ate_rigid_m": round(result.ate_rigid_m, 4),
        "odometry_ate_m": round(result.odometry_ate_m, 4),
        "matches": result.counts,
        "wall_time_s": round(time.monotonic() - t0, 3),
    }
    append_jsonl(out / "results.jsonl", record)
    return (f"map: {out / (name + '.png')}, {out / (name + '.yaml')}  ({len(parsed.scans)} scans, "
            f"odometry alone: ATE {result.odometry_ate_m:.3f} m)\nATE {result.ate_m:.3f} m")
