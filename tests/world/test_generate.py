"""Generated worlds: deterministic bytes per seed, passable doors, scanned-map artefacts, loading by name."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ConfigError, WorldError
from robotexp.world.groundtruth import occupancy
from robotexp.mapping.kernels import clearance_mask, label8
from robotexp.world.generate import (DEFAULT_SIZES, DOOR_MIN, KINDS, expand_generated, generate_grid,
                                     parse_generated, write_generated)
from robotexp.world.loader import load_world
from robotexp.world.mobilesim import load_mobilesim
from robotexp.world.rosmap import load_ros_world


@pytest.mark.parametrize("kind", KINDS)
def test_same_seed_same_bytes_other_seed_other_bytes(tmp_path, kind):
    files = {}
    for name, seed in (("a", 4), ("b", 4), ("c", 5)):
        (tmp_path / name).mkdir()
        for suffix in (".yaml", ".map"):
            for f in write_generated(tmp_path / name / f"w{suffix}", kind, seed, scanned=True):
                files[(name, f.suffix)] = f.read_bytes()
    for suffix in (".yaml", ".pgm", ".map"):
        assert files[("a", suffix)] == files[("b", suffix)]
    assert files[("a", ".pgm")] != files[("c", ".pgm")]
    assert files[("a", ".map")] != files[("c", ".map")]


def centre_space(values: np.ndarray, geo, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Labels of the 8-connected places where a disc of `radius` fits (unknown counts as blocked), and
    the mask of the building's inside."""
    blocked = np.ascontiguousarray((values >= 50) | (values < 0))
    labels, _ = label8(clearance_mask(blocked, radius / geo.cell))
    return labels, blocked


@pytest.mark.parametrize("kind", ["office", "warehouse", "cave"])   # building: narrow doors by design
@pytest.mark.parametrize("scanned", [False, True])
def test_every_place_a_robot_fits_inside_the_building_is_one_region(kind, scanned):
    # doors and passages are >= DOOR_MIN: a robot of 0.6 m across (P3-DX plus margin) passes everywhere
    w, h = DEFAULT_SIZES[kind]
    for seed in range(3):
        values, geo = generate_grid(kind, seed, scanned=scanned)
        labels, _ = centre_space(values, geo, DOOR_MIN / 3)
        r0, c0 = geo.cell_of(0.01, 0.01)
        r1, c1 = geo.cell_of(w - 0.01, h - 0.01)
        inside = labels[r0:r1 + 1, c0:c1 + 1]
        regions = set(np.unique(inside[inside > 0]).tolist())
        assert len(regions) == 1, (kind, seed, scanned, regions)
        assert np.count_nonzero(inside) > 0.2 * inside.size       # much of the floor is open


def test_scanned_maps_have_unknown_space_around_and_a_way_out():
    for kind in ("office", "warehouse"):
        values, geo = generate_grid(kind, 0, scanned=True)
        assert values[0, 0] == -1 and values[-1, -1] == -1       # the corners of the image: unknown
        clean, _ = generate_grid(kind, 0)
        assert np.count_nonzero(clean < 0) == 0
        # the building's inside region reaches outside its walls through a gap in the outer wall
        w, h = DEFAULT_SIZES[kind]
        labels, _ = centre_space(values, geo, 0.3)
        r, c = geo.cell_of(w / 2, h / 2)
        inner = labels[geo.cell_of(w * 0.5, h * 0.5)] if labels[r, c] else None
        ys, xs = np.nonzero(labels == (inner or np.bincount(labels.ravel())[1:].argmax() + 1))
        x, y = geo.origin_x + (xs + 0.5) * geo.cell, geo.origin_y + (ys + 0.5) * geo.cell
        assert np.any((x < -0.2) | (x > w + 0.2) | (y < -0.2) | (y > h + 0.2)), kind


def test_generated_names_load_everywhere_as_the_written_maps(tmp_path):
    world = load_world("generated:office:2")
    assert world.name == "office-2" and world.collision == "index" and world.source == "generated:office:2"
    write_generated(tmp_path / "o.yaml", "office", 2)
    np.testing.assert_array_equal(world.boxes, load_ros_world(tmp_path / "o.yaml").boxes)
    # the .map holds the surface cells; the simulator meets the same faces
    values, geo = generate_grid("office", 2)
    write_generated(tmp_path / "o.map", "office", 2)
    from_points = occupancy(load_mobilesim(tmp_path / "o.map"), geo)
    occ = values >= 50
    assert np.all(occ[from_points]) and np.count_nonzero(from_points) < np.count_nonzero(occ)
    assert load_world("generated:cave:1:12x10:scanned").name == "cave-1-scanned"


def test_generated_specs_parse_expand_and_refuse_bad_ones():
    assert parse_generated("generated:office:3-5:40x30:scanned") == ("office", [3, 4, 5], (40.0, 30.0), True)
    assert expand_generated("generated:cave:0-2:scanned") == [
        "generated:cave:0:scanned", "generated:cave:1:scanned", "generated:cave:2:scanned"]
    assert expand_generated("dense") == ["dense"]
    for bad, fragment in (("generated:castle:1", "unknown kind 'castle'"), ("generated:office", "expected"),
                          ("generated:office:5-3", "empty"), ("generated:office:1:huge", "unknown option")):
        with pytest.raises(WorldError, match=fragment):
            parse_generated(bad)
    with pytest.raises(WorldError, match="range of seeds"):
        load_world("generated:office:0-3")
    with pytest.raises(ConfigError, match="size 5 x 30 m"):
        generate_grid("office", 0, (5.0, 30.0))


def test_worlds_generate_cli_writes_the_files_and_refuses_bad_input_in_one_line(tmp_path):
    out = tmp_path / "w.yaml"
    result = CliRunner().invoke(main, ["worlds", "generate", "--kind", "warehouse", "--seed", "7", "--size", "20x15",
                                       "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.is_file() and (tmp_path / "w.pgm").is_file()
    assert load_ros_world(out).bounds == pytest.approx((-0.5, -0.5, 20.5, 15.5))
    for args, fragment in ((["--size", "20"], "--size '20'"), (["--size", "3x3"], "size 3 x 3 m"),
                           (["--out", str(tmp_path / "w.png")], "unknown map format '.png'")):
        full = ["worlds", "generate", "--kind", "office", "--out", str(out), *args]
        result = CliRunner().invoke(main, full)
        assert result.exit_code == 2, result.output
        assert fragment in result.output and len(result.output.strip().splitlines()) == 1
    listing = CliRunner().invoke(main, ["worlds"])
    assert listing.exit_code == 0 and "dense" in listing.output
