"""The start-up plan, called directly: survey → EEPROM diff → torque plan (no runtime, no
port)."""

from __future__ import annotations

from dynamixel_sdk import COMM_RX_TIMEOUT

from whexar.actors.bus.servos import (
    MODE_POSITION,
    MODE_VELOCITY,
    OPERATING_MODE,
    RETURN_DELAY,
    Servo,
    servo_table,
)
from whexar.actors.bus.startup import eeprom_diff, gains_diff, model_mismatches, plan_start
from whexar.bus import control_table as ct
from whexar.bus.sdk import COMM_SUCCESS, Reply
from whexar.config import RobotConfig, parse_config
from whexar.robot import servo_id

CFG = RobotConfig()
RDT = 10  # Return Delay Time 20 µs, in 2 µs units


def servos() -> list[Servo]:
    return sorted(servo_table(CFG).values(), key=lambda s: s.id)


def surveyed(servo: Servo, **regs: int) -> dict[str, int]:
    """A servo as configured, limp, at 2048, unless ``regs`` say otherwise."""
    return {
        "return_delay_time": RDT,
        "operating_mode": servo.mode,
        "velocity_limit": 265,
        "shutdown": 0x34,
        "torque_enable": 0,
        "hardware_error_status": 0,
        "bus_watchdog": 0,
        "position_d_gain": 0,
        "position_i_gain": 0,
        "position_p_gain": 850,
        "goal_position": 2048,
        "present_position": 2048,
        **regs,
    }


def test_only_the_eeprom_settings_that_differ_are_written() -> None:
    table = servo_table(CFG)
    femur, wheel = table[servo_id(0, "femur")], table[servo_id(0, "wheel")]
    assert eeprom_diff(femur, surveyed(femur), RDT) == []
    assert eeprom_diff(femur, surveyed(femur, return_delay_time=250), RDT) == [(RETURN_DELAY, RDT)]
    assert eeprom_diff(wheel, surveyed(wheel, operating_mode=MODE_POSITION), RDT) == [
        (OPERATING_MODE, MODE_VELOCITY)
    ]


def test_a_robot_standing_under_torque_keeps_its_torque_and_goals() -> None:
    table = servos()
    survey = {s.id: surveyed(s, torque_enable=1, goal_position=2100) for s in table}
    plan = plan_start(table, survey, RDT)
    assert plan.changes == {}
    assert plan.holding == {s.id for s in table}
    assert plan.limp == ()
    assert plan.stopped == ()
    for s in table:
        assert plan.start_ticks[s.id] == (0 if s.endless else 2100)
    # Goals that needed no clamp need no write; the wheels are stopped all the same.
    goals: dict[int, int | None] = dict(plan.start_ticks)
    moved, wheels = plan.hold_writes(goals)
    assert moved == {}
    assert wheels == [s.id for s in table if s.endless]
    # A goal the limits changed is written.
    femur = servo_id(2, "femur")
    moved, _ = plan.hold_writes({**goals, femur: 2000})
    assert moved == {femur: 2000}


def test_torque_goes_off_only_where_eeprom_must_change() -> None:
    table = servos()
    odd, limp = servo_id(1, "tibia"), servo_id(4, "coxa")
    survey = {s.id: surveyed(s, torque_enable=1, present_position=1900) for s in table}
    survey[odd] = surveyed(table[odd - 1], torque_enable=1, return_delay_time=250)
    survey[limp] = surveyed(table[limp - 1], present_position=1900)
    plan = plan_start(table, survey, RDT)
    assert plan.changes == {odd: [(RETURN_DELAY, RDT)]}
    assert plan.limp == (odd, limp)
    assert odd not in plan.holding
    assert limp not in plan.holding
    assert plan.start_ticks[limp] == 1900  # a limp joint starts where it is
    assert plan.start_ticks[servo_id(0, "femur")] == 2048  # a held one keeps its goal


def test_the_survey_gives_each_servo_its_limits_and_finds_watchdog_stops() -> None:
    table = servos()
    survey = {s.id: surveyed(s, velocity_limit=100 + s.id, shutdown=0x24) for s in table}
    survey[5]["bus_watchdog"] = survey[9]["bus_watchdog"] = -1
    plan = plan_start(table, survey, RDT)
    assert plan.stopped == (5, 9)
    assert plan.speed_limits[7] == 107
    assert set(plan.shutdowns.values()) == {0x24}


def test_a_servo_of_another_model_is_named() -> None:
    table = servos()[:3]
    pings = {s.id: Reply(COMM_SUCCESS, value=s.model.model_number) for s in table}
    assert model_mismatches(table, pings) == []
    pings[2] = Reply(COMM_SUCCESS, value=311)
    pings[3] = Reply(COMM_RX_TIMEOUT)  # silent: not a mismatch (it is pinged again)
    (wrong,) = model_mismatches(table, pings)
    assert wrong == (
        "servo 2 (RF trochanter) is a MX-64 (model 311); the configuration says MX-106 (model 321)"
    )


def test_configured_gains_are_written_where_they_differ_and_keep_torque_on() -> None:
    cfg = parse_config({"joints": {"coxa": {"gains": {"p": 3400, "d": 16}}}})
    table = sorted(servo_table(cfg).values(), key=lambda s: s.id)
    coxas = [s.id for s in table if s.joint == 0]
    mx64 = ct.MODELS["MX-64"]
    p_gain, d_gain = mx64.register("position_p_gain"), mx64.register("position_d_gain")
    coxa = table[coxas[0] - 1]
    assert coxa.gains == ((p_gain, 3400), (d_gain, 16))
    assert gains_diff(coxa, surveyed(coxa)) == [(p_gain, 3400), (d_gain, 16)]
    assert gains_diff(coxa, surveyed(coxa, position_d_gain=16)) == [(p_gain, 3400)]
    femur = table[servo_id(0, "femur") - 1]
    assert femur.gains == ()  # not configured: the servo keeps its own
    # A robot standing under torque: the gains are RAM, written under torque.
    survey = {s.id: surveyed(s, torque_enable=1) for s in table}
    survey[coxas[1]] |= {"position_p_gain": 3400, "position_d_gain": 16}  # already set
    plan = plan_start(table, survey, RDT)
    assert sorted(plan.gains) == [c for c in coxas if c != coxas[1]]
    assert plan.changes == {}
    assert plan.holding == {s.id for s in table}
