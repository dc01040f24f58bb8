"""The figures every run writes (robotexp.output.figures on matplotlib): the map with its legend, scale bar, crop and
the estimated path beside the true one under odometry error, the coverage curve with units, the formats asked
for, and drawing from several threads at once."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from robotexp.cli import main
from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.output.figures import DPI, PAGE_WIDTH, map_figure, run_coverage_figure, run_map_figure, save_figure
from robotexp.mapping.geometry import GridGeometry
from robotexp.output.render import COLORS
from robotexp.robot import Pose


def _legend(fig) -> list[str]:
    return [t.get_text() for leg in fig.legends for t in leg.get_texts()]


@pytest.fixture(scope="module")
def localized_run(tmp_path_factory: pytest.TempPathFactory):
    out = tmp_path_factory.mktemp("loc")
    # without localization the odometry's drift keeps the estimated path centimetres from the true one (scan
    # matching holds it within the 1 cm under which the figure draws one path)
    return out, run_experiment(RunSpec(world="ufmg-static", method="frontier", max_time=25, odometry="p3dx",
                                       localize="none"), out)


def test_a_run_with_odometry_error_shows_the_estimated_and_the_true_path(localized_run) -> None:
    out, res = localized_run
    assert res.image == out / f"{res.record.run}.png" and res.plot == out / f"{res.record.run}.coverage.png"
    with Image.open(res.image) as im:
        assert im.width == round(PAGE_WIDTH * DPI)
    fig = run_map_figure(res.run)
    labels = _legend(fig)
    assert "true path" in labels and "estimated path" in labels and "path" not in labels
    ax = fig.axes[0]
    true, est = (np.array(line.get_xydata()) for line in ax.lines[:2])
    np.testing.assert_allclose(true, np.array(res.run.metrics.path))
    np.testing.assert_allclose(est, np.array(res.run.metrics.estimated))
    assert np.hypot(*(est - true).T).max() > 0.01                  # they differ: the odometry drifts
    assert res.record["localize"] == "none" and res.record["ate_m"] > 0
    assert "ATE" in ax.get_title("left") and "ufmg-static - frontier" in ax.get_title("left")


def test_a_run_without_localization_error_shows_one_path(tmp_path: Path) -> None:
    res = run_experiment(RunSpec(world="ufmg-static", method="frontier", max_time=10), tmp_path, image=False)
    assert res.image is None and not (tmp_path / f"{res.record.run}.png").exists()
    fig = run_map_figure(res.run)
    labels = _legend(fig)
    assert labels[:3] == ["free", "occupied", "unknown"] and "path" in labels and "estimated path" not in labels
    assert "start" in labels and "end" in labels
    ax = fig.axes[0]
    pts = np.array(res.run.metrics.path)
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x0 <= pts[:, 0].min() and pts[:, 0].max() <= x1 and y0 <= pts[:, 1].min() and pts[:, 1].max() <= y1
    assert ax.get_xlabel() == "x [m]" and "cell 100 mm" in ax.get_title("left") and "coverage" in ax.get_title("left")
    cov = run_coverage_figure(res.run)
    assert cov is not None
    cax = cov.axes[0]
    assert cax.get_ylabel() == "coverage [%] (100 mm cells)" and cax.get_xlabel() == "robot time [s]"
    assert cax.get_ylim() == (0.0, 100.0)


def test_the_view_is_cropped_to_the_content_and_the_path() -> None:
    geo = GridGeometry(0.0, 0.0, 0.05, 400, 400)                   # 20 m x 20 m, mostly unknown
    states = np.full((400, 400), -1, np.int8)
    states[100:140, 100:140] = 0                                   # a 2 m room at (5..7, 5..7) m
    path = np.array([[5.5, 5.5], [6.5, 6.5], [9.0, 6.0]])          # leaving the room eastwards
    fig = map_figure(states, geo, path=path, start=Pose(5.5, 5.5, 0.0), title="t")
    (x0, x1), (y0, y1) = fig.axes[0].get_xlim(), fig.axes[0].get_ylim()
    assert x0 <= 5.0 and x1 >= 9.0 and y0 <= 5.0 and y1 >= 7.0     # the room and the whole path
    assert x1 - x0 < 7.0 and y1 - y0 < 5.0                         # not the 20 m grid


def test_a_harmonic_potential_gets_a_log_colour_bar() -> None:
    geo = GridGeometry(0.0, 0.0, 0.1, 30, 60)
    states = np.zeros((30, 60), np.int8)
    pot = 1.0 - np.tile(np.exp(-np.linspace(0, 20, 60)), (30, 1))   # 1 - p from 1 down to 2e-9
    fig = map_figure(states, geo, potential=pot, title="t")
    bar = fig.axes[1]
    assert "log" in bar.get_ylabel() and bar.get_yscale() == "log"


def test_explore_writes_the_formats_asked_and_refuses_others(tmp_path: Path) -> None:
    args = ["explore", "--world", "ufmg-static", "--max-time", "5", "--out", str(tmp_path)]
    res = CliRunner().invoke(main, [*args, "--image-format", "png,svg,pdf"])
    assert res.exit_code == 0, res.output
    (png,) = tmp_path.glob("*_s0.png")
    stem = png.name[:-4]
    for name in (f"{stem}.svg", f"{stem}.pdf", f"{stem}.coverage.png", f"{stem}.coverage.svg", f"{stem}.coverage.pdf"):
        assert (tmp_path / name).is_file(), name
    svg = (tmp_path / f"{stem}.svg").read_text()
    assert "ufmg-static - frontier" in svg and "obstacle not mapped" in svg and " m<" in svg    # scale bar label
    assert (tmp_path / f"{stem}.pdf").read_bytes().startswith(b"%PDF")
    bad = CliRunner().invoke(main, [*args, "--image-format", "png,jpg"])
    assert bad.exit_code == 2 and "--image-format" in bad.output


def test_figures_drawn_from_threads_at_once(tmp_path: Path) -> None:
    geo = GridGeometry(0.0, 0.0, 0.1, 50, 80)
    states = np.zeros((50, 80), np.int8)
    states[:, :3] = 100
    errors: list[BaseException] = []

    def draw(k: int) -> None:
        try:
            for i in range(2):
                save_figure(map_figure(states, geo, title=f"t{k}"), tmp_path / f"f{k}_{i}", ("png", "svg"))
        except BaseException as exc:      # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=draw, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for k in range(2):
        assert f">t{k}<" in (tmp_path / f"f{k}_1.svg").read_text() or f"t{k}" in (tmp_path / f"f{k}_1.svg").read_text()
        with Image.open(tmp_path / f"f{k}_1.png") as im:
            assert im.width == round(PAGE_WIDTH * DPI)


def test_a_users_matplotlib_settings_do_not_change_the_figures(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import matplotlib

    geo = GridGeometry(0.0, 0.0, 0.1, 50, 80)
    for key, value in (("savefig.bbox", "tight"), ("savefig.dpi", 50), ("font.size", 30.0)):
        monkeypatch.setitem(matplotlib.rcParams, key, value)
    fig = map_figure(np.zeros((50, 80), np.int8), geo, title="t")
    (png,) = save_figure(fig, tmp_path / "m", ("png",))
    with Image.open(png) as im:
        assert im.width == round(PAGE_WIDTH * DPI)
    assert fig.axes[0].xaxis.label.get_fontsize() == 9.0                 # FONT_SIZE, not the 30 pt set above
    assert matplotlib.rcParams["savefig.bbox"] == "tight"        # the user's settings are left as they were


def test_the_show_overlays_are_drawn_on_the_figure(tmp_path: Path) -> None:
    from matplotlib.collections import LineCollection
    from matplotlib.quiver import Quiver

    res = run_experiment(RunSpec(world="ufmg-static", method="bvp", max_time=8), tmp_path, image=False)
    fig = run_map_figure(res.run, show=("grid", "laser", "vectors", "potential"))
    ax = fig.axes[0]
    assert "laser" in _legend(fig) and len(fig.axes) == 2                 # the potential's colour bar
    assert any(isinstance(c, Quiver) for c in ax.collections)             # the vector field
    assert sum(isinstance(c, LineCollection) for c in ax.collections) == 2   # grid lines, both ways
    plain = run_map_figure(res.run)
    assert len(plain.axes) == 1 and not plain.axes[0].collections and "laser" not in _legend(plain)


def test_a_log_map_shows_the_logged_and_the_estimated_path(tmp_path: Path) -> None:
    from robotexp.localization.carmen import flaser_angles, format_flaser
    from robotexp.world.builtin import builtin_world
    from robotexp.world.raycast import RayIndex

    world = builtin_world("dense")
    index = RayIndex(world.boxes, world.discs, 2.0)
    angles = flaser_angles(181)
    lines = ["PARAM robot_front_laser_max 81.91 nohost 0"]
    for k in range(40):                                           # along the corridor, 0.15 m a scan
        p = Pose(-8.0 + 0.15 * k, 7.5, 0.0)
        frac = index.cast(np.tile([p.x, p.y], (181, 1)), p.theta + angles, 8.0, 0.3)
        lines.append(format_flaser(np.where(frac >= 1.0, 81.91, frac * 8.0), p, p, float(k)))
    log = tmp_path / "corridor.log"
    log.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["map", str(log), "--out", str(out), "--odometry-noise", "0.05,5",
                                    "--localize", "none"])
    assert res.exit_code == 0, res.output
    with Image.open(out / "corridor.png") as im:
        assert im.width == round(PAGE_WIDTH * DPI)
        px = np.asarray(im.convert("RGB")).astype(int)

    def count(rgb: tuple[int, int, int]) -> int:
        return int((np.abs(px - np.array(rgb)).max(axis=2) <= 30).sum())

    assert count(COLORS["path"]) > 200 and count(COLORS["laser"]) > 100   # the logged and the estimated path


def test_a_team_figure_names_each_robot_and_keeps_every_path_in_view() -> None:
    geo = GridGeometry(0.0, 0.0, 0.05, 400, 400)
    states = np.full((400, 400), -1, np.int8)
    states[100:140, 100:140] = 0
    one = np.array([[5.5, 5.5], [6.5, 6.5]])
    two = np.array([[5.6, 5.5], [12.0, 15.0]])                      # far out of the room: the view follows it
    three = np.array([[5.7, 5.5], [6.0, 5.0], [np.nan, np.nan]])     # a NaN row is left out
    fig = map_figure(states, geo, path=one, others=[two, three], start=Pose(5.5, 5.5, 0.0), end=Pose(6.5, 6.5, 0.0))
    labels = _legend(fig)
    assert [t for t in labels if t.startswith("robot")] == ["robot 1", "robot 2", "robot 3"] and "path" not in labels
    assert fig.axes[0].get_xlim()[1] >= 12.0 and fig.axes[0].get_ylim()[1] >= 15.0
    handles = {h.get_label(): h.get_color() for leg in fig.legends for h in leg.legend_handles
               if h.get_label().startswith("robot")}
    assert len(set(handles.values())) == 3                          # a colour of its own for each robot
    drawn = {line.get_color() for line in fig.axes[0].lines}
    assert set(handles.values()) <= drawn
    alone = _legend(map_figure(states, geo, path=one))              # one robot alone keeps its legend
    assert "path" in alone and "robot 1" not in alone
