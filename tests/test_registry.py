"""robotexp.registry: entry-point discovery, loading with checks, and the Lua spelling of names.

Extra plugins come from real distribution metadata (a `*.dist-info` directory with an
`entry_points.txt`) put on sys.path for one test: exactly what `pip install` leaves behind.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from robotexp.errors import PluginError
from robotexp.explorer import Explorer
from robotexp.registry import EXPLORERS, ROBOTS, PluginInfo, available, load, lua_name
from robotexp.robot import Robot


def _install_metadata(site: Path, dist: str, version: str, entry_points: str) -> None:
    """Write the metadata of distribution `dist` into `site` (a directory on sys.path)."""
    info = site / f"{dist.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text(entry_points)


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A fresh site directory first on sys.path (removed again after the test)."""
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


# -- what is installed ---------------------------------------------------------------------

def test_available_lists_frontier_with_its_distribution() -> None:
    explorers = available(EXPLORERS)
    assert explorers["frontier"] == PluginInfo("frontier", "robotexp_plugins.frontier:FrontierExplorer",
                                               "robotexp", explorers["frontier"].version)
    assert explorers["frontier"].version == "0.1.0"
    assert list(explorers) == sorted(explorers)
    assert available(ROBOTS)["sim"].target == "robotexp.sim:SimRobot"
    assert available("robotexp.no-such-group") == {}


def test_load_returns_the_checked_class() -> None:
    from robotexp_plugins.frontier import FrontierExplorer
    from robotexp.sim import SimRobot

    assert load(EXPLORERS, "frontier", Explorer) is FrontierExplorer
    assert load(ROBOTS, "sim", Robot) is SimRobot


def test_unknown_name_lists_the_available_and_the_closest() -> None:
    with pytest.raises(PluginError) as err:
        load(EXPLORERS, "fronteir", Explorer)
    msg = str(err.value)
    assert "unknown method 'fronteir'" in msg
    assert "did you mean 'frontier'?" in msg
    listed = msg.split("available: ")[1].split(". ")[0]
    assert listed.split(", ") == list(available(EXPLORERS))    # every installed method, sorted
    assert "frontier" in listed.split(", ")
    assert "pip install -e ." in msg


def test_unknown_name_without_a_close_one() -> None:
    with pytest.raises(PluginError) as err:
        load(ROBOTS, "zzzzzz", Robot)
    msg = str(err.value)
    assert "unknown robot backend 'zzzzzz'" in msg and "did you mean" not in msg
    assert "sim" in msg.split("available:")[1]


def test_a_target_of_the_wrong_kind_is_refused() -> None:
    with pytest.raises(PluginError, match=r"plugin 'sim' of robotexp \(robotexp.sim:SimRobot\) is not a "
                                          r"subclass of robotexp.explorer.Explorer"):
        load(ROBOTS, "sim", Explorer)


def test_lua_name() -> None:
    assert lua_name("srt-laser") == "SRT_LASER"
    assert lua_name("frontier") == "FRONTIER"
    assert lua_name("meta-firefly-2") == "META_FIREFLY_2"


# -- third-party metadata ------------------------------------------------------------------

def test_a_third_party_plugin_is_listed_and_loaded(site: Path) -> None:
    (site / "thirdparty_explorer_mod.py").write_text(
        "from robotexp.explorer import Explorer, Done\n"
        "class SpinExplorer(Explorer):\n"
        "    def step(self, state, grid):\n"
        "        return Done()\n"
        "NOT_A_CLASS = 3\n")
    _install_metadata(site, "robotexp-spin", "2.3",
                      "[robotexp.explorers]\nspin = thirdparty_explorer_mod:SpinExplorer\n"
                      "three = thirdparty_explorer_mod:NOT_A_CLASS\n")
    try:
        found = available(EXPLORERS)
        assert found["spin"] == PluginInfo("spin", "thirdparty_explorer_mod:SpinExplorer", "robotexp-spin", "2.3")
        assert "frontier" in found
        cls = load(EXPLORERS, "spin", Explorer)
        assert cls.__name__ == "SpinExplorer" and issubclass(cls, Explorer)
        with pytest.raises(PluginError, match="'three' of robotexp-spin .* is not a subclass"):
            load(EXPLORERS, "three", Explorer)
    finally:
        sys.modules.pop("thirdparty_explorer_mod", None)


def test_a_failed_import_names_distribution_and_target(site: Path) -> None:
    _install_metadata(site, "robotexp-broken", "0.1",
                      "[robotexp.explorers]\nbroken = no_such_module_for_robotexp_tests:Thing\n")
    with pytest.raises(PluginError) as err:
        load(EXPLORERS, "broken", Explorer)
    msg = str(err.value)
    assert "'broken' of robotexp-broken (no_such_module_for_robotexp_tests:Thing) failed to import" in msg
    assert "ModuleNotFoundError" in msg
    assert isinstance(err.value.__cause__, ModuleNotFoundError)
    # the other plugins of the group are unaffected
    assert "frontier" in available(EXPLORERS)


def test_a_missing_attribute_is_a_failed_import(site: Path) -> None:
    _install_metadata(site, "robotexp-typo", "0.1", "[robotexp.explorers]\ntypo = robotexp.explorer:Explorr\n")
    with pytest.raises(PluginError, match="failed to import: AttributeError") as err:
        load(EXPLORERS, "typo", Explorer)
    assert isinstance(err.value.__cause__, AttributeError)


def test_one_name_in_two_distributions(site: Path) -> None:
    _install_metadata(site, "robotexp-rival", "1.0",
                      "[robotexp.explorers]\nfrontier = robotexp_plugins.frontier:FrontierExplorer\n")
    with pytest.raises(PluginError) as err:
        available(EXPLORERS)
    msg = str(err.value)
    assert "the name 'frontier' is claimed by both" in msg
    assert {"robotexp-rival", "robotexp"} <= set(msg.replace(":", " ").split())
    # other groups are not affected
    assert "sim" in available(ROBOTS)


def test_a_malformed_name_is_refused(site: Path) -> None:
    _install_metadata(site, "robotexp-shouty", "1.0", "[robotexp.explorers]\nBig_Name = robotexp.explorer:Explorer\n")
    with pytest.raises(PluginError, match="plugin name 'Big_Name' of robotexp-shouty is not lowercase"):
        available(EXPLORERS)


def test_one_scan_serves_every_group(site: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # a run asks for a second group (say, its coordinators) at its end, when a live view's idle clients
    # may hold every file the process may open: the first scan read every robotexp group, and the second
    # lookup opens no distribution's metadata
    import robotexp.registry as registry
    _install_metadata(site, "robotexp-extra", "1.0",
                      "[robotexp.coordinators]\nrelay = robotexp.coordinator:Coordinator\n"
                      "[console_scripts]\nNot_Ours = robotexp.cli:main\n")
    calls: list[int] = []
    real = registry.distributions

    def counted() -> object:
        calls.append(1)
        return real()

    monkeypatch.setattr(registry, "distributions", counted)
    assert "frontier" in available(EXPLORERS) and len(calls) == 1
    coordinators = available("robotexp.coordinators")
    assert coordinators["relay"].distribution == "robotexp-extra" and "none" in coordinators
    assert len(calls) == 1 and available("robotexp.nothing") == {}
