"""ROS map_server maps (YAML + PGM/PNG image, docs/maps-format.md §2): load as a grid or a `World`, save.

Pixels are read as nav2's `map_io` reads them: channels averaged to a shade `x` in [0, 255]
(in trinary mode an alpha channel is averaged in too, 255 = opaque, as nav2 and ROS 1 do; so an
opaque white pixel is free and a transparent one is darker), `p = (255 - x)/255` (or `x/255`
with `negate`), then `trinary`: `p > occupied_thresh` -> 100, `p < free_thresh` -> 0, else -1;
`scale`: the same at the ends, `rint(100 (p - free)/(occ - free))` between, -1 for a
transparent pixel; `raw`: `x` rounded when in [0, 100], else -1 (nav2 ignores `negate` here).
Saving follows ROS 1 `map_saver` (binary PGM, 0 -> 254, 100 -> 0, else 205), which every ROS
tool reads back. The YAML is parsed here (the subset map files use: `key: value`, `[a, b]` and
block `- a` lists of scalars, quotes, `#` comments); there is no PyYAML dependency.
"""

from __future__ import annotations

import logging
import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError, WorldError
from robotexp.mapping.geometry import MAX_CELLS, GridGeometry
from robotexp.world.model import World

__all__ = ["load_ros_grid", "load_ros_world", "merge_cells", "save_ros_map", "world_from_grid"]

log = logging.getLogger(__name__)

_REQUIRED = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_MODES = ("trinary", "scale", "raw")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)
_PLAIN_NAME = re.compile(r"[\w./-]+", re.ASCII)
_FREE, _UNKNOWN, _OCCUPIED = 254, 205, 0     # ROS 1 map_saver pixel values
MIN_RESOLUTION = 1e-4       # [m/pixel] 0.1 mm: finer is a corrupted file
MAX_COORD = 1e6             # [m] 1000 km: a map reaching farther is a corrupted file
MAX_YAML_BYTES = 1 << 20    # a map YAML is a few lines; a larger file is not one
MAX_BOXES = 1_000_000       # obstacle rectangles of a grid map (real buildings: tens of thousands at most)


# what to check in a map's YAML when its image seems read wrong (too little of it free)
READ_WRONG = "is its negate, mode or free_thresh right for its image? (free cells are light pixels unless negate: 1)"

@dataclass(frozen=True)
class _Entry:
    """One top-level YAML value: a scalar string or a list of scalar strings, and its line."""

    value: str | list[str]
    line: int


def load_ros_grid(yaml_path: str | os.PathLike[str]
                  ) -> tuple[npt.NDArray[np.int8], GridGeometry]:
    """Load a map_server map as an occupancy grid.

    Args:
        yaml_path: the map's YAML file; its `image` is absolute or relative to the YAML's folder.

    Returns:
        `(values, geo)`: `values` int8 (rows, cols), row 0 the bottom row of the image: 0 free,
        100 occupied, -1 unknown (`scale` and `raw` modes also give 1..99); `geo` places cell
        (0, 0) at the YAML `origin` with cells of `resolution` [m].

    Raises:
        WorldError: the YAML or the image cannot be read, a required key is missing, a number
            is malformed, `origin` is not 3 numbers or has a non-zero yaw, `resolution` is outside
            [MIN_RESOLUTION, MAX_COORD] or the map reaches beyond +-MAX_COORD,
            thresholds are outside [0, 1] or `free_thresh >= occupied_thresh`, `negate` or
            `mode` is unknown. The message names the file, the line and the key.
    """
    src = str(yaml_path)
    entries = _parse_yaml(_read_text(Path(yaml_path), src), src)
    for key in _REQUIRED:
        if key not in entries:
            raise WorldError(f"{src}: missing key {key!r}, expected the map_server keys "
                             f"{', '.join(_REQUIRED)} (and optionally mode)")
    resolution = _number(entries, "resolution", src)
    if not MIN_RESOLUTION <= resolution <= MAX_COORD:
        raise WorldError(f"{src}:{entries['resolution'].line}: key 'resolution': {resolution:g} m/pixel is out of "
                         f"range, expected a cell size from {MIN_RESOLUTION:g} m to {MAX_COORD:g} m")
    origin = _origin(entries, src)
    if not all(abs(v) <= MAX_COORD for v in origin):
        raise WorldError(f"{src}:{entries['origin'].line}: key 'origin': ({origin[0]:g}, {origin[1]:g}) m is beyond "
                         f"+-{MAX_COORD:g} m, expected coordinates of a building")
    occupied = _number(entries, "occupied_thresh", src)
    free = _number(entries, "free_thresh", src)
    for key, value in (("occupied_thresh", occupied), ("free_thresh", free)):
        if not 0.0 <= value <= 1.0:
            raise WorldError(f"{src}:{entries[key].line}: key {key!r}: {value} is outside [0, 1], "
                             "expected a probability")
    if free >= occupied:
        raise WorldError(f"{src}:{entries['free_thresh'].line}: key 'free_thresh': {free} >= "
                         f"occupied_thresh {occupied}, expected free_thresh < occupied_thresh")
    negate = _negate(entries, src)
    mode = _scalar(entries["mode"], "mode", src).lower() if "mode" in entries else "trinary"
    if mode not in _MODES:
        raise WorldError(f"{src}:{entries['mode'].line}: key 'mode': unknown mode {mode[:30]!r}, "
                         f"expected one of {', '.join(_MODES)}")
    image = _scalar(entries["image"], "image", src)
    if not image:
        raise WorldError(f"{src}:{entries['image'].line}: key 'image' is empty, expected an image "
                         "file name (relative to the YAML's folder or absolute)")
    image_path = Path(yaml_path).parent / image
    sums, divisor, opaque = _read_image(image_path, mode, f"{src}:{entries['image'].line}: key 'image'")
    if sums.ndim != 2 or sums.size == 0:
        raise WorldError(f"{src}:{entries['image'].line}: key 'image': image {str(image_path)!r} "
                         "has no pixel, expected at least one")
    # every pixel has one of 255*divisor + 1 shades: classify those once, then look up
    table = _classify(np.arange(255 * divisor + 1) / divisor, mode, negate, free, occupied)
    values = table[sums]
    if mode == "scale" and opaque is not None:
        values[~opaque] = -1
    values = np.ascontiguousarray(values[::-1])
    extent = max(values.shape) * resolution
    if not all(abs(v) + extent <= MAX_COORD for v in origin):
        raise WorldError(f"{src}:{entries['resolution'].line}: the map reaches {extent:g} m from its origin "
                         f"({values.shape[1]} x {values.shape[0]} pixels of {resolution:g} m), "
                         f"beyond +-{MAX_COORD:g} m: "
                         "expected the resolution of a building map [m/pixel]")
    geo = GridGeometry(origin[0], origin[1], resolution, values.shape[0], values.shape[1])
    return values, geo


def load_ros_world(yaml_path: str | os.PathLike[str]) -> World:
    """Load a map_server map as a `World` for the simulator.

    Occupied cells (value >= 50) and unknown cells (-1) become obstacles: unknown is outside
    the mapped area, where the simulated robot must neither drive nor see. Cells are merged
    into axis-aligned rectangles (`merge_cells`). `bounds` is the image extent.

    Args:
        yaml_path: the map's YAML file.

    Returns:
        The world; `name` is the YAML stem, `source` the YAML path; no poses.

    Raises:
        WorldError: as `load_ros_grid`, or the map has no occupied or unknown cell at all.
    """
    values, geo = load_ros_grid(yaml_path)
    return world_from_grid(values, geo, name=Path(yaml_path).stem, source=str(yaml_path),
                           what=f"ROS map {Path(yaml_path).name}")


def world_from_grid(values: npt.NDArray[np.int8], geo: GridGeometry, *, name: str, source: str,
                    what: str) -> World:
    """The `World` of an occupancy grid (as `load_ros_world`): occupied (>= 50) and unknown (< 0)
    cells merged into boxes, bounds and declared area the grid's extent, collision "index".

    Raises:
        WorldError: the grid has no occupied or unknown cell at all, or no free one, or its blocked cells make
            more than MAX_BOXES rectangles (noise, a dithered image), told before they are merged.
    """
    blocked = (values < 0) | (values >= 50)
    if blocked.all():
        raise WorldError(f"{source}: the map has no free cell ({int(np.count_nonzero(values >= 50))} occupied, "
                         f"{int(np.count_nonzero(values < 0))} unknown): {READ_WRONG}")
    # at least one rectangle per run of blocked cells along a row that does not start where a run of the
    # row before starts (merged rectangles stack equal runs): a cheap lower bound of their number
    starts = blocked.copy()
    starts[:, 1:] &= ~blocked[:, :-1]
    fresh = starts.copy()
    fresh[1:] &= ~starts[:-1]
    least = int(np.count_nonzero(fresh))
    if least > MAX_BOXES:
        raise WorldError(f"{source}: the map's occupied and unknown cells make at least {least} separate "
                         f"rectangles, more than the {MAX_BOXES} a map may have (a building has tens of thousands): "
                         "is the image noise or dithered? Threshold it into walls and free space")
    rects = merge_cells(blocked)
    if len(rects) == 0:
        raise WorldError(f"{source}: the map has no occupied or unknown cell, expected walls "
                         "(the simulated robot would drive off the map)")
    r0, r1, c0, c1 = (rects[:, i].astype(np.float64) for i in range(4))
    cell = geo.cell
    boxes = np.column_stack([geo.origin_x + (c0 + c1) / 2 * cell, geo.origin_y + (r0 + r1) / 2 * cell,
                             (c1 - c0) / 2 * cell, (r1 - r0) / 2 * cell, np.zeros(len(rects))])
    bounds = (geo.origin_x, geo.origin_y, geo.origin_x + geo.width, geo.origin_y + geo.height)
    description = (f"{what}: {geo.cols} x {geo.rows} cells of {cell:g} m, "
                   f"{int(np.count_nonzero(values >= 50))} occupied, "
                   f"{int(np.count_nonzero(values < 0))} unknown, {len(rects)} boxes")
    return World(name=name, boxes=boxes, bounds=bounds, source=source, description=description,
                 declared=bounds, collision="index")


def merge_cells(mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.int64]:
    """Cover the True cells of `mask` (rows, cols) with disjoint rectangles.

    Runs of True cells along each row are found, then equal runs (same first and last column)
    in consecutive rows are merged into one rectangle.

    Args:
        mask: bool (rows, cols).

    Returns:
        int64 (k, 4): `[row0, row1, col0, col1]`, half-open (rows row0..row1-1, same for cols).
    """
    mask = np.asarray(mask, dtype=bool)
    rows, cols = mask.shape
    padded = np.zeros((rows, cols + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    step = np.diff(padded, axis=1)            # +1 where a run starts, -1 one past its end
    run_row, run_c0 = np.nonzero(step == 1)   # both row-major, so the i-th start pairs with
    _, run_c1 = np.nonzero(step == -1)        # the i-th end
    order = np.lexsort((run_row, run_c1, run_c0))
    run_row, run_c0, run_c1 = run_row[order], run_c0[order], run_c1[order]
    n = len(run_row)
    if n == 0:
        return np.zeros((0, 4), dtype=np.int64)
    new = np.ones(n, dtype=bool)
    new[1:] = ((run_c0[1:] != run_c0[:-1]) | (run_c1[1:] != run_c1[:-1])
               | (run_row[1:] != run_row[:-1] + 1))
    first = np.flatnonzero(new)
    last = np.append(first[1:], n) - 1
    return np.column_stack([run_row[first], run_row[last] + 1, run_c0[first], run_c1[first]]
                           ).astype(np.int64)


def save_ros_map(yaml_path: str | os.PathLike[str], values: npt.NDArray[np.int8], geo: GridGeometry,
                 *, image_name: str | None = None) -> None:
    """Write an occupancy grid as a ROS 1 map_saver map: YAML plus binary PGM (P5).

    Pixels: 0 -> 254 (free), 100 -> 0 (occupied), any other value -> 205 (unknown); the image
    is flipped so its top row is the grid's last row. The YAML has `image`, `resolution`,
    `origin: [x, y, 0.0]`, `negate: 0`, `occupied_thresh: 0.65`, `free_thresh: 0.196`,
    `mode: trinary`, so `load_ros_grid` gives back `values` exactly when they are -1/0/100.

    Args:
        yaml_path: the YAML file to write.
        values: int8 (geo.rows, geo.cols), row 0 the bottom.
        geo: where the grid lies; `geo.cell` is written as the resolution [m/pixel].
        image_name: the image file name, relative to the YAML's folder; default the YAML's
            stem + ".pgm".

    Raises:
        ConfigError: `values` does not match `geo`, or `image_name` is empty or has a quote
            or a line break.
        WorldError: a file cannot be written.
    """
    grid = np.asarray(values)
    if grid.shape != (geo.rows, geo.cols):
        raise ConfigError(f"save_ros_map: values have shape {grid.shape}, expected (rows, cols) = "
                          f"({geo.rows}, {geo.cols}) from geo")
    if not (math.isfinite(geo.cell) and geo.cell > 0):
        raise ConfigError(f"save_ros_map: geo.cell is {geo.cell}, expected a positive size [m]")
    yaml_file = Path(yaml_path)
    name = image_name if image_name is not None else yaml_file.stem + ".pgm"
    if not name or any(ch in name for ch in "\"'\n\r"):
        raise ConfigError(f"save_ros_map: image_name {name!r} is empty or has a quote or line "
                          "break, expected a plain file name such as 'map.pgm'")
    pixels = np.full(grid.shape, _UNKNOWN, dtype=np.uint8)
    pixels[grid == 0] = _FREE
    pixels[grid == 100] = _OCCUPIED
    header = f"P5\n# CREATOR: robotexp {geo.cell:.3f} m/pix\n{geo.cols} {geo.rows}\n255\n"
    image_text = name if _PLAIN_NAME.fullmatch(name) else f'"{name}"'
    yaml_text = (f"image: {image_text}\n"
                 f"resolution: {_yaml_float(geo.cell)}\n"
                 f"origin: [{_yaml_float(geo.origin_x)}, {_yaml_float(geo.origin_y)}, 0.0]\n"
                 "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n")
    image_path = yaml_file.parent / name
    try:
        image_path.write_bytes(header.encode("ascii") + pixels[::-1].tobytes())
        yaml_file.write_text(yaml_text, encoding="utf-8")
    except OSError as exc:
        raise WorldError(f"{exc.filename or yaml_file}: cannot write the map ({exc.strerror or exc}), "
                         "expected a writable folder") from exc


def _yaml_float(value: float) -> str:
    """`value` as a YAML float that reads back to the same double (always with a '.')."""
    text = repr(float(value))
    if not math.isfinite(value):
        raise ConfigError(f"save_ros_map: {value} is not a finite number, expected finite geo values")
    mantissa, e, exponent = text.partition("e")
    return (mantissa if "." in mantissa else mantissa + ".0") + (e + exponent if e else "")


def _read_text(path: Path, src: str) -> str:
    """The YAML file as text; WorldError when it cannot be read or is not UTF-8 text."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise WorldError(f"{src}: cannot read the map YAML ({exc.strerror or exc}), "
                         "expected a readable map_server .yaml file") from exc
    if len(data) > MAX_YAML_BYTES:
        raise WorldError(f"{src}: {len(data)} bytes, expected a map_server .yaml file of at most "
                         f"{MAX_YAML_BYTES} bytes (a few lines of keys)")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise WorldError(f"{src}:{line}: not UTF-8 text (byte 0x{data[exc.start]:02x}), expected "
                         "a map_server .yaml file") from None
    if "\x00" in text:
        raise WorldError(f"{src}:{text.count(chr(10), 0, text.index(chr(0))) + 1}: NUL byte, "
                         "expected a text map_server .yaml file")
    return text


def _parse_yaml(text: str, src: str) -> dict[str, _Entry]:
    """The top-level `key: value` pairs of a map YAML (values: scalars or lists of scalars), read by PyYAML's
    composer as map_server's YAML reader would read them (block or flow style, quotes, comments, anchors),
    each with its line. Nested mappings under keys robotexp does not read are left out."""
    import yaml  # type: ignore[import-untyped]  # PyYAML: a dependency (map YAML files)

    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.context_mark or exc.problem_mark
        where = f"{src}:{mark.line + 1}" if mark is not None else src
        what = " ".join(part for part in (exc.context, exc.problem) if part)
        raise WorldError(f"{where}: not valid YAML ({what}), expected 'key: value' lines") from None
    except yaml.YAMLError as exc:
        raise WorldError(f"{src}: not valid YAML ({exc}), expected 'key: value' lines") from None
    except RecursionError:
        raise WorldError(f"{src}: YAML nested too deeply, expected 'key: value' lines") from None
    if root is None:
        return {}
    if not isinstance(root, yaml.MappingNode):
        raise WorldError(f"{src}:{root.start_mark.line + 1}: {_node_text(root)!r} is not a mapping, expected "
                         "'key: value' lines")
    entries: dict[str, _Entry] = {}
    for key_node, node in root.value:
        number = key_node.start_mark.line + 1
        if not isinstance(key_node, yaml.ScalarNode):
            raise WorldError(f"{src}:{number}: a key that is not a name, expected 'key: value' lines")
        key = key_node.value
        if key in entries:
            raise WorldError(f"{src}:{number}: key {key!r} repeated (first on line {entries[key].line}), "
                             "expected each key once")
        if isinstance(node, yaml.ScalarNode):
            entries[key] = _Entry(node.value, number)
        elif isinstance(node, yaml.SequenceNode) and all(isinstance(n, yaml.ScalarNode) for n in node.value):
            entries[key] = _Entry([n.value for n in node.value], number)
        elif key in _REQUIRED or key == "mode":
            raise WorldError(f"{src}:{number}: key {key!r}: {_node_text(node)!r} is not a value or a list of "
                             "values")
        # else: a nested mapping under a key map_server does not read; left out
    return entries


def _node_text(node: object) -> str:
    """A short text of a YAML node for a message."""
    mark = getattr(node, "start_mark", None)
    end = getattr(node, "end_mark", None)
    if mark is not None and end is not None and mark.buffer is not None:
        return str(mark.buffer[mark.index:end.index])[:40]
    return str(getattr(node, "value", ""))[:40]


def _scalar(entry: _Entry, key: str, src: str) -> str:
    """The entry's scalar value; WorldError when it is a list."""
    if isinstance(entry.value, list):
        raise WorldError(f"{src}:{entry.line}: key {key!r} is a list, expected a single value")
    return entry.value


def _to_float(text: str, key: str, src: str, line: int, expected: str) -> float:
    """`text` as a finite float; WorldError naming the key otherwise."""
    if not _NUMBER.fullmatch(text) or not math.isfinite(float(text)):
        raise WorldError(f"{src}:{line}: key {key!r}: bad number {text[:40]!r}, expected {expected}")
    return float(text)


def _number(entries: dict[str, _Entry], key: str, src: str) -> float:
    """The float value of a scalar key."""
    entry = entries[key]
    expected = "a cell size [m/pixel]" if key == "resolution" else "a probability in [0, 1]"
    return _to_float(_scalar(entry, key, src), key, src, entry.line, expected)


def _origin(entries: dict[str, _Entry], src: str) -> tuple[float, float]:
    """(x, y) [m] of the lower-left pixel from `origin: [x, y, yaw]` (yaw must be 0)."""
    entry = entries["origin"]
    expected = "3 numbers '[x, y, yaw]' [m, m, rad]"
    if not isinstance(entry.value, list) or len(entry.value) != 3:
        raise WorldError(f"{src}:{entry.line}: key 'origin': {entry.value!r} is not 3 numbers, "
                         f"expected {expected}")
    x, y, yaw = (_to_float(v, "origin", src, entry.line, expected) for v in entry.value)
    if abs(yaw) > 1e-9:
        raise WorldError(f"{src}:{entry.line}: key 'origin': yaw {yaw} is not supported, expected 0 "
                         "(rotate the image instead)")
    return x, y


def _negate(entries: dict[str, _Entry], src: str) -> bool:
    """`negate` as a bool: 0/1 (ROS 1) or true/false (nav2)."""
    entry = entries["negate"]
    text = _scalar(entry, "negate", src).lower()
    if text in ("0", "false", "no", "off"):
        return False
    if text in ("1", "true", "yes", "on"):
        return True
    raise WorldError(f"{src}:{entry.line}: key 'negate': bad value {text[:30]!r}, expected 0 or 1")


def _read_image(path: Path, mode: str, where: str
                ) -> tuple[npt.NDArray[np.integer], int, npt.NDArray[np.bool_] | None]:
    """(sums, divisor, opaque) of an image, top row first.

    The shade of a pixel in [0, 255] is `sums / divisor` (the mean of its channels, in trinary
    mode with the alpha averaged in, as nav2 does); `opaque` says where alpha is 255
    (None when the image has no alpha). Integer sums let the caller classify through a table.
    """
    from PIL import Image, UnidentifiedImageError  # only when a ROS map is loaded

    if not path.is_file():
        raise WorldError(f"{where}: image {str(path)!r} not found, expected an image file "
                         "relative to the YAML's folder or absolute")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(path) as img:       # reads the header only: the size is known before decoding
                width, height = img.size
                if width * height > MAX_CELLS:
                    raise WorldError(f"{where}: image {str(path)!r} is {width} x {height} pixels, more than "
                                     f"the {MAX_CELLS:.3g} cells a map may have; use a smaller image")
                img.load()
                if img.mode in ("I", "I;16", "I;16B", "I;16L", "I;16N"):
                    # 16-bit PGM/PNG: pillow scales samples to 0..65535, so shade = v / 257
                    sums = np.asarray(img, dtype=np.int64)
                    if sums.size and not 0 <= sums.min() <= sums.max() <= 65535:
                        raise ValueError("32-bit samples")
                    return sums, 257, None
                if img.mode == "L":
                    return np.asarray(img), 1, None
                if img.mode == "F":
                    raise ValueError("float samples")
                has_alpha = "A" in img.getbands() or "transparency" in img.info
                rgba = np.asarray(img.convert("RGBA" if has_alpha else "RGB"), dtype=np.int32)
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError, EOFError,
            Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        raise WorldError(f"{where}: cannot read image {str(path)!r} ({exc}), expected an 8- or "
                         "16-bit PGM (P5/P2) or PNG image") from exc
    if not has_alpha:
        return rgba.sum(axis=2), 3, None
    opaque = rgba[:, :, 3] == 255
    if mode == "trinary":
        # nav2 adds MaxRGB - GraphicsMagick's alphaQuantum (an opacity, 0 = opaque): the alpha
        return rgba.sum(axis=2), 4, opaque
    return rgba[:, :, :3].sum(axis=2), 3, opaque


def _classify(shade: npt.NDArray[np.float64], mode: str, negate: bool, free: float,
              occupied: float) -> npt.NDArray[np.int8]:
    """int8 cell values of pixel shades in [0, 255], following nav2's map_io (alpha aside)."""
    if mode == "raw":
        level = np.floor(shade + 0.5)          # C round(): half away from zero, shade >= 0
        return np.where(level <= 100, level, -1).astype(np.int8)
    p = shade / 255.0 if negate else (255.0 - shade) / 255.0
    values = np.full(shade.shape, -1, dtype=np.int8)
    if mode == "scale":
        values[:] = np.clip(np.rint((p - free) / (occupied - free) * 100.0), 0, 100)
    values[p > occupied] = 100
    values[p < free] = 0
    return values


def ros_image_path(yaml_path: str | os.PathLike[str]) -> Path:
    """The image file a map YAML names (its `image` key, relative to the YAML's folder), unread.

    Lets a caller check where the image is before `load_ros_grid` reads it (the Lua sandbox).

    Raises:
        WorldError: the YAML cannot be read or parsed, or has no non-empty `image` key.
    """
    src = str(yaml_path)
    entries = _parse_yaml(_read_text(Path(yaml_path), src), src)
    if "image" not in entries:
        raise WorldError(f"{src}: missing key 'image', expected the map_server keys {', '.join(_REQUIRED)}")
    image = _scalar(entries["image"], "image", src)
    if not image:
        raise WorldError(f"{src}:{entries['image'].line}: key 'image' is empty, expected an image file name")
    return Path(yaml_path).parent / image
