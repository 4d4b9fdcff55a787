"""Robot configuration: the shipped file, and every kind of problem named precisely."""

import json
import tomllib
import typing
from pathlib import Path
from typing import Any

import pytest
from pydantic import BaseModel

from whexar.cli import main
from whexar.config import BusSpec, RobotConfig, config_schema, load_config, parse_config
from whexar.errors import ConfigError
from whexar.sensors.usart import BOARD_BAUDRATES, usart_setting

CONFIG = Path(__file__).resolve().parents[2] / "config" / "whexar.toml"


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
    data["stances"]["crouch sideways"] = {"reach_mm": 200.0}  # a new stance needs its keys
    del data["legs"][3]["mount_mm"]  # an array item replaces the default whole
    data["legs"][2]["name"] = "XX"
    found = _problems(data)
    assert found['stances."crouch sideways".height_mm'].endswith(
        "(missing): required key is missing"
    )
    assert "required key is missing" in found["legs[3].mount_mm"]
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
    data["joints"]["coxa"]["endless"] = True  # its limits stay: a file cannot delete keys
    data["joints"]["wheel"]["endless"] = False  # and the wheel's are absent by default
    data["joints"]["wheel"]["max_deg"] = 10.0
    data["bus"]["protocol"] = 1.0
    found = _problems(data)
    assert "endless joint has no limits" in found["joints.coxa.min_deg"]
    assert "required unless endless" in found["joints.wheel.min_deg"]
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


# --------------------------------------------------------------------------- partial files


def _load(tmp_path: Path, text: str) -> RobotConfig:
    path = tmp_path / "robot.toml"
    path.write_text(text)
    return load_config(path)


def _load_problems(tmp_path: Path, text: str) -> dict[str, str]:
    path = tmp_path / "robot.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    return {p.path: str(p) for p in info.value.problems}


def test_a_file_needs_only_the_keys_it_changes(tmp_path: Path) -> None:
    cfg = _load(tmp_path, "[joints.femur]\nmin_deg = -100\n")
    default = RobotConfig()
    assert cfg.joints.femur.min_deg == -100
    assert cfg.joints.femur.model == default.joints.femur.model == "MX-106"
    assert cfg.joints.femur.max_deg == default.joints.femur.max_deg
    assert cfg.joints.femur.length_mm == default.joints.femur.length_mm
    assert cfg.joints.tibia == default.joints.tibia
    assert cfg.model_copy(update={"joints": default.joints}) == default
    assert _load(tmp_path, "") == default
    deep = _load(tmp_path, "[sensor_board.accelerometer]\nfitted = true\n")
    assert deep.sensor_board.accelerometer.fitted is True
    assert deep.sensor_board.accelerometer.counts_per_g == (67.5, 67.5, 67.5)
    assert deep.sensor_board.port == "/dev/ttyACM0"


def test_mapping_sections_merge_by_key(tmp_path: Path) -> None:
    cfg = _load(
        tmp_path,
        "[stances.crouch]\nreach_mm = 230.0\nheight_mm = 220.0\n"
        "[stances.high]\nheight_mm = 370.0\n"
        '[servo_models."MX-64"]\nmass_g = 140.0\n',
    )
    default = RobotConfig()
    assert set(cfg.stances) == {*default.stances, "crouch"}  # added, none lost
    assert cfg.stances["crouch"].front_rear_yaw_deg == 0.0
    assert cfg.stances["high"].height_mm == 370.0
    assert cfg.stances["high"].reach_mm == default.stances["high"].reach_mm  # partly changed
    assert cfg.stances["high"].front_rear_yaw_deg == 25.0
    assert cfg.stances["low"] == default.stances["low"]
    assert cfg.servo_models["MX-64"].mass_g == 140.0
    assert cfg.servo_models["MX-64"].stall_torque_nm == 6.0


def test_arrays_replace_the_default_whole(tmp_path: Path) -> None:
    one_leg = '[[legs]]\nname = "RF"\nmount_mm = [300.0, -74.0, 0.0]\n'
    one_leg += "servo_ids = [1, 2, 3, 4, 5, 6, 7]\n"
    found = _load_problems(tmp_path, one_leg)
    assert "exactly six legs" in found["legs"]
    cfg = _load(tmp_path, "[sensor_board.accelerometer]\nzero_g_counts = [330.0, 340.0, 350.0]\n")
    assert cfg.sensor_board.accelerometer.zero_g_counts == (330.0, 340.0, 350.0)
    found = _load_problems(tmp_path, "[sensor_board.accelerometer]\ncounts_per_g = [67.5]\n")
    assert set(found) == {  # not padded from the default: the array is the file's
        "sensor_board.accelerometer.counts_per_g[1]",
        "sensor_board.accelerometer.counts_per_g[2]",
    }


def test_partial_files_keep_every_problem_with_its_key_path(tmp_path: Path) -> None:
    # Relations between a file's keys and the defaults it did not write.
    found = _load_problems(
        tmp_path,
        "[joints.femur]\nmin_deg = 130\n"  # above the default max_deg
        "[dh.tibia]\na_mm = 150.0\n"  # against the default segment length
        "[fsr]\ncontact_off_counts = 250\n"  # against the default contact_on_counts
        "[gait_selector.ripple]\nmax_tilt_deg = 10.0\n"  # below tetrapod's default
        "[stances.tall]\nreach_mm = 100.0\nheight_mm = 500.0\n",  # unreachable
    )
    assert (
        "joints.femur.min_deg = 130.0: must be below max_deg (120)" in found["joints.femur.min_deg"]
    )
    assert "joints.tibia.length_mm (124 mm" in found["dh.tibia.a_mm"]
    assert "hysteresis" in found["fsr.contact_off_counts"]
    assert "at least tetrapod's 25" in found["gait_selector.ripple.max_tilt_deg"]
    assert set(found) == {
        "joints.femur.min_deg",
        "dh.tibia.a_mm",
        "fsr.contact_off_counts",
        "gait_selector.ripple.max_tilt_deg",
    }  # the stance check waits for valid joints: limits it could not trust
    found = _load_problems(tmp_path, "[stances.tall]\nreach_mm = 100.0\nheight_mm = 500.0\n")
    assert "reach within its joint limits" in found["stances.tall"]
    # A bad key still leaves the other sections' relations checked.
    found = _load_problems(tmp_path, "[joints.femur]\nsize = 3\n[fsr]\ncontact_off_counts = 250\n")
    assert "unknown key; allowed here: model, min_deg" in found["joints.femur.size"]
    assert "hysteresis" in found["fsr.contact_off_counts"]


def test_position_gains_are_register_values_for_positioned_joints(tmp_path: Path) -> None:
    found = _load_problems(tmp_path, "[joints.coxa]\ngains = { p = 20000, x = 1 }\n")
    assert "less than or equal to 16383" in found["joints.coxa.gains.p"]
    assert "allowed here: p, i, d" in found["joints.coxa.gains.x"]
    found = _load_problems(tmp_path, "[joints.wheel]\ngains = { p = 900 }\n")
    assert "velocity control" in found["joints.wheel.gains"]
    path = tmp_path / "ok.toml"
    path.write_text("[joints.femur]\ngains = { i = 40 }\n")
    femur = load_config(path).joints.femur
    assert femur.gains is not None
    assert femur.gains.registers() == {"position_i_gain": 40}
    assert femur.min_deg == RobotConfig().joints.femur.min_deg  # the rest stays


def test_the_schema_follows_the_merge_rule() -> None:
    schema = config_schema()
    defs = schema["$defs"]

    def target(node: dict[str, Any]) -> dict[str, Any]:
        ref = node.get("$ref")
        return defs[ref.rsplit("/", 1)[-1]] if ref else node

    joints = target(schema["properties"]["joints"])
    femur = target(joints["properties"]["femur"])
    assert "required" not in femur  # [joints.femur] with only min_deg is a valid file
    assert set(femur["properties"]) == {
        "model",
        "min_deg",
        "max_deg",
        "endless",
        "length_mm",
        "gains",
    }
    stances = schema["properties"]["stances"]
    assert "required" not in target(stances["properties"]["high"])  # a preset, partly changed
    assert set(target(stances["additionalProperties"])["required"]) == {"reach_mm", "height_mm"}
    leg = target(schema["properties"]["legs"]["items"])
    assert set(leg["required"]) == {"name", "mount_mm", "servo_ids"}  # array items: whole
    assert not [name for name, d in defs.items() if name.endswith("Partial") and "required" in d]


def test_shipped_file_spells_out_every_key() -> None:
    # Merging would hide a key missing from the documented file; it may leave out
    # only keys at their model's own default (endless = false, theta_sign = 1…),
    # as it could before files were merged.
    def omitted(model: BaseModel, table: dict[str, Any], at: str) -> list[str]:
        found = []
        for name, field in type(model).model_fields.items():
            value = getattr(model, name)
            path = f"{at}.{name}" if at else name
            if name not in table:
                if field.is_required() or value != field.get_default(call_default_factory=True):
                    found.append(path)
            elif isinstance(value, BaseModel):
                found += omitted(value, table[name], path)
            elif isinstance(value, dict):
                for key, item in value.items():
                    if isinstance(item, BaseModel):
                        found += omitted(item, table[name].get(key, {}), f"{path}.{key}")
        return found

    assert omitted(RobotConfig(), _data(), "") == []


# --------------------------------------------------------------------------- device limits


def test_sensor_board_baudrate_is_a_rate_the_board_runs_at(tmp_path: Path) -> None:
    assert BOARD_BAUDRATES == (76800, 250_000, 500_000, 1_000_000, 2_000_000)
    for rate in BOARD_BAUDRATES:
        assert _load(tmp_path, f"[sensor_board]\nbaudrate = {rate}\n").sensor_board.baudrate == rate
    cases = {
        115200: "(U2X, UBRR = 16) gives 117647 bps, +2.1 %",
        57600: "(normal speed, UBRR = 16) gives 58824 bps, +2.1 %",
        230400: "-3.5 %",
        38400: "too slow for 127-byte frames at 50 Hz (63500 bps)",
        1_000_001: "not one of the datasheet's rates",
        0: "not a rate",
    }
    for rate, why in cases.items():
        found = _load_problems(tmp_path, f"[sensor_board]\nbaudrate = {rate}\n")
        problem = found["sensor_board.baudrate"]
        assert f"sensor_board.baudrate = {rate}" in problem
        assert "76800, 250000, 500000, 1000000, 2000000" in problem
        assert why in problem, problem


def test_usart_rule_matches_the_datasheet_table() -> None:
    # ATmega2560 datasheet, Table 22-12 (16 MHz): UBRR and error with U2X = 1.
    table = {
        2400: (832, 0.0),
        9600: (207, 0.2),
        28800: (68, 0.6),
        76800: (25, 0.2),
        115200: (16, 2.1),
        230400: (8, -3.5),
        250000: (7, 0.0),
        1_000_000: (1, 0.0),
        2_000_000: (0, 0.0),
    }
    for rate, (ubrr, error_pct) in table.items():
        setting = usart_setting(rate)
        assert setting.u2x
        assert (setting.ubrr, round(100 * setting.error, 1)) == (ubrr, error_pct)
    # The Arduino core forces normal speed for 57600 at 16 MHz: UBRR 16, +2.1 %
    # (U2X = 0 column), where U2X with UBRR 34 would give -0.8 %.
    s57 = usart_setting(57600)
    assert (s57.u2x, s57.ubrr, round(100 * s57.error, 1), s57.ok) == (False, 16, 2.1, False)


def test_servo_bus_baudrates_are_the_mx_rates_the_sdk_can_set() -> None:
    # MX (2.0) Baud Rate register (8): 9600, 57600, 115200, 1M, 2M, 3M, 4M, 4.5M
    # (ROBOTIS e-manual). dynamixel-sdk's setBaudRate accepts all but 4.5M.
    from dynamixel_sdk import PortHandler

    mx2 = (9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000)
    sdk = PortHandler("/dev/null")
    usable = {rate for rate in mx2 if sdk.getCFlagBaud(rate) > 0}
    allowed = set(typing.get_args(BusSpec.model_fields["baudrate"].annotation))
    assert allowed == usable == set(mx2) - {4_500_000}
