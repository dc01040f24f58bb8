import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from robotexp.errors import ConfigError, WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.world.rosmap import load_ros_grid, load_ros_world, merge_cells, save_ros_map

# A 3 x 4 grey image, top row first, chosen around the default thresholds (0.196, 0.65):
# 205 -> p = 0.19608 (just not free), 206 -> 0.19216 (free), 89 -> 0.6510 (occupied), 90 -> 0.6471
PIXELS = [[0, 254, 205, 255],
          [100, 206, 50, 89],
          [10, 240, 128, 90]]

# Expected grids, row 0 = the image's bottom row, worked out by hand from docs/maps-format.md §2
EXPECTED = {
    ("trinary", 0): [[100, 0, -1, -1], [-1, 0, 100, 100], [100, 0, -1, 0]],
    ("trinary", 1): [[0, 100, -1, -1], [-1, 100, -1, -1], [0, 100, 100, 100]],
    # scale: rint(100 (p - 0.196) / 0.454) between the thresholds, e.g. 100 -> p 0.6078 -> 90.7 -> 91
    ("scale", 0): [[100, 0, 67, 99], [91, 0, 100, 100], [100, 0, 0, 0]],
    ("scale", 1): [[0, 100, 67, 35], [43, 100, 0, 34], [0, 100, 100, 100]],
    # raw (nav2): the pixel value when <= 100, else unknown; negate is not applied
    ("raw", 0): [[10, -1, -1, 90], [100, -1, 50, 89], [0, -1, -1, -1]],
    ("raw", 1): [[10, -1, -1, 90], [100, -1, 50, 89], [0, -1, -1, -1]],
}


def pgm_p5(pixels) -> bytes:
    rows, cols = len(pixels), len(pixels[0])
    return f"P5\n# hand made\n{cols} {rows}\n255\n".encode() + bytes(v for row in pixels for v in row)


def pgm_p2(pixels) -> bytes:
    rows, cols = len(pixels), len(pixels[0])
    body = "\n".join(" ".join(str(v) for v in row) for row in pixels)
    return f"P2\n{cols} {rows}\n255\n{body}\n".encode()


def yaml_text(image="map.pgm", *, mode="trinary", negate="0", resolution="0.05",
              origin="[-1.5, 2.25, 0.0]", occupied="0.65", free="0.196") -> str:
    return (f"image: {image}\nresolution: {resolution}\norigin: {origin}\nnegate: {negate}\n"
            f"occupied_thresh: {occupied}\nfree_thresh: {free}\n" + (f"mode: {mode}\n" if mode else ""))


def write_map(folder: Path, image_bytes: bytes, yaml: str, image="map.pgm", name="map.yaml") -> Path:
    (folder / image).write_bytes(image_bytes)
    path = folder / name
    path.write_text(yaml)
    return path


@pytest.mark.parametrize("mode, negate", sorted(EXPECTED))
@pytest.mark.parametrize("encode", [pgm_p5, pgm_p2])
def test_modes_and_negate_give_the_hand_computed_grid(tmp_path, mode, negate, encode):
    path = write_map(tmp_path, encode(PIXELS), yaml_text(mode=mode, negate=str(negate)))
    values, geo = load_ros_grid(path)
    assert values.dtype == np.int8
    np.testing.assert_array_equal(values, np.array(EXPECTED[mode, negate], dtype=np.int8))
    assert geo == GridGeometry(-1.5, 2.25, 0.05, 3, 4)


def test_mode_defaults_to_trinary_and_negate_accepts_booleans(tmp_path):
    path = write_map(tmp_path, pgm_p5(PIXELS), yaml_text(mode=None, negate="true"))
    values, _ = load_ros_grid(path)
    np.testing.assert_array_equal(values, EXPECTED["trinary", 1])


def test_png_grey_rgb_and_rgba(tmp_path):
    Image.fromarray(np.array(PIXELS, dtype=np.uint8), "L").save(tmp_path / "grey.png")
    values, _ = load_ros_grid(write_map(tmp_path, (tmp_path / "grey.png").read_bytes(),
                                        yaml_text("grey.png"), image="grey.png"))
    np.testing.assert_array_equal(values, EXPECTED["trinary", 0])
    # RGB: mean 85 -> p 0.667 -> 100; mean 170 -> p 0.333 -> -1; mean 254.33 -> p 0.003 -> 0
    rgb = np.array([[[255, 0, 0], [0, 255, 255], [254, 254, 255]]], dtype=np.uint8)
    Image.fromarray(rgb, "RGB").save(tmp_path / "rgb.png")
    values, _ = load_ros_grid(write_map(tmp_path, (tmp_path / "rgb.png").read_bytes(),
                                        yaml_text("rgb.png"), image="rgb.png"))
    np.testing.assert_array_equal(values, [[100, -1, 0]])
    # RGBA, trinary averages alpha in: opaque white 255 -> free, transparent black 0 -> occupied,
    # transparent white (765 + 0) / 4 = 191.25 -> p 0.25 -> unknown; scale: not opaque -> unknown
    rgba = np.array([[[255, 255, 255, 255], [0, 0, 0, 0], [255, 255, 255, 0], [0, 0, 0, 255]]],
                    dtype=np.uint8)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "rgba.png")
    png = (tmp_path / "rgba.png").read_bytes()
    values, _ = load_ros_grid(write_map(tmp_path, png, yaml_text("rgba.png"), image="rgba.png"))
    np.testing.assert_array_equal(values, [[0, 100, -1, 100]])
    values, _ = load_ros_grid(write_map(tmp_path, png, yaml_text("rgba.png", mode="scale"),
                                        image="rgba.png"))
    np.testing.assert_array_equal(values, [[0, -1, -1, 100]])


def test_16_bit_pgm(tmp_path):
    # 0 -> black, 65535 -> white, 257 * 205 -> shade 205 exactly (unknown), 257 * 206 -> free
    samples = [0, 65535, 257 * 205, 257 * 206]
    data = b"P5\n4 1\n65535\n" + b"".join(v.to_bytes(2, "big") for v in samples)
    values, _ = load_ros_grid(write_map(tmp_path, data, yaml_text()))
    np.testing.assert_array_equal(values, [[100, 0, -1, 0]])


def test_yaml_subset_comments_quotes_block_lists_and_absolute_image(tmp_path):
    (tmp_path / "my map.pgm").write_bytes(pgm_p5(PIXELS))
    yaml = ("# saved by hand\n---\n"
        "image: \"my map.pgm\"   # quoted, with a space\n"
        "resolution: 5e-2\n"
        "origin:\n  - -1.5\n  - +2.25\n  - 0\n"
        "negate: 'false'\n"
        "occupied_thresh: .65\n"
        "free_thresh: 0.196 # the ROS 1 value\n"
        "extra:\n  nested: 1\n  other: [1, 2]\n"
        "mode: Trinary\n")
    path = tmp_path / "m.yaml"
    path.write_text(yaml)
    values, geo = load_ros_grid(path)
    np.testing.assert_array_equal(values, EXPECTED["trinary", 0])
    assert geo == GridGeometry(-1.5, 2.25, 0.05, 3, 4)
    sub = tmp_path / "sub"
    sub.mkdir()
    (sub / "abs.yaml").write_text(yaml_text(f"'{tmp_path / 'my map.pgm'}'"))
    values, _ = load_ros_grid(sub / "abs.yaml")
    np.testing.assert_array_equal(values, EXPECTED["trinary", 0])


def test_crlf_yaml(tmp_path):
    path = write_map(tmp_path, pgm_p5(PIXELS), "")
    path.write_bytes(yaml_text().replace("\n", "\r\n").encode())
    values, _ = load_ros_grid(path)
    np.testing.assert_array_equal(values, EXPECTED["trinary", 0])


@pytest.mark.parametrize("yaml, line, fragment", [
    (yaml_text().replace("resolution: 0.05\n", ""), None, "missing key 'resolution'"),
    (yaml_text().replace("image: map.pgm\n", ""), None, "missing key 'image'"),
    (yaml_text().replace("negate: 0\n", ""), None, "missing key 'negate'"),
    (yaml_text().replace("free_thresh: 0.196\n", ""), None, "missing key 'free_thresh'"),
    (yaml_text(resolution="0.05m"), 2, "key 'resolution': bad number '0.05m'"),
    (yaml_text(resolution="1_0"), 2, "key 'resolution': bad number"),
    (yaml_text(resolution="0"), 2, "key 'resolution': 0 m/pixel is out of range"),
    (yaml_text(resolution="1e-300"), 2, "key 'resolution': 1e-300 m/pixel is out of range"),
    (yaml_text(resolution="1e300"), 2, "key 'resolution': 1e+300 m/pixel is out of range"),
    (yaml_text(resolution="1e6"), 2, "the map reaches"),
    (yaml_text(origin="[1e308, 0.0, 0.0]"), 3, "key 'origin': (1e+308, 0) m is beyond"),
    (yaml_text(resolution="-0.1"), 2, "key 'resolution'"),
    (yaml_text(origin="[1.0, 2.0]"), 3, "key 'origin'"),
    (yaml_text(origin="1.0"), 3, "key 'origin'"),
    (yaml_text(origin="[1.0, x, 0]"), 3, "key 'origin': bad number 'x'"),
    (yaml_text(origin="[0, 0, 0.5]"), 3, "yaw 0.5 is not supported"),
    (yaml_text(origin="[0, 0, 0"), 3, "not valid YAML (while parsing a flow sequence"),
    (yaml_text(negate="2"), 4, "key 'negate'"),
    (yaml_text(occupied="1.5"), 5, "key 'occupied_thresh': 1.5 is outside [0, 1]"),
    (yaml_text(free="-0.1"), 6, "key 'free_thresh': -0.1 is outside [0, 1]"),
    (yaml_text(occupied="0.3", free="0.3"), 6, "free_thresh < occupied_thresh"),
    (yaml_text(occupied="nan"), 5, "key 'occupied_thresh': bad number"),
    (yaml_text(mode="fancy"), 7, "key 'mode': unknown mode 'fancy'"),
    (yaml_text("nothere.pgm"), 1, "key 'image': image"),
    (yaml_text("''"), 1, "key 'image' is empty"),
    (yaml_text('"map.pgm'), 1, "while scanning a quoted scalar"),
    (yaml_text() + "resolution: 0.1\n", 8, "key 'resolution' repeated (first on line 2)"),
    (yaml_text() + "just words\n", 8, "could not find expected ':'"),
    ("  indented: 1\n" + yaml_text(), 2, "not valid YAML"),
    (yaml_text().replace("negate: 0", "negate: {a: 1}"), 4, "key 'negate': '{a: 1}' is not a value"),
    ("- image\n- map.pgm\n", 1, "is not a mapping"),
    (yaml_text().replace("image: map.pgm", "image: [a, b]"), 1, "key 'image' is a list"),
])
def test_bad_yaml_names_file_line_and_key(tmp_path, yaml, line, fragment):
    path = write_map(tmp_path, pgm_p5(PIXELS), yaml)
    with pytest.raises(WorldError) as info:
        load_ros_grid(path)
    message = str(info.value)
    prefix = f"{path}:{line}: " if line is not None else f"{path}: "
    assert message.startswith(prefix), message
    assert fragment in message, message


def test_flow_style_and_nested_keys_read_as_map_server_reads_them(tmp_path):
    """The same map in YAML's flow style, with comments, quotes, a block list and a nested mapping under a key
    map_server does not read: the same grid and geometry as the plain block-style file."""
    block = write_map(tmp_path, pgm_p5(PIXELS), yaml_text())
    plain = load_ros_grid(block)
    flow = tmp_path / "flow.yaml"
    flow.write_text("# a map in flow style\n{image: 'map.pgm', resolution: 0.05, origin: [-1.5, 2.25, 0.0],\n"
                    " negate: 0, occupied_thresh: 0.65, free_thresh: 0.196, mode: trinary}\n")
    listed = tmp_path / "listed.yaml"
    listed.write_text('image: "map.pgm"\nresolution: 0.05\norigin:\n  - -1.5\n  - 2.25\n  - 0.0\nnegate: 0\n'
                      "occupied_thresh: 0.65   # ROS defaults\nfree_thresh: 0.196\nmode: trinary\n"
                      "extra:\n  made_by: someone\n  date: [2024, 1, 1]\n")
    for path in (flow, listed):
        values, geo = load_ros_grid(path)
        np.testing.assert_array_equal(values, plain[0])
        assert geo == plain[1]


def test_hostile_yaml_is_one_line(tmp_path):
    """Nesting deeper than Python's recursion and a file far larger than a map YAML: a WorldError each."""
    path = tmp_path / "deep.yaml"
    path.write_text("image: " + "[" * 20000 + "]" * 20000 + "\n")
    with pytest.raises(WorldError, match="nested too deeply"):
        load_ros_grid(path)
    path.write_text(yaml_text() + "# padding\n" * 200_000)
    with pytest.raises(WorldError, match="expected a map_server .yaml file of at most"):
        load_ros_grid(path)


def test_unreadable_files(tmp_path):
    with pytest.raises(WorldError, match="cannot read the map YAML"):
        load_ros_grid(tmp_path / "none.yaml")
    path = write_map(tmp_path, b"this is not an image", yaml_text())
    with pytest.raises(WorldError, match=r"map\.yaml:1: key 'image': cannot read image"):
        load_ros_grid(path)
    path.write_bytes(b"image: map.pgm\nresolution: \xff\n")
    with pytest.raises(WorldError, match=r"map\.yaml:2: not UTF-8"):
        load_ros_grid(path)
    path.write_bytes(b"image: map.pgm\x00\n")
    with pytest.raises(WorldError, match=r"map\.yaml:1: NUL byte"):
        load_ros_grid(path)
    (tmp_path / "map.pgm").write_bytes(pgm_p5(PIXELS)[:-3])       # truncated pixel data
    path.write_text(yaml_text())
    with pytest.raises(WorldError, match="cannot read image"):
        load_ros_grid(path)


def test_save_writes_ros1_map_saver_files_byte_for_byte(tmp_path):
    values = np.array([[0, 100], [-1, 0]], dtype=np.int8)        # row 0 is the bottom
    save_ros_map(tmp_path / "t.yaml", values, GridGeometry(-1.5, 2.0, 0.05, 2, 2))
    assert (tmp_path / "t.pgm").read_bytes() == (
        b"P5\n# CREATOR: robotexp 0.050 m/pix\n2 2\n255\n" + bytes([205, 254, 254, 0]))
    assert (tmp_path / "t.yaml").read_text() == (
        "image: t.pgm\nresolution: 0.05\norigin: [-1.5, 2.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n")


def test_save_maps_other_values_to_unknown(tmp_path):
    values = np.array([[0, 100, 50, -1, 99, 1]], dtype=np.int8)
    save_ros_map(tmp_path / "o.yaml", values, GridGeometry(0.0, 0.0, 0.1, 1, 6))
    assert (tmp_path / "o.pgm").read_bytes()[-6:] == bytes([254, 0, 205, 205, 205, 205])
    loaded, _ = load_ros_grid(tmp_path / "o.yaml")
    np.testing.assert_array_equal(loaded, [[0, 100, -1, -1, -1, -1]])


@pytest.mark.parametrize("seed", range(4))
def test_save_then_load_round_trips_exactly(tmp_path, seed):
    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(1, 40, size=2)
    values = rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(rows, cols))
    geo = GridGeometry(float(rng.normal() * 100), float(rng.normal() * 1e-7),
                       float(rng.choice([0.05, 0.1, 1 / 3, 1e-5, 0.025])), int(rows), int(cols))
    name = "map with space.pgm" if seed % 2 else None
    save_ros_map(tmp_path / "rt.yaml", values, geo, image_name=name)
    loaded, loaded_geo = load_ros_grid(tmp_path / "rt.yaml")
    assert loaded.dtype == np.int8
    np.testing.assert_array_equal(loaded, values)
    assert loaded_geo == geo


def test_save_rejects_bad_arguments(tmp_path):
    geo = GridGeometry(0.0, 0.0, 0.1, 2, 3)
    with pytest.raises(ConfigError, match=r"shape \(3, 2\)"):
        save_ros_map(tmp_path / "a.yaml", np.zeros((3, 2), np.int8), geo)
    with pytest.raises(ConfigError, match="image_name"):
        save_ros_map(tmp_path / "a.yaml", np.zeros((2, 3), np.int8), geo, image_name='a"b.pgm')
    with pytest.raises(ConfigError, match="geo.cell"):
        save_ros_map(tmp_path / "a.yaml", np.zeros((2, 3), np.int8), geo._replace(cell=0.0))
    with pytest.raises(WorldError, match="cannot write"):
        save_ros_map(tmp_path / "missing" / "a.yaml", np.zeros((2, 3), np.int8), geo)


def test_load_ros_world_merges_cells_into_the_hand_computed_boxes(tmp_path):
    values = np.array([[100, 100, 100, 100, 100, 100],       # row 0, the bottom
                       [100, 0, 0, 0, 0, 100],
                       [100, 0, 100, 100, 0, 100],
                       [100, 0, 100, 100, 0, -1],
                       [100, 100, 100, 100, 100, -1]], dtype=np.int8)
    save_ros_map(tmp_path / "rooms.yaml", values, GridGeometry(-1.0, 2.0, 0.5, 5, 6))
    world = load_ros_world(tmp_path / "rooms.yaml")
    expected = {(0.5, 2.25, 1.5, 0.25, 0.0), (0.5, 4.25, 1.5, 0.25, 0.0),
                (-0.75, 3.25, 0.25, 0.75, 0.0), (1.75, 3.25, 0.25, 0.75, 0.0),
                (0.5, 3.5, 0.5, 0.5, 0.0)}
    assert {tuple(map(float, b)) for b in world.boxes} == expected
    assert world.bounds == (-1.0, 2.0, 2.0, 4.5)
    assert world.name == "rooms" and world.source == str(tmp_path / "rooms.yaml")
    assert "5 boxes" in world.description


def test_load_ros_world_without_obstacles_is_refused(tmp_path):
    save_ros_map(tmp_path / "e.yaml", np.zeros((3, 3), np.int8), GridGeometry(0.0, 0.0, 0.1, 3, 3))
    with pytest.raises(WorldError, match=r"e\.yaml: the map has no occupied or unknown cell"):
        load_ros_world(tmp_path / "e.yaml")


def test_a_map_without_a_free_cell_is_refused_with_what_to_check(tmp_path):
    # every cell occupied or unknown (a white-on-black image read without negate, a raw image): one line that says
    # so, before any start pose is searched for
    values = np.full((4, 5), 100, np.int8)
    values[1:3, 1:3] = -1
    save_ros_map(tmp_path / "w.yaml", values, GridGeometry(0.0, 0.0, 0.1, 4, 5))
    with pytest.raises(WorldError, match=r"w\.yaml: the map has no free cell \(16 occupied, 4 unknown\): is its "
                                         r"negate, mode or free_thresh right"):
        load_ros_world(tmp_path / "w.yaml")


def test_a_map_of_noise_is_refused_before_its_cells_are_merged(tmp_path, monkeypatch):
    # a checkerboard: every blocked cell its own rectangle (4000 x 4000 pixels: 8 million boxes, which took
    # tens of seconds and gigabytes before the default start found no room); refused from a cheap count
    import robotexp.world.rosmap as rosmap

    side = 60
    board = (np.indices((side, side)).sum(axis=0) % 2 * 254).astype(np.uint8)
    Image.fromarray(board).save(tmp_path / "board.png")
    (tmp_path / "board.yaml").write_text("image: board.png\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
                                         "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    monkeypatch.setattr(rosmap, "MAX_BOXES", side * side // 2 - 1)

    def never(mask: np.ndarray) -> np.ndarray:
        raise AssertionError("merged")
    monkeypatch.setattr(rosmap, "merge_cells", never)
    with pytest.raises(WorldError, match=r"board\.yaml: the map's occupied and unknown cells make at least 1800 "
                                         r"separate rectangles, more than the 1799 .*Threshold it"):
        load_ros_world(tmp_path / "board.yaml")
    monkeypatch.setattr(rosmap, "MAX_BOXES", side * side // 2)            # at the limit: loaded
    monkeypatch.setattr(rosmap, "merge_cells", merge_cells)
    assert len(load_ros_world(tmp_path / "board.yaml").boxes) == side * side // 2


def paint(rects: np.ndarray, shape) -> np.ndarray:
    count = np.zeros(shape, dtype=np.int64)
    for r0, r1, c0, c1 in rects:
        assert r0 < r1 and c0 < c1
        count[r0:r1, c0:c1] += 1
    return count


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.integers(1, 12), st.integers(0, 2**32 - 1), st.floats(0.0, 1.0))
def test_merge_cells_covers_the_mask_exactly_once(rows, cols, seed, density):
    mask = np.random.default_rng(seed).random((rows, cols)) < density
    rects = merge_cells(mask)
    assert rects.dtype == np.int64 and rects.shape[1] == 4
    np.testing.assert_array_equal(paint(rects, mask.shape), mask.astype(np.int64))


def test_merge_cells_keeps_a_1000_by_1000_office_map_to_a_few_thousand_boxes():
    n = 1000
    rr, cc = np.mgrid[0:n, 0:n]
    walls = np.zeros((n, n), dtype=bool)
    for k in range(100, n, 100):                                     # walls every 5 m, 3 cells
        walls[k:k + 3, :] = True
        walls[:, k:k + 3] = True
    for k in range(150, n, 100):                                     # 2 m doors in the walls
        for j in range(100, n, 100):
            walls[k - 20:k + 20, j:j + 3] = False
            walls[j:j + 3, k - 20:k + 20] = False
    blocked = walls | ((rr - 500) ** 2 + (cc - 500) ** 2 > 480 ** 2)  # unknown outside a disc
    rng = np.random.default_rng(0)
    for _ in range(200):                                             # furniture
        r, c = rng.integers(0, n - 30, size=2)
        blocked[r:r + rng.integers(5, 30), c:c + rng.integers(5, 30)] = True
    rects = merge_cells(blocked)
    np.testing.assert_array_equal(paint(rects, blocked.shape), blocked.astype(np.int64))
    assert len(rects) < 5000, len(rects)


def test_merge_cells_empty_and_full():
    assert merge_cells(np.zeros((3, 4), bool)).shape == (0, 4)
    np.testing.assert_array_equal(merge_cells(np.ones((3, 4), bool)), [[0, 3, 0, 4]])


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edits=st.lists(st.tuples(st.integers(0, 500), st.integers(0, 3), st.binary(max_size=3)),
                      max_size=5),
       target=st.sampled_from(["yaml", "pgm"]))
def test_fuzz_mutated_yaml_or_image_gives_a_grid_or_world_error(tmp_path, edits, target):
    path = write_map(tmp_path, pgm_p5(PIXELS), yaml_text())
    victim = path if target == "yaml" else tmp_path / "map.pgm"
    data = bytearray(victim.read_bytes())
    for pos, cut, insert in edits:
        pos %= len(data) + 1
        data[pos:pos + cut] = insert
    victim.write_bytes(bytes(data))
    try:
        values, geo = load_ros_grid(path)
    except WorldError as exc:
        assert str(path) in str(exc)
        return
    assert values.dtype == np.int8 and values.shape == (geo.rows, geo.cols)
    assert np.all((values >= -1) & (values <= 100))
    assert geo.cell > 0 and math.isfinite(geo.origin_x)
