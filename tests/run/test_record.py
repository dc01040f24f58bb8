"""The typed run record and end reasons, typed capabilities and the factories that
need no list of backend names (item 1)."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest

from robotexp.campaign.report import report_tables
from robotexp.campaign.compare import comparison_tables, load_results
from robotexp.errors import ConfigError
from robotexp.run.record import RESULT_KEYS, EndReason, RunRecord, record_problem
from robotexp.registry import EMULATORS, available, connect_robot, load, make_emulator
from robotexp.robot import Capability, Robot, RobotState, Twist
from robotexp.sim import SimRobot

DOCS = Path(__file__).resolve().parent.parent.parent / "docs"


@pytest.mark.parametrize("name", ["thesis", "santos", "srt_star"])
def test_existing_results_files_load_and_write_back_the_same(name: str) -> None:
    lines = [json.loads(line) for line in (DOCS / name / "results.jsonl").read_text().splitlines() if line.strip()]
    records = [RunRecord.from_dict(d) for d in lines]
    for data, record in zip(lines, records, strict=True):
        assert set(RESULT_KEYS) <= set(data)
        assert record.as_dict() == data                        # same keys, same values
        assert list(record.as_dict()) == list(data)            # in the order they were written
        assert dict(record) == data and record["coverage"] == record.coverage == data["coverage"]
        assert record.end is (EndReason.EXPLORED if data["completed"] else record.end)
    assert all(r.end is not EndReason.UNKNOWN for r in records)
    # the reports read them as before (load_results gives RunRecords)
    loaded = load_results(DOCS / name / "results.jsonl")
    assert [r.as_dict() for r in loaded] == lines
    assert report_tables(loaded) == report_tables(lines)
    assert comparison_tables(loaded) == comparison_tables(lines)


def test_end_reasons_of_every_reason_text() -> None:
    cases = {
        (True, "no reachable frontier left"): EndReason.EXPLORED,
        (False, "time limit of 14400 s reached"): EndReason.TIME_LIMIT,
        (False, "interrupted (Ctrl-C)"): EndReason.INTERRUPTED,
        (False, "robot error: kobuki: no data from 'x' for 0.50 s"): EndReason.ROBOT_ERROR,
        (False, "stalled: no progress for 60 s"): EndReason.STALLED,
        (False, "stopped: the script's --timeout of 5 s was reached"): EndReason.STOPPED,
        (False, "plugin error: explorer 'x' (m.X): step returned None (NoneType); ..."): EndReason.PLUGIN_ERROR,
        (False, "something a hand-edited file says"): EndReason.UNKNOWN,
    }
    for (completed, reason), end in cases.items():
        assert EndReason.classify(completed, reason) is end, reason
    thesis = [RunRecord.from_dict(json.loads(line))
              for line in (DOCS / "thesis" / "results.jsonl").read_text().splitlines()]
    assert Counter(r.end for r in thesis) == {EndReason.EXPLORED: len(thesis)}


def test_a_minimal_record_reads_with_defaults() -> None:
    r = RunRecord.from_dict({"run": "a", "world": "w", "method": "m", "visited_cells": 3, "reason": "interrupted"})
    assert r.end is EndReason.INTERRUPTED and r.completed is False and r.coverage is None and r.nodes is None
    assert r.extra == {} and r["visited_cells"] == 3 and "pose" not in r


def test_record_problem_names_a_field_of_the_wrong_type() -> None:
    for name in ("thesis", "santos", "srt_star"):           # every record robotexp wrote has none
        for line in (DOCS / name / "results.jsonl").read_text().splitlines():
            assert record_problem(json.loads(line)) is None
    ok = {"run": "a", "world": "w", "coverage": None, "collisions": 2.0, "start_pose": [1, 2.5, 0], "free": [[]]}
    assert record_problem(ok) is None                       # null, an integral float, keys of no field
    cases = {"coverage": ("x", "coverage is 'x', expected a number or null"),
             "path_length_m": ({"a": 1}, "path_length_m is {'a': 1}, expected a number or null"),
             "world": (["x"], "world is ['x'], expected a string or null"),
             "collisions": (1.5, "collisions is 1.5, expected an integer or null"),
             "max_speed_m_s": (True, "max_speed_m_s is True, expected a number or null"),
             "start_pose": ([0, "y", 0], "start_pose is [0, 'y', 0], expected a list of numbers or null"),
             "robots": ([1], "robots is [1], expected a list of objects or null"),
             "reason": (["x"] * 100, "reason is ['x', 'x', 'x', 'x', 'x', 'x', 'x', '..., expected a string")}
    for key, (value, words) in cases.items():
        assert (record_problem(dict(ok, **{key: value})) or "").startswith(words), key


def test_capabilities_are_typed() -> None:
    assert SimRobot.capabilities == {Capability.SONAR, Capability.MOVE_TO, Capability.GROUND_TRUTH}
    assert "move_to" in SimRobot.capabilities and all(isinstance(c, Capability) for c in SimRobot.capabilities)

    class Plain(Robot):
        capabilities = frozenset({"battery"})      # type: ignore[arg-type]  # strings are read as members

        def _read(self) -> RobotState: raise NotImplementedError

        def _command(self, twist: Twist) -> None: ...

        def _close(self) -> None: ...

    assert Plain.capabilities == {Capability.BATTERY}
    with pytest.raises(TypeError, match="'teleport' is not a valid Capability"):
        class Bad(Plain):
            capabilities = frozenset({"teleport"})  # type: ignore[arg-type]


def test_backends_declare_what_the_factories_need() -> None:
    with pytest.raises(ConfigError, match="robot 'sim' has no address"):
        connect_robot("sim", "127.0.0.1")
    for name in available(EMULATORS):
        cls = load(EMULATORS, name, object)
        assert isinstance(cls.radius, float) and cls.radius > 0, name   # type: ignore[attr-defined]
        assert isinstance(cls.options, frozenset), name                # type: ignore[attr-defined]
    with pytest.raises(ConfigError, match="--udp is not an option of the 'p3dx' emulator"):
        make_emulator("p3dx", "ufmg-static", udp="127.0.0.1:14550")
    emulator = make_emulator("kobuki", "ufmg-static", port=0)
    try:
        assert emulator.start() is emulator and emulator.address.startswith("socket://127.0.0.1:")
    finally:
        emulator.close()


def test_the_public_api_is_lazy_and_complete() -> None:
    import subprocess
    import sys

    import robotexp

    assert set(robotexp.__all__) - {"__version__"} == set(robotexp._EXPORTS)
    for name in robotexp.__all__:
        assert getattr(robotexp, name) is not None, name
    assert robotexp.Done("x") == robotexp.Done("x") and robotexp.EndReason.STALLED.value == "stalled"
    # a fresh interpreter: `import robotexp` loads none of the modules behind the names
    code = "import sys, robotexp; print(sorted(m for m in sys.modules if m.startswith('robotexp.')))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
    assert (Path(robotexp.__file__).parent / "py.typed").is_file()
