"""Robot configuration: the shipped file, and every kind of problem named precisely."""

import json
import tomllib
from pathlib import Path
from typing import Any

import pytest

from whexar.cli import main
from whexar.config import RobotConfig, config_schema, load_config, parse_config
from whexar.errors import ConfigError

CONFIG = Path(__file__).resolve().parents[1] / "config" / "whexar.toml"


def _data() -> dict[str, Any]:
    return tomllib.loads(CONFIG.read_text())


def _problems(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ConfigError) as info:
        parse_config(data, "test.toml")
    return {p.path: str(p) for p in info.value.problems}


def test_shipped_file_is_the_thesis_robot() -> None:
    cfg = load_config(CONFIG)
    assert cfg == RobotConfig()
    assert cfg.joints.femur.model == "MX-106"
    assert cfg.joints.tibia.limits_rad is not None
    assert cfg.servo_models["MX-64"].stall_torque_nm == 6.0
    assert cfg.legs[3].servo_ids == (22, 23, 24, 25, 26, 27, 28)
    assert cfg.bus.return_delay_time_us == 20
    assert cfg.gait_selector.wheels.max_tilt_deg == 20  # raised from 7 in 6.7.5


def test_config_check_prints_ok(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "check", str(CONFIG)]) == 0
    assert capsys.readouterr().out.strip() == "ok"


def test_duplicate_id_and_inverted_limit_are_both_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = CONFIG.read_text()
    text = text.replace("servo_ids = [8, 9, 10", "servo_ids = [3, 9, 10")
    text = text.replace("min_deg = -150.0\nmax_deg = 150.0", "min_deg = 150.0\nmax_deg = -150.0")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert main(["config", "check", str(bad)]) == 1
    out = capsys.readouterr().out
    assert "2 problems" in out
    assert "legs[1].servo_ids[0] = 3: servo IDs must be unique" in out
    assert "legs[0].servo_ids[2] (RF femur)" in out
    assert "joints.tibia.min_deg = 150.0: must be below max_deg (-150)" in out
    assert "Traceback" not in out


def test_field_errors_and_section_relations_are_reported_together() -> None:
    data = _data()
    data["bus"]["baudrate"] = 1234
    data["bus"]["return_delay_time_us"] = 21
    data["bus"]["parity"] = "none"
    data["joints"]["femur"]["max_deg"] = "lots"
    data["legs"][5]["servo_ids"][6] = 1
    found = _problems(data)
    assert "1000000" in found["bus.baudrate"]
    assert "1234" in found["bus.baudrate"]
    assert "multiple of 2" in found["bus.return_delay_time_us"]
    assert "unknown key" in found["bus.parity"]
    assert "return_delay_time_us" in found["bus.parity"]
    assert "'lots'" in found["joints.femur.max_deg"]
    assert "unique" in found["legs[5].servo_ids[6]"]


def test_missing_key_and_bad_name() -> None:
    data = _data()
    del data["servo_models"]["MX-28"]["mass_g"]
    data["legs"][2]["name"] = "XX"
    found = _problems(data)
    assert found['servo_models."MX-28".mass_g'].endswith("(missing): required key is missing")
    assert "'XX'" in found["legs[2].name"]


def test_cross_section_checks() -> None:
    data = _data()
    data["dh"]["femur"]["a_mm"] = 140.0
    data["gait_selector"]["tetrapod"]["max_lost_supports"] = 2
    data["stances"]["tall"] = {"reach_mm": 100.0, "height_mm": 500.0}
    data["sensor_board"]["frame_rate_hz"] = 40.0
    data["sensor_board"]["sample_rate_hz"] = 30.0
    data["fsr"]["contact_off_counts"] = 300
    data["legs"][1]["mount_mm"] = [300.0, -74.0, 0.0]
    found = _problems(data)
    assert "within 5 mm of joints.femur.length_mm (127 mm" in found["dh.femur.a_mm"]
    assert "at least tripod's 3" in found["gait_selector.tetrapod.max_lost_supports"]
    assert "reach within its joint limits" in found["stances.tall"]
    assert "sample_rate_hz" in found["sensor_board.frame_rate_hz"]
    assert "hysteresis" in found["fsr.contact_off_counts"]
    assert "left (y > 0)" in found["legs[1].mount_mm[1]"]


def test_legs_must_be_the_six_in_thesis_order() -> None:
    data = _data()
    data["legs"][0], data["legs"][1] = data["legs"][1], data["legs"][0]
    found = _problems(data)
    assert "RF, LF, RM, LM, RR, LR" in found["legs"]


def test_endless_joint_and_protocol() -> None:
    data = _data()
    data["joints"]["wheel"]["min_deg"] = -10.0
    data["joints"]["coxa"]["endless"] = False
    del data["joints"]["coxa"]["max_deg"]
    data["bus"]["protocol"] = 1.0
    found = _problems(data)
    assert "endless joint has no limits" in found["joints.wheel.min_deg"]
    assert "required unless endless" in found["joints.coxa.max_deg"]
    assert "Protocol 2.0" in found["bus.protocol"]


def test_syntax_error_names_the_line(tmp_path: Path) -> None:
    bad = tmp_path / "broken.toml"
    bad.write_text("[robot]\nmass_kg = = 3\n")
    with pytest.raises(ConfigError) as info:
        load_config(bad)
    (problem,) = info.value.problems
    assert problem.path == "line 2"
    assert "valid TOML" in problem.allowed


def test_missing_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["config", "check", str(tmp_path / "nope.toml")]) == 1
    assert "a readable TOML file" in capsys.readouterr().out


def test_programmatic_config_is_checked_too() -> None:
    legs = list(RobotConfig().legs)
    legs[0] = legs[0].model_copy(update={"servo_ids": (8, 2, 3, 4, 5, 6, 7)})
    with pytest.raises(ValueError, match="unique"):
        RobotConfig.model_validate({"legs": [leg.model_dump() for leg in legs]})


def test_unknown_stance_names_the_known_ones() -> None:
    with pytest.raises(ConfigError, match="default"):
        RobotConfig().stance("sprawl")


def test_schema(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema == json.loads(json.dumps(config_schema()))
    assert {"legs", "joints", "dh", "bus", "gait_selector", "stances"} <= set(schema["properties"])
    assert schema["additionalProperties"] is False
