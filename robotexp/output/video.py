"""Frames of a run as it goes (`FrameObserver`): saved as PNGs (`explore --frames DIR`, as IfTEA did)
or encoded into a video (`robotexp video`: MP4 through the ffmpeg binary of the imageio-ffmpeg wheel,
no system ffmpeg; GIF through Pillow).

A frame is the map so far (the fast raster path, `robotexp.output.render.render_map`: unknown grey, free
white, occupied black, obstacles not yet mapped in slate where ground truth is known), the path
(blue), the laser's hits (orange), the start (green) and the robot (red), under a title with the
robot time, path length and coverage. Every frame of a run has the same size (the whole grid at
one scale), as a video needs.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.run.observers import RunObserver, StepEvent, ends_team_tick

if TYPE_CHECKING:
    from PIL import Image

    from robotexp.run.loop import ExplorationRun
    from robotexp.run.record import RunRecord

__all__ = ["FrameObserver", "PngFrames", "VideoWriter", "VIDEO_SUFFIXES", "check_video_path",
           "check_fps"]

VIDEO_SUFFIXES = (".mp4", ".gif")
FRAME_SIZE = 800        # [px] frames fit this square unless the grid has more cells than that
BLOCK = 16              # [px] video frames are padded to multiples of this (H.264 macro blocks)


def _frame_image(run: ExplorationRun, scale: int | None = None, title: str | None = None,
                show: tuple[str, ...] = ()) -> Image.Image:
    """The frame of `run` now (see the module's docstring); `scale` [px per cell] (None: fit FRAME_SIZE);
    `show`: the explorer's overlays to draw too ("potential", "vectors", "grid", as `explore --show`)."""
    from robotexp.output.render import render_map

    from robotexp.output.figures import run_title
    from robotexp.output.render import laser_hits, teammates_of

    state = run.state
    laser = laser_hits(run)
    path = np.array(run.metrics.path) if run.metrics.path else None
    if title is None:
        cov = run.coverage()
        team = len(getattr(run, "paths", ()))
        title = run_title(run, f"{run.robot_time:.0f} s, " + (f"{team} robots, " if team > 1 else "")
                          + f"{run.metrics.path_length:.1f} m"
                          + ("" if cov is None else f", coverage {cov * 100:.1f} %"))
    overlays = run.explorer.overlays() if ("potential" in show or "vectors" in show) else {}
    return render_map(run.grid.states(), run.grid.geo, truth=None if run.truth is None else run.truth.occupied,
                      path=path, start=run.start_pose,
                      end=None if state is None else (state.true_pose or state.pose),
                      laser=laser, scale=scale, title=title, max_size=FRAME_SIZE, show_grid="grid" in show,
                      potential=overlays.get("potential") if "potential" in show else None,
                      vectors=overlays.get("vectors") if "vectors" in show else None,
                      teammates=teammates_of(run))


class FrameObserver(RunObserver):
    """Renders a frame every `every` seconds of robot time (the first at the start, the last at the
    end) and hands it to `sink`; `show`: the explorer's overlays drawn too (`_frame_image`).

    Raises:
        ConfigError: `every` is not > 0.
    """

    critical = True         # a frame that cannot be written fails the command after the run (its record kept)

    def __init__(self, sink: Callable[[Image.Image], None], every: float = 1.0, show: tuple[str, ...] = ()) -> None:
        if not (every > 0 and math.isfinite(every)):
            raise ConfigError(f"frame period must be > 0 s, got {every:g}")
        self.sink, self.every, self.show = sink, every, show
        self.frames = 0
        self._next = 0.0
        self._scale: int | None = None
        self._last_time = -math.inf

    def _emit(self, run: ExplorationRun, time: float) -> None:
        if self._scale is None:
            from robotexp.output.render import map_layout

            self._scale = map_layout(run.grid.geo, title="t", max_size=FRAME_SIZE).scale
        self.sink(_frame_image(run, self._scale, show=self.show))
        self.frames += 1
        self._last_time = time

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        """A frame when one is due (half a control period early: robot time sums float periods)."""
        if step.time >= self._next - run.period / 2:
            self._emit(run, step.time)
            while self._next <= step.time + run.period / 2:
                self._next += self.every

    def on_robot_step(self, run: ExplorationRun, robot: int, step: StepEvent) -> None:
        """A team run: a frame when one is due, once every robot has stepped at that time (at the step of the
        last robot still exploring: the frame shows the whole team's tick, and its title the team's totals)."""
        if ends_team_tick(run, robot):
            self.on_step(run, step)

    def on_end(self, run: ExplorationRun, record: RunRecord) -> None:
        """The final frame, unless the last one shows that instant already."""
        if run.robot_time > self._last_time:
            self._emit(run, run.robot_time)


class PngFrames:
    """A frame sink writing `folder/frame_000001.png`, ... (the folder is made)."""

    def __init__(self, folder: Path) -> None:
        from robotexp.output.safefile import writable_folder

        writable_folder(folder, "--frames")
        self.folder = folder
        self.count = 0

    def __call__(self, image: Image.Image) -> None:
        from robotexp.output.render import save_png

        self.count += 1
        save_png(image, self.folder / f"frame_{self.count:06d}.png")


def check_video_path(path: Path) -> None:
    """Raise ConfigError unless `path` is an .mp4 or .gif in an existing folder and the writer it needs
    is installed (the `video` extra)."""
    from robotexp.extras import require

    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise ConfigError(f"-o {path}: a video is an .mp4 or a .gif file; name it run.mp4 or run.gif")
    if path.parent.exists() and not path.parent.is_dir():
        raise ConfigError(f"-o {path}: {path.parent} is a file, not a folder")
    if not path.parent.is_dir():
        raise ConfigError(f"-o {path}: folder {path.parent} does not exist; create it first")
    if path.is_dir():
        raise ConfigError(f"-o {path}: a folder of that name is there; name the video another way")
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise ConfigError(f"-o {path}: folder {path.parent} is not writable; choose another")
    require("imageio", f"a video ({path.name})")
    if path.suffix.lower() == ".mp4":
        require("imageio_ffmpeg", f"an MP4 video ({path.name})")


MIN_FPS, MAX_FPS = 0.1, 120.0   # [frames/s] a video's frame rate (a frame at most every 10 s)


def check_fps(fps: float) -> None:
    """Raise ConfigError unless `fps` is within MIN_FPS..MAX_FPS."""
    if not (math.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
        raise ConfigError(f"--fps must be within {MIN_FPS:g}..{MAX_FPS:g} frames per second, got {fps:g}")


def _padded(image: Image.Image) -> npt.NDArray[np.uint8]:
    """The image's pixels, padded with white to multiples of BLOCK (so ffmpeg never rescales)."""
    px = np.asarray(image.convert("RGB"), np.uint8)
    h, w = px.shape[:2]
    out = np.full((-(-h // BLOCK) * BLOCK, -(-w // BLOCK) * BLOCK, 3), 255, np.uint8)
    out[:h, :w] = px
    return out


class _GifStream:
    """A GIF written frame by frame (a local palette each, looping forever): only the frame at hand
    is in memory, however long the video."""

    def __init__(self, path: Path, duration_ms: float) -> None:
        self.file = open(path, "wb")
        self.duration = duration_ms
        self.started = False

    def append(self, px: npt.NDArray[np.uint8]) -> None:
        from PIL import GifImagePlugin, Image

        frame = Image.fromarray(px, "RGB").quantize(256, method=Image.Quantize.MEDIANCUT)
        if not self.started:
            header, _ = GifImagePlugin.getheader(frame.copy(), info={"loop": 0, "duration": self.duration})
            self.file.write(b"".join(header))
            self.started = True
        for part in GifImagePlugin.getdata(frame, (0, 0), duration=self.duration, include_color_table=True):
            self.file.write(part)

    def close(self) -> None:
        try:
            if self.started:
                self.file.write(b";")
        finally:
            self.file.close()


class VideoWriter:
    """A frame sink encoding an MP4 (H.264 through imageio-ffmpeg's own ffmpeg) or a GIF (Pillow's GIF
    encoder, frame by frame), at `fps` frames per second; each frame is written as it comes, to a hidden file
    beside `path` that replaces `path` once the video is finished (an error or Ctrl-C on the way leaves a
    video already at `path` as it was, and no partial one). Use it as a context manager."""

    def __init__(self, path: Path, fps: float = 10.0) -> None:
        check_video_path(path)
        check_fps(fps)
        self.path, self.fps = path, fps
        self.partial = path.with_name(f".{path.stem}.partial{path.suffix}")     # the suffix picks the format
        self.count = 0
        self.gif = path.suffix.lower() == ".gif"
        self._writer: Any = None
        self._size: tuple[int, int] | None = None

    def __call__(self, image: Image.Image) -> None:
        px = _padded(image)
        if self._size is None:
            self._size = (px.shape[1], px.shape[0])
        elif (px.shape[1], px.shape[0]) != self._size:
            raise ConfigError(f"video {self.path}: frame of {px.shape[1]} x {px.shape[0]} px after "
                              f"{self._size[0]} x {self._size[1]}; every frame must have one size")
        self.count += 1
        if self._writer is None:
            if self.gif:
                self._writer = _GifStream(self.partial, 1000.0 / self.fps)
            else:
                import imageio.v2 as iio

                self._writer = iio.get_writer(self.partial, format="FFMPEG", fps=self.fps, codec="libx264",
                                              quality=7, macro_block_size=BLOCK, ffmpeg_log_level="error")
        if self.gif:
            self._writer.append(px)
        else:
            self._writer.append_data(px)

    def close(self) -> None:
        """Finish the file and put it at `path`. Raises ConfigError when no frame came."""
        if self._writer is not None:
            writer, self._writer = self._writer, None
            try:
                writer.close()
            except BaseException:
                self.partial.unlink(missing_ok=True)
                raise
            os.replace(self.partial, self.path)
        if self.count == 0:
            raise ConfigError(f"video {self.path}: no frame was rendered")

    def discard(self) -> None:
        """Drop the video being written (`path` stays as it was)."""
        if self._writer is not None:
            writer, self._writer = self._writer, None
            try:
                writer.close()
            finally:
                self.partial.unlink(missing_ok=True)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        if exc[0] is None:
            self.close()
        else:
            self.discard()
