"""A GIF video is written frame by frame: memory stays at about one frame however many frames come,
and the file plays back every frame."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import imageio.v3 as iio3
import numpy as np
from PIL import Image

from robotexp.output.video import VideoWriter


def test_gif_frames_are_not_kept(tmp_path: Path) -> None:
    size = 320                                  # 320 x 320 RGB: 0.3 MB a frame, 18 MB for 60
    frames = 60
    base = np.full((size, size, 3), 255, np.uint8)
    tracemalloc.start()
    try:
        with VideoWriter(tmp_path / "v.gif", fps=10) as writer:
            for i in range(frames):
                px = base.copy()
                px[:, : (i + 1) * size // frames] = (200, 80, 20)      # an orange bar that grows
                writer(Image.fromarray(px))
                del px
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 6 * size * size * 3, peak     # a few frames' worth, not 60
    gif = iio3.imread(tmp_path / "v.gif", index=None)
    assert gif.shape == (frames, size, size, 3)
    orange = [int(np.count_nonzero(np.all(np.abs(f.astype(int) - (200, 80, 20)) < 12, axis=2))) for f in gif]
    assert orange[0] == size * (size // frames) and orange[-1] == size * size
    assert all(a < b for a, b in zip(orange, orange[1:], strict=False))
