"""A file named in an actor's params is checked with the wiring, with the other problems."""

from pathlib import Path
from typing import Any

import pytest

from whexar.runtime.wiring import WiringError, build_graph
from whexar.testing.bus import bus_graph
from whexar.testing.imu import imu_graph
from whexar.testing.sensors import sensor_graph


@pytest.mark.parametrize(
    ("make", "key"),
    [
        (lambda p: bus_graph("emulator", {"config": p}, wiggle={}), "actors.bus.params.config"),
        (lambda p: bus_graph("emulator", {"faults": p}, wiggle={}), "actors.bus.params.faults"),
        (lambda p: sensor_graph("emulator", {"config": p}), "actors.sensors.params.config"),
        (lambda p: imu_graph("fake", {"config": p}), "actors.imu.params.config"),
    ],
)
def test_a_missing_file_is_a_wiring_problem(make: Any, key: str, tmp_path: Path) -> None:
    missing = tmp_path / "nowhere.toml"
    with pytest.raises(WiringError) as caught:
        build_graph(make(str(missing)))
    text = str(caught.value)
    assert key in text
    assert "nowhere.toml" in text
    assert "a readable TOML file" in text


def test_every_problem_of_the_graph_is_listed_with_the_files(tmp_path: Path) -> None:
    plan = tmp_path / "plan.toml"
    plan.write_text('[[faults]]\nkind = "melt"\n')
    doc = bus_graph("emulator", {"faults": str(plan), "stats_period_s": -1}, wiggle={})
    with pytest.raises(WiringError) as caught:
        build_graph(doc)
    assert len(caught.value.problems) == 2
    assert "actors.bus.params.faults" in str(caught.value)
    assert "faults[0].kind" in str(caught.value)
    assert "actors.bus.params.stats_period_s" in str(caught.value)


def test_good_files_pass(tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[bus]\nretries = 2\n")
    build_graph(bus_graph("emulator", {"config": str(config)}, wiggle={}))
