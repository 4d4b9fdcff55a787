"""Scenario files: every problem named with its key path before a run, the built-ins load."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from whexar.errors import ConfigError
from whexar.sim.scenario import (
    SCENARIO_DIR,
    load_scenario,
    parse_scenario,
    scenario_names,
)
from whexar.sim.terrain import Terrain


def _problems(data: dict[str, Any], tmp_path: Path | None = None) -> dict[str, str]:
    """Key path → "value: allowed" of every problem of a scenario document."""
    with pytest.raises(ConfigError) as info:
        parse_scenario(data, "test.toml", base=tmp_path)
    return {p.path: f"{p.value!r}: {p.allowed}" for p in info.value.problems}


def test_the_built_in_scenarios_all_load() -> None:
    names = scenario_names()
    assert {"course", "slope", "wheels", "obstacles"} <= set(names)
    for name in names:
        s = load_scenario(name)
        assert s.name == name
        assert s.duration_s > 0
        assert isinstance(s.terrain, Terrain)
        assert s.commands, name
        assert all(cmd.t == t and cmd.source == "scenario" for t, cmd in s.commands)


def test_the_default_course_rides_and_walks_the_course_terrain() -> None:
    s = load_scenario()
    assert s.name == "course"
    assert s.terrain.name == "course"
    assert 50 <= s.duration_s <= 120
    modes = {cmd.mode for _, cmd in s.commands if cmd.mode}
    assert {"walk", "ride"} <= modes


def test_a_minimal_document_takes_the_defaults() -> None:
    s = parse_scenario({"duration_s": 5}, stem="mini")
    assert (s.name, s.seed, s.terrain.name, s.start, s.commands) == (
        "mini",
        0,
        "flat",
        (0, 0, 0),
        (),
    )
    assert s.faults is None
    assert s.config_path is None


def test_commands_become_motion_commands_at_their_times() -> None:
    s = parse_scenario(
        {
            "duration_s": 10,
            "start": {"x_m": 1.0, "yaw_deg": 90},
            "commands": [
                {"t": 1, "vx_m_s": 1, "gait": "ripple"},
                {"t": 4.5, "mode": "ride", "turn_radius_m": -1.0},
                {"t": 8, "stop": True},
            ],
        }
    )
    assert s.start[:2] == (1.0, 0.0)
    assert s.start[2] == pytest.approx(math.pi / 2)
    (t0, c0), (t1, c1), (t2, c2) = s.commands
    assert (t0, c0.vx_m_s, c0.gait) == (1.0, 1.0, "ripple")
    assert isinstance(c0.vx_m_s, float)  # a TOML integer is a float in a message
    assert (t1, c1.mode, c1.turn_radius_m) == (4.5, "ride", -1.0)
    assert (t2, c2.stop) == (8.0, True)


def test_an_unknown_key_names_itself_and_the_allowed_ones() -> None:
    found = _problems({"duration_s": 5, "speed": 3, "start": {"z_m": 1}})
    assert "unknown key" in found["speed"]
    assert "duration_s" in found["speed"]
    assert "unknown key" in found["start.z_m"]
    assert "yaw_deg" in found["start.z_m"]


def test_a_bad_type_and_a_missing_duration_are_listed_together() -> None:
    found = _problems({"seed": "one", "start": {"x_m": "left"}})
    assert set(found) == {"duration_s", "seed", "start.x_m"}
    assert "required" in found["duration_s"]
    assert "'one'" in found["seed"]


def test_a_command_the_robot_cannot_do_names_the_command_and_key() -> None:
    found = _problems(
        {
            "duration_s": 5,
            "commands": [
                {"t": 1, "gait": "gallop"},
                {"t": 2, "mode": "fly"},
                {"t": 3, "stance": "crouch"},
                {"t": 4, "turn_radius_m": 0.1},
                {"t": 5, "vx_m_s": "fast", "jump": True},
                {"vx_m_s": 0.1},
                {"t": 0.5},
                {"t": 6, "upside_down": True, "mode": "ride"},
            ],
        }
    )
    assert "tripod" in found["commands[0].gait"]
    assert "'gallop'" in found["commands[0].gait"]
    assert "ride" in found["commands[1].mode"]
    assert "default" in found["commands[2].stance"]
    assert "min_turn_radius_mm" in found["commands[3].turn_radius_m"]
    assert "finite number" in found["commands[4].vx_m_s"]
    assert "unknown key" in found["commands[4].jump"]
    assert "required" in found["commands[5].t"]
    assert "never go back" in found["commands[6].t"]
    assert "upside down" in found["commands[7].mode"]


def test_command_problems_are_reported_with_other_bad_keys() -> None:
    found = _problems({"duration_s": -1, "commands": [{"t": 1, "gait": "gallop"}]})
    assert set(found) == {"duration_s", "commands[0].gait"}


@pytest.mark.parametrize("angle", [-5.0, 51.0, math.inf])
def test_an_impossible_slope_is_a_terrain_problem(angle: float) -> None:
    found = _problems({"duration_s": 5, "terrain": {"slope_deg": angle}})
    assert list(found) == ["terrain.slope_deg"]


def test_an_unknown_terrain_name_lists_the_built_in_ones() -> None:
    found = _problems({"duration_s": 5, "terrain": "moon"})
    assert "course" in found["terrain"]
    assert "slope<deg>" in found["terrain"]


def test_terrain_features_map_onto_the_builders() -> None:
    s = parse_scenario(
        {
            "duration_s": 5,
            "seed": 7,
            "terrain": {
                "steps": {"height_mm": 60, "depth_mm": 350, "count": 2},
                "blocks": [
                    {"size_mm": [100, 100, 100], "at_m": [2.0, 0.3], "mass_kg": 0.3},
                    {"size_mm": [150, 150, 150], "at_m": [3.0, -0.3]},
                ],
                "ditch": {"width_mm": 200, "depth_mm": 100, "at_m": 4.0},
                "rocks": {"count": 5, "area_m": [[5.0, 6.0], [-0.5, 0.5]]},
            },
        }
    )
    kinds = [p.kind for p in s.terrain.parts]
    assert kinds.count("step") == 2
    assert kinds.count("rock") == 5
    assert s.terrain.ground.ditches == ((4.0, 0.2, 0.1),)
    # The rocks follow the scenario's seed unless they have their own.
    again = s.with_overrides(seed=8)
    assert again.seed == 8
    assert again.terrain.parts != s.terrain.parts
    assert s.with_overrides(seed=7).terrain == s.terrain


def test_features_the_builders_refuse_are_problems_of_their_key() -> None:
    found = _problems(
        {
            "duration_s": 5,
            "terrain": {
                "slope_deg": 10,
                "ditch": {"width_mm": 200, "depth_mm": 100, "at_m": 2.0},
                "rocks": {"count": 3, "area_m": [[2.0, 1.0], [0.0, 1.0]]},
            },
            "commands": [{"t": 1, "gait": "gallop"}],
        }
    )
    assert set(found) == {"terrain.ditch", "terrain.rocks.area_m", "commands[0].gait"}
    found = _problems({"duration_s": 5, "terrain": {"ramp": {"angle_deg": 60, "rise_mm": 100}}})
    assert list(found) == ["terrain.ramp.angle_deg"]


def test_a_ditch_under_the_start_is_refused() -> None:
    found = _problems(
        {"duration_s": 5, "terrain": {"ditch": {"width_mm": 400, "depth_mm": 100, "at_m": -0.2}}}
    )
    assert "start" in found["terrain"]


def test_faults_and_config_paths_are_checked_relative_to_the_file(tmp_path: Path) -> None:
    (tmp_path / "plan.toml").write_text("[[faults]]\nkind = 'nonsense'\n", encoding="utf-8")
    found = _problems({"duration_s": 5, "faults": "plan.toml", "config": "missing.toml"}, tmp_path)
    assert "fault plan" in found["faults"]
    assert "kind" in found["faults"]
    assert "robot configuration" in found["config"]
    good = SCENARIO_DIR.parent / "faults" / "noisy-bus.toml"
    s = parse_scenario(
        {"duration_s": 5, "faults": "../faults/noisy-bus.toml", "config": "../whexar.toml"},
        base=SCENARIO_DIR,
    )
    assert s.faults is not None
    assert s.faults.resolve() == good.resolve()
    assert s.config_path is not None
    assert s.config_path.name == "whexar.toml"


def test_a_configuration_given_replaces_the_scenarios_own(tmp_path: Path) -> None:
    stiff = tmp_path / "stiff.toml"
    stiff.write_text("[joints.coxa]\ngains = { p = 1700 }\n", encoding="utf-8")
    s = load_scenario("tripod", config=stiff)
    assert s.config_path == stiff.resolve()
    gains = s.config.joints.by_name("coxa").gains
    assert gains is not None
    assert gains.p == 1700
    assert load_scenario("tripod").config.joints.by_name("coxa").gains is None
    # A bad one is a problem of the scenario's `config`, naming the file and its key.
    bad = tmp_path / "bad.toml"
    bad.write_text("[locomotion]\nstand_up_s = -1\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_scenario("tripod", config=bad)
    (problem,) = info.value.problems
    assert problem.path == "config"
    assert problem.value == str(bad.resolve())
    assert "locomotion.stand_up_s" in problem.allowed


def test_a_missing_file_or_unknown_name_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        load_scenario(tmp_path / "nowhere.toml")
    assert "readable" in str(info.value)
    with pytest.raises(ConfigError) as info:
        load_scenario("no-such-scenario")
    assert "course" in str(info.value)


def test_a_toml_syntax_error_names_its_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('duration_s = 5\nterrain = "flat\n', encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    assert info.value.problems[0].path == "line 2"


def test_overrides_check_their_values() -> None:
    s = load_scenario("slope")
    assert s.with_overrides(duration_s=3).duration_s == 3
    with pytest.raises(ValueError, match="seconds"):
        s.with_overrides(duration_s=0)


def test_the_supply_and_motors_keys() -> None:
    from whexar.sim.power import BenchSupply, LiPoBattery

    bench = parse_scenario({"duration_s": 1.0})
    assert isinstance(bench.spec.supply.build(), BenchSupply)
    assert bench.spec.supply.build().terminal_volts == 12.0
    assert bench.spec.motors == "bam"
    lipo = parse_scenario(
        {
            "duration_s": 1.0,
            "motors": "datasheet",
            "supply": {"kind": "lipo", "capacity_ah": 2.0, "charge": 0.5},
        }
    )
    pack = lipo.spec.supply.build()
    assert isinstance(pack, LiPoBattery)
    assert pack.capacity_ah == 2.0
    assert pack.state_of_charge == 0.5
    assert lipo.spec.supply.build() is not pack  # every run starts afresh
    assert lipo.spec.motors == "datasheet"


def test_a_bad_supply_names_the_key_the_value_and_what_is_allowed() -> None:
    found = _problems(
        {
            "duration_s": 1.0,
            "motors": "strong",
            "supply": {"kind": "lipo", "charge": 1.5, "volts": 14.0},
        }
    )
    assert "'strong'" in found["motors"]
    assert "'bam'" in found["motors"]
    assert "datasheet" in found["motors"]
    assert "1.5" in found["supply.charge"]
    assert "1" in found["supply.charge"]
    found = _problems({"duration_s": 1.0, "supply": {"kind": "mains"}})
    assert "'mains'" in found["supply.kind"]
    assert "lipo" in found["supply.kind"]
    found = _problems({"duration_s": 1.0, "supply": {"capacity_ah": 3.0}})
    assert 'kind = "lipo"' in found["supply.capacity_ah"]
    found = _problems({"duration_s": 1.0, "supply": {"kind": "lipo", "volts": 14.0}})
    assert "14" in found["supply.volts"]


def test_a_battery_refuses_a_plan_that_sets_the_servos_voltage() -> None:
    from whexar.sim.scenario import SCENARIO_DIR

    data = {"duration_s": 1.0, "faults": "../faults/brownout.toml", "supply": {"kind": "lipo"}}
    with pytest.raises(ConfigError) as info:
        parse_scenario(data, "test.toml", base=SCENARIO_DIR)
    (problem,) = info.value.problems
    assert problem.path == "faults"
    assert "voltage_sag" in problem.allowed
