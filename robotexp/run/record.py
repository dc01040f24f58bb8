"""The typed record of one run (`RunRecord`) and why a run ended (`EndReason`).

A record has exactly the keys of docs/reference/results.md as fields, plus `extra` for what an explorer or a
caller adds (`targets`, `script`, `address`, ...). `as_dict()` gives the JSON object appended to
`results.jsonl` (robotexp/schema/results.schema.json describes it), and `RunRecord.from_dict` reads
any such object back, also one written before records had a `schema_version` or were typed (their
end reason is read from `completed` and the `reason` text, see `EndReason.classify`). A record is
also a read-only mapping of its JSON keys (`record["coverage"]`), so code written for the dict records keeps working.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import Any

__all__ = ["EndReason", "RunRecord", "RESULT_KEYS", "COVERAGE_MILESTONES", "SCHEMA_VERSION", "milestone_keys",
           "record_problem", "results_schema"]

SCHEMA_VERSION = 1      # the format of the records written now (robotexp/schema/results.schema.json)

COVERAGE_MILESTONES = (0.90, 0.95, 0.99)


class EndReason(enum.Enum):
    """Why a run ended. The record's `reason` text says more (the explorer's words, the robot's
    error); the enum is what code decides on."""

    EXPLORED = "explored"               # the explorer returned Done (`completed` is true)
    TIME_LIMIT = "time limit"           # the run's robot-time limit was reached
    INTERRUPTED = "interrupted"         # Ctrl-C (or a signal turned into KeyboardInterrupt)
    ROBOT_ERROR = "robot error"         # the robot failed (link lost, emergency stop, protocol error)
    STALLED = "stalled"                 # the robot made no progress (detected by the loop's stall watch)
    STOPPED = "stopped"                 # an observer asked the run to stop (a user, a view, a script's timeout)
    PLUGIN_ERROR = "plugin error"       # the explorer raised or returned something other than Twist / Done
    UNKNOWN = "unknown"                 # a record whose reason cannot be read (hand-written files)

    @classmethod
    def classify(cls, completed: bool, reason: str) -> EndReason:
        """The end reason of a record that has only `completed` and the `reason` text (every record
        written before the enum existed, and the JSON of every record since: the text of each
        reason below starts with its enum value, which is what this reads)."""
        if completed:
            return cls.EXPLORED
        for member in (cls.INTERRUPTED, cls.TIME_LIMIT, cls.ROBOT_ERROR, cls.STALLED, cls.STOPPED,
                       cls.PLUGIN_ERROR):
            if reason.startswith(member.value):
                return member
        return cls.UNKNOWN


def results_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a results.jsonl line of `SCHEMA_VERSION`, as shipped in the
    package (robotexp/schema/results.schema.json)."""
    import json
    from importlib.resources import files

    schema: dict[str, Any] = json.loads(files("robotexp").joinpath("schema/results.schema.json").read_text("utf-8"))
    return schema


def milestone_keys(level: float) -> tuple[str, str]:
    """The record keys of a coverage milestone: (`time_to_coverage_90_s`, `path_to_coverage_90_m`)."""
    key = f"{round(level * 100)}"
    return f"time_to_coverage_{key}_s", f"path_to_coverage_{key}_m"


# the JSON keys in the order records have always been written; milestone keys follow `cell_m`, then
# `extra` (an explorer's result fields, then the caller's), then the settings written with `out`
_HEAD = ("run", "method", "world", "start_pose", "max_speed_m_s", "path_length_m", "robot_time_s",
         "wall_time_s", "coverage", "collisions", "nodes", "visited_cells", "seed", "completed", "reason",
         "map_iou", "cell_m")
_TAIL = ("pose", "laser_range_m", "robot")
# a team's keys (`robotexp explore --team`), written after `_TAIL` when set; records of one robot have none
_TEAM = ("team_size", "coordinator", "comm_range_m", "total_path_m", "max_path_m", "overlap_ratio", "idle_time_s",
         "robot_collisions", "coordinator_rounds", "robots")
RESULT_KEYS = _HEAD[:-1]     # the keys every record has, docs/reference/results.md


@dataclass(frozen=True, eq=True)
class RunRecord(Mapping[str, Any]):
    """One run's results (SI units; docs/reference/results.md describes each field); immutable (`method_fields`
    and `extra` are read-only mappings).

    Records of `SCHEMA_VERSION` 1 write `schema_version`, `end` (the `EndReason` value) and
    `map_iou_tolerant` (`map_iou` with one cell of tolerance). A record read from a line written before
    (no `schema_version`) has `schema_version` None, derives `end` from `completed` and `reason`, and
    writes back exactly the keys it was read with. `pose`, `laser_range_m` and `robot` are None in
    records written without an output folder before this class existed; they are always set now.
    """

    run: str
    method: str
    world: str
    start_pose: list[float] | None
    max_speed_m_s: float
    path_length_m: float
    robot_time_s: float
    wall_time_s: float
    coverage: float | None
    collisions: int
    nodes: int | None
    visited_cells: int
    seed: int
    completed: bool
    reason: str
    map_iou: float | None
    cell_m: float | None
    time_to_coverage_90_s: float | None = None
    path_to_coverage_90_m: float | None = None
    time_to_coverage_95_s: float | None = None
    path_to_coverage_95_m: float | None = None
    time_to_coverage_99_s: float | None = None
    path_to_coverage_99_m: float | None = None
    pose: str | None = None
    laser_range_m: float | None = None
    robot: str | None = None
    method_fields: Mapping[str, Any] = field(default_factory=dict)
    extra: Mapping[str, Any] = field(default_factory=dict)
    end: EndReason = EndReason.UNKNOWN
    map_iou_tolerant: float | None = None
    schema_version: int | None = SCHEMA_VERSION
    team_size: int | None = None
    coordinator: str | None = None
    comm_range_m: float | None = None
    total_path_m: float | None = None
    max_path_m: float | None = None
    overlap_ratio: float | None = None
    idle_time_s: float | None = None
    robot_collisions: int | None = None
    coordinator_rounds: int | None = None
    robots: list[dict[str, Any]] | None = None
    coverage_inside: float | None = None

    def __post_init__(self) -> None:
        if self.end is EndReason.UNKNOWN:
            object.__setattr__(self, "end", EndReason.classify(bool(self.completed), str(self.reason)))
        object.__setattr__(self, "method_fields", MappingProxyType(dict(self.method_fields)))
        object.__setattr__(self, "extra", MappingProxyType(dict(self.extra)))

    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]:
        """Pickled as its fields (the read-only mappings as dicts), for campaign workers."""
        state = {f.name: getattr(self, f.name) for f in fields(self)}
        state["method_fields"], state["extra"] = dict(self.method_fields), dict(self.extra)
        return _unpickle, (state,)

    # -- JSON ----------------------------------------------------------------------------------
    def as_dict(self) -> dict[str, Any]:
        """The JSON object of docs/reference/results.md, keys in the order they have always been written:
        the fields, the explorer's `method_fields`, `pose`, `laser_range_m`, `robot`, then `extra`. A
        record of a schema version also writes `schema_version` (first), `end` (after `reason`) and
        `map_iou_tolerant` (after `map_iou`); one read from an earlier line has none of them.
        `coverage_inside` follows `coverage` when it is set (a run with ground truth); a line read without
        it is written back without it."""
        versioned = self.schema_version is not None
        out: dict[str, Any] = {"schema_version": self.schema_version} if versioned else {}
        for key in _HEAD:
            out[key] = getattr(self, key)
            if key == "coverage" and self.coverage_inside is not None:
                out["coverage_inside"] = self.coverage_inside
            if versioned and key == "reason":
                out["end"] = self.end.value
            elif versioned and key == "map_iou":
                out["map_iou_tolerant"] = self.map_iou_tolerant
        for level in COVERAGE_MILESTONES:
            t_key, p_key = milestone_keys(level)
            out[t_key], out[p_key] = getattr(self, t_key), getattr(self, p_key)
        out.update(self.method_fields)
        for key in _TAIL:
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        if self.team_size is not None:
            for key in _TEAM:
                out[key] = getattr(self, key)
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunRecord:
        """A record from its JSON object (any results.jsonl line robotexp wrote). Keys the record has
        no field for go to `method_fields` when they come before `pose`, `laser_range_m` and `robot`, else to
        `extra`, so that `as_dict()` gives the object back, keys in order; missing keys read as None
        (0 / "" for the identifying ones)."""
        if isinstance(data, RunRecord):
            return data
        known = {f.name for f in fields(cls)} - {"method_fields", "extra", "end"}
        kwargs: dict[str, Any] = {key: data.get(key) for key in known}
        end = EndReason.UNKNOWN
        if data.get("end") is not None:
            try:
                end = EndReason(data["end"])
            except ValueError:
                pass            # a reason this version does not know: read from `completed` and `reason`
        for key, default in (("run", ""), ("method", ""), ("world", ""), ("max_speed_m_s", 0.0),
                             ("path_length_m", 0.0), ("robot_time_s", 0.0), ("wall_time_s", 0.0),
                             ("collisions", 0), ("visited_cells", 0), ("seed", 0), ("completed", False),
                             ("reason", "")):
            if kwargs[key] is None:
                kwargs[key] = default
        # the explorer's keys come before `pose`/`laser_range_m`/`robot`, the caller's after them
        method_fields: dict[str, Any] = {}
        extra: dict[str, Any] = {}
        seen_tail = False
        for key, value in data.items():
            seen_tail = seen_tail or key in _TAIL or key in _TEAM
            if key not in known and key != "end":
                (extra if seen_tail else method_fields)[key] = value
        return cls(**kwargs, method_fields=method_fields, extra=extra, end=end)

    # -- read-only mapping of the JSON keys ----------------------------------------------------
    def __getitem__(self, key: str) -> Any:
        return self.as_dict()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.as_dict())

    def __len__(self) -> int:
        return len(self.as_dict())

    def __contains__(self, key: object) -> bool:
        return key in self.as_dict()


def _unpickle(state: dict[str, Any]) -> RunRecord:
    return RunRecord(**state)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_integer(value: Any) -> bool:
    return _is_number(value) and (isinstance(value, int) or value.is_integer())


# the JSON type of each typed field, by its annotation (null is always allowed: it reads as the default)
_JSON_TYPES: dict[str, tuple[str, Callable[[Any], bool]]] = {
    "float": ("a number", _is_number),
    "int": ("an integer", _is_integer),
    "str": ("a string", lambda v: isinstance(v, str)),
    "bool": ("a boolean", lambda v: isinstance(v, bool)),
    "list[float]": ("a list of numbers", lambda v: isinstance(v, list) and all(map(_is_number, v))),
    "list[dict[str, Any]]": ("a list of objects", lambda v: isinstance(v, list) and all(isinstance(x, dict)
                                                                                     for x in v)),
}
_FIELD_TYPES = {f.name: _JSON_TYPES[str(f.type).removesuffix(" | None")] for f in fields(RunRecord)
                if str(f.type).removesuffix(" | None") in _JSON_TYPES}


def record_problem(data: Mapping[str, Any]) -> str | None:
    """What makes the JSON object `data` no run record: the first field of `RunRecord` whose value has
    the wrong JSON type (`"coverage": "x"`, `"world": ["x"]`), said in a few words; None when every field
    present has its type (null and missing keys read as the field's default; other keys are free)."""
    for key, (expected, ok) in _FIELD_TYPES.items():
        value = data.get(key)
        if value is not None and not ok(value):
            shown = repr(value)
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            return f"{key} is {shown}, expected {expected} or null"
    return None
