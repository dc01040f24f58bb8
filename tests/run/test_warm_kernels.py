"""Before a robot other than the embedded simulator moves, the run compiles (or loads from numba's cache)
the kernels it will call on a short simulated run (`robotexp.experiment.warm_kernels`): on a fresh
install a kernel compiled mid-run left a real robot going on with its last command for seconds."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

CHILD = r"""
import json, sys
from robotexp.run.spec import RunSpec
from robotexp.experiment import warm_kernels
from robotexp.localization import kernels as lk
from robotexp.mapping import kernels as mk
from robotexp.planning import kernels as pk
from robotexp.robot import Robot, RobotState, Pose, Twist


class Still(Robot):
    '''A robot that is not the simulator (warm_kernels must never read or command it).'''
    name = "still"
    def _read(self): raise AssertionError("read")
    def _command(self, twist): raise AssertionError("command")
    def _close(self): pass


def compiled():
    return {"integrate": len(mk.integrate_scan_logodds.signatures), "search": len(lk.search.signatures),
            "astar": len(pk.astar_kernel.signatures), "simplify": len(pk.simplify_kernel.signatures)}


before = compiled()
spec = RunSpec(method="frontier", localize=sys.argv[1])
robot = Still()
warm_kernels(spec, robot)
after = compiled()
warm_kernels(spec, robot)        # once per process and setting: no second run
print(json.dumps({"before": before, "after": after}))
"""


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="compilation is what is tested")
@pytest.mark.parametrize("localize", ["auto", "none"])
def test_a_real_robots_run_compiles_its_kernels_before_the_robot_moves(localize: str, tmp_path) -> None:
    done = subprocess.run([sys.executable, "-c", CHILD, localize], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert got["before"] == {"integrate": 0, "search": 0, "astar": 0, "simplify": 0}   # a fresh process
    assert got["after"]["integrate"] >= 1                            # the map update is ready
    # and the planners' A* and path simplification, which a 5 s frontier run does not reach (the clean-clone
    # CI saw A* compile mid-run on a robot: 2 s blind, 4 bumps)
    assert got["after"]["astar"] >= 1 and got["after"]["simplify"] >= 1
    # "auto" on a real robot is scan matching: its kernels are ready too; without a localizer they are not
    assert (got["after"]["search"] >= 1) == (localize == "auto")
    assert list(tmp_path.iterdir()) == []                            # the warm-up wrote nothing
