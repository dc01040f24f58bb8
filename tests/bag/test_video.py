"""Video: `robotexp video` of a recording writes an MP4 and a GIF that play back (the wheel's ffmpeg
decodes every MP4 frame, imageio every GIF frame, of the size the frames were drawn at);
`explore --frames` saves PNG frames during a run."""

from __future__ import annotations

import subprocess
from pathlib import Path

import imageio.v3 as iio3
import imageio_ffmpeg
import numpy as np
from click.testing import CliRunner
from PIL import Image

from robotexp.bag.replay import read_bag
from robotexp.cli import main
from robotexp.mapping.geometry import GridGeometry
from robotexp.output.render import map_layout
from robotexp.output.video import BLOCK, FRAME_SIZE


def _frame_size(bag: Path) -> tuple[int, int]:
    """(width, height) [px] of a frame of the recorded grid, padded to macro blocks."""
    meta = read_bag(bag).meta
    assert meta is not None
    g = meta["grid"]
    lay = map_layout(GridGeometry(g["origin_x"], g["origin_y"], g["cell"], g["rows"], g["cols"]), title="t",
                     max_size=FRAME_SIZE)
    return -(-lay.image_width // BLOCK) * BLOCK, -(-lay.image_height // BLOCK) * BLOCK


def _decode_mp4(path: Path, width: int, height: int) -> list[np.ndarray]:
    """Every frame of an MP4 decoded by the wheel's ffmpeg (imageio's reader leaves its pipes open),
    checking the stream's size and rate on the way."""
    out = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(path), "-f", "rawvideo",
                          "-pix_fmt", "rgb24", "-"], capture_output=True, timeout=60, check=True)
    info = out.stderr.decode(errors="replace")
    assert f"{width}x{height}" in info and "h264" in info and " 5 fps" in info, info
    raw = np.frombuffer(out.stdout, np.uint8)
    assert raw.size % (width * height * 3) == 0
    return list(raw.reshape(-1, height, width, 3))


def test_video_mp4_and_gif(recorded: tuple[Path, dict[str, object]], tmp_path: Path) -> None:
    bag, _ = recorded
    width, height = _frame_size(bag)
    # a frame every 2 s of the 25 s run: 0, 2, ..., 24 and the end at 25 s
    for name in ("run.mp4", "run.gif"):
        res = CliRunner().invoke(main, ["video", str(bag), "-o", str(tmp_path / name), "--every", "2", "--fps", "5"])
        assert res.exit_code == 0, res.output
        assert "14 frames" in res.output
    mp4 = _decode_mp4(tmp_path / "run.mp4", width, height)
    assert len(mp4) == 14
    gif = iio3.imread(tmp_path / "run.gif", index=None)
    assert gif.shape == (14, height, width, 3)
    # the map grows: more white (free) pixels at the end than at the start, in both
    for frames in (mp4, list(gif)):
        white = [int(np.count_nonzero(np.all(f > 240, axis=2))) for f in (frames[0], frames[-1])]
        assert white[1] > white[0] * 1.5


def test_video_bad_input(recorded: tuple[Path, dict[str, object]], tmp_path: Path) -> None:
    bag, _ = recorded
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(tmp_path / "run.avi")])
    assert res.exit_code == 2 and "mp4 or a .gif" in res.output
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(tmp_path / "v.gif"), "--every", "0"])
    assert res.exit_code == 2 and "--every" in res.output


def test_explore_frames(recorded: tuple[Path, dict[str, object]]) -> None:
    bag, _ = recorded
    frames = sorted((bag.parent / "frames").glob("frame_*.png"))
    # every 5 s of the 25 s run: 0, 5, 10, 15, 20, 25
    assert [f.name for f in frames] == [f"frame_{i:06d}.png" for i in range(1, 7)]
    sizes = set()
    for f in frames:
        with Image.open(f) as im:
            sizes.add(im.size)
    assert len(sizes) == 1


def test_frames_draw_the_explorers_overlays() -> None:
    """explore --frames with --show potential: the frames carry the BVP potential (viridis on free cells)."""
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment
    from robotexp.output.render import viridis
    from robotexp.output.video import FrameObserver

    shown: list[np.ndarray] = []
    plain: list[np.ndarray] = []
    spec = RunSpec(world="ufmg-static", method="bvp", max_time=4.0)
    run_experiment(spec, None, observers=[FrameObserver(lambda im: shown.append(np.asarray(im)), 2.0, ("potential",)),
                                          FrameObserver(lambda im: plain.append(np.asarray(im)), 2.0)])
    assert len(shown) == len(plain) == 3
    ends = {tuple(int(c) for c in viridis(np.array([v]))[0]) for v in (0.0, 1.0)}

    def count(img: np.ndarray) -> int:
        return sum(int(np.count_nonzero(np.all(img == np.array(c, np.uint8), axis=2))) for c in ends)

    assert count(shown[-1]) > 100 and count(plain[-1]) == 0
