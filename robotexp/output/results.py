"""Run results: the record of one run, the JSONL file runs are appended to, the curve, path, map
and image files, and `ResultsWriter`, the run observer that writes them all.

Each finished (or interrupted) run is appended to `OUT/results.jsonl` as one JSON object and
flushed to disk at once, so an interrupted campaign keeps every run already written.
"""

from __future__ import annotations

import csv
import errno
import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from robotexp.errors import ConfigError, RobotexpError
from robotexp.run.observers import RunObserver
from robotexp.run.record import RESULT_KEYS, EndReason, RunRecord, record_problem

if TYPE_CHECKING:
    from robotexp.run.loop import ExplorationRun
from robotexp.output.render import laser_hits, render_map, teammates_of
from robotexp.output.safefile import append_line, safe_name

__all__ = ["append_jsonl", "read_jsonl", "read_records", "run_id", "take_name", "write_curve_csv", "ResultsWriter",
           "map_image", "read_curve_csv", "RESULT_KEYS", "RunRecord", "EndReason"]


log = logging.getLogger(__name__)


def run_id(world: str, method: str, pose: str, speed: float, seed: int, out: Path) -> str:
    """A file-name-safe run name (`safe_name`), unique in `out` (a numeric suffix is added when taken), and
    taken: its `<name>.coverage.csv` is created exclusively (O_EXCL, with the header only until the run
    writes its samples), so runs that start at once in one folder, in other processes too, never get one
    name, and no run's files overwrite another's.

    Raises:
        OSError: `out` cannot be written.
    """
    return take_name(out, safe_name(f"{world}_{method}_{pose}_{speed * 1000:.0f}mms_s{seed}"))


def take_name(out: Path, base: str) -> str:
    """`base`, or `base_2`, `base_3`, ... the first that no run in `out` has, taken for the caller by an
    exclusive create of its `<name>.coverage.csv` (the header only; see `run_id`).

    Raises:
        OSError: `out` cannot be written.
    """
    name, k = base, 1
    while True:
        if not (out / f"{name}.png").exists():
            try:
                fd = os.open(out / f"{name}.coverage.csv", os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                pass
            else:
                with os.fdopen(fd, "w", encoding="utf-8") as f:
                    f.write(",".join(CURVE_HEADER) + "\n")
                return name
        k += 1
        name = f"{base}_{k}"


class ResultsWriter(RunObserver):
    """The observer that writes a run's files under `out` at its end: the record appended to
    `results.jsonl` first (so it is never lost), then `<run>.coverage.csv`, `<run>.path.csv` (the true
    path where known), `<run>.estimated_path.csv` (the pose the explorer got, when it differs: odometry
    error, localization), `<run>.map.yaml` + `.pgm` and, with `image`, the figures `<run>.png` and
    `<run>.coverage.png` (`robotexp.output.figures`; also as .svg / .pdf when `image` is a tuple of formats
    naming them).

    It is `critical`: when writing fails the caller of the run raises the error after the run.
    """

    critical = True

    def __init__(self, out: Path, *, image: bool | tuple[str, ...] = True, show: tuple[str, ...] = ()) -> None:
        self.out, self.image, self.show = out, bool(image), show
        self.formats: tuple[str, ...] = image if isinstance(image, tuple) else ("png",)
        self.image_path: Path | None = None
        self.plot_path: Path | None = None

    def on_end(self, run: ExplorationRun, record: RunRecord) -> None:
        """Write the record and the run's files."""

        out, name = self.out, record.run
        results = out / "results.jsonl"
        try:
            out.mkdir(parents=True, exist_ok=True)
            append_jsonl(results, record)      # first: the record is never lost
        except IsADirectoryError:
            # something made results.jsonl a folder during the run: the record goes beside it
            rescue = out / f"{name}.record.json"
            append_jsonl(rescue, record)
            raise ConfigError(f"{results} is a folder, not a results file: this run's record was "
                              f"written to {rescue} instead; move the folder away") from None
        except OSError as exc:      # a full disk: append_jsonl left no half line
            raise OSError(exc.errno, f"{exc.strerror or exc}: the record of run {name} was not written to "
                          f"{results}") from exc
        try:
            self._files(run, name)
        except (OSError, RobotexpError) as exc:
            why = getattr(exc, "strerror", None) or str(exc)
            raise OSError(getattr(exc, "errno", None) or errno.EIO, f"{why}: the record of run {name} is in "
                          f"{results}, but its other files in {out} (CSVs, map, figures) are incomplete") from exc

    def _files(self, run: ExplorationRun, name: str) -> None:
        """The run's files beside its record."""
        from robotexp.output.trajectory import write_path_csv
        from robotexp.world.rosmap import save_ros_map

        out = self.out
        write_curve_csv(out / f"{name}.coverage.csv", run.metrics.curve)
        write_path_csv(out / f"{name}.path.csv", run.metrics.path)     # overlaid by `campaign plot`
        for i, other in enumerate(getattr(run, "paths", [])[1:], start=2):     # a team's other robots
            write_path_csv(out / f"{name}.robot_{i}.path.csv", other)
        est = np.asarray(run.metrics.estimated, np.float64).reshape(-1, 2)
        if len(est) and np.abs(est - np.asarray(run.metrics.path, np.float64)).max() > 1e-3:   # odometry error on
            write_path_csv(out / f"{name}.estimated_path.csv", run.metrics.estimated)   # the explorer's pose
        save_ros_map(out / f"{name}.map.yaml", run.grid.states(), run.grid.geo)   # ROS map_server map
        if self.image:
            self.image_path, self.plot_path = _save_run_images(run, out, name, self.show, self.formats)


def _save_run_images(run: ExplorationRun, out: Path, name: str, show: tuple[str, ...] = (),
                    formats: tuple[str, ...] = ("png",)) -> tuple[Path, Path | None]:
    """The map figure (grid, walls, path - true and estimated when they differ -, start, end and the `show`
    overlays) and the coverage figure (None without ground truth), as `formats` (PNG first)."""
    from robotexp.output.figures import save_run_figures

    fmts = ("png", *(f for f in formats if f != "png"))
    return save_run_figures(run, out, name, fmts, show)


def map_image(run: ExplorationRun, title: str, show: tuple[str, ...] = (), *, scale: int | None = None,
              path: bool = True) -> Any:
    """The fast raster image (PIL, `robotexp.output.render`) of a run's map with its path and the overlays named in
    `show` (grid, laser, vectors, potential, truth), for frames; `scale` in pixels per cell (None: fit),
    `path` False leaves the path out. The final images are figures (`_save_run_images`)."""

    m = run.metrics
    overlays = run.explorer.overlays()
    state = run.state
    laser = laser_hits(run) if "laser" in show else None
    end = None if state is None else (state.true_pose or state.pose)
    states = run.grid.states()
    content = states >= 0 if run.truth is None else (states >= 0) | run.truth.explorable
    return render_map(states, run.grid.geo, content=content,
                      truth=run.truth.occupied if run.truth is not None else None,
                      path=np.array(m.path) if m.path and path else None, start=run.start_pose, end=end,
                      scale=scale,
                      show_grid="grid" in show, laser=laser,
                      vectors=overlays.get("vectors") if "vectors" in show else None,
                      potential=overlays.get("potential") if "potential" in show else None,
                      title=title, teammates=teammates_of(run))


def append_jsonl(path: Path, record: RunRecord | dict[str, Any]) -> None:
    """Append `record` (a RunRecord is written as its `as_dict()`) as one line to `path` and force it
    to disk; a torn last line left by an earlier fault is repaired first (and reported), and a failed
    write leaves no half line (`robotexp.output.safefile.append_line`)."""
    append_line(path, record.as_dict() if isinstance(record, RunRecord) else record)


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    """Every record of a results file; a torn or damaged line, and a record whose known fields have the
    wrong type (`record_problem`: `"coverage": "x"`), is reported (`file:line`) and skipped."""
    from robotexp.output.safefile import read_records
    return read_records(path, check=record_problem)


def read_records(path: Path) -> list[RunRecord]:
    """Every record of a results file as a `RunRecord` (a torn or damaged line, or a field of the wrong type,
    is reported and skipped: `read_jsonl`)."""
    return [RunRecord.from_dict(r) for r in read_jsonl(path) if isinstance(r, dict)]


def read_curve_csv(path: Path) -> np.ndarray[Any, np.dtype[np.float64]]:
    """The (k, 3) float64 curve of a `write_curve_csv` file: robot time [s], path length [m], coverage.

    Raises:
        ConfigError: not a coverage file (wrong header, a line that is not three numbers).
        OSError: the file cannot be read.
    """

    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    if not rows or [c.strip() for c in rows[0]] != list(CURVE_HEADER):
        raise ConfigError(f"{path}:1: not a coverage file: expected the header {','.join(CURVE_HEADER)}")
    try:
        return np.array([[float(v) for v in row] for row in rows[1:]], np.float64).reshape(-1, 3)
    except ValueError:
        raise ConfigError(f"{path}: expected three numbers per line after the header") from None


CURVE_HEADER = ("robot_time_s", "path_length_m", "coverage")


def write_curve_csv(path: Path, curve: list[tuple[float, float, float]]) -> None:
    """The coverage curve: robot time [s], path length [m], coverage (0..1, -1 when unknown)."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(CURVE_HEADER)
        for t, s, c in curve:
            w.writerow([f"{t:.3f}", f"{s:.4f}", f"{c:.5f}"])
