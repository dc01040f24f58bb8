"""Optional install extras: code that needs a package of `robotexp[cluster]` or `robotexp[video]` says in
one line which extra to install (exit 2), before any work starts."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.cli import main


@pytest.mark.parametrize("missing", ["dask", "distributed"])
def test_cluster_without_dask_names_the_extra(missing: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, missing, None)         # import fails as if not installed
    camp = tmp_path / "c.yaml"
    camp.write_text("name: c\nworlds: [dense]\nmethods: [frontier]\n")
    result = CliRunner().invoke(main, ["campaign", "run", str(camp), "--cluster", "local:1", "--out",
                                       str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines() == [
        f"robotexp: error: --cluster local:1 needs {missing}, which the base install leaves out; install it with "
        "pip install 'robotexp[cluster]'"]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("missing", "name", "dist"), [("imageio", "run.gif", "imageio"),
                                                        ("imageio_ffmpeg", "run.mp4", "imageio-ffmpeg")])
def test_video_without_imageio_names_the_extra(missing: str, name: str, dist: str, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, missing, None)
    bag = tmp_path / "run.mcap"
    bag.write_bytes(b"")
    result = CliRunner().invoke(main, ["video", str(bag), "-o", str(tmp_path / name)])
    assert result.exit_code == 2, result.output
    (line,) = result.output.strip().splitlines()
    assert line.endswith(f"needs {dist}, which the base install leaves out; install it with "
                         "pip install 'robotexp[video]'"), line
