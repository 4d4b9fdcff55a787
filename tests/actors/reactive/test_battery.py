"""The battery reflex's policy, called directly: warn, sit down, shut down (5.3.1)."""

from __future__ import annotations

from collections.abc import Iterable

import pytest

from whexar.actors.messages import (
    BatteryLow,
    BatteryRestored,
    LocomotionState,
    ReflexRequest,
    ServoHealth,
)
from whexar.actors.reactive import Command, Shutdown, check_params
from whexar.actors.reactive.battery import Battery, Stage
from whexar.config import RobotConfig
from whexar.testing.reflexes import locomotion_state

SERVOS = range(1, 43)


def battery(**params: object) -> Battery:
    return Battery(check_params(Battery, params), name="reflex-battery", cfg=RobotConfig())


def readings(t: float, volts: float, servos: Iterable[int] = SERVOS) -> list[ServoHealth]:
    return [ServoHealth(t=t, source="bus", servo_id=s, voltage_v=volts) for s in servos]


def feed(b: Battery, t0: float, t1: float, volts: float, *, every_s: float = 0.2) -> list[Command]:
    """Every servo reads ``volts`` every ``every_s`` from ``t0`` to ``t1``."""
    out: list[Command] = []
    n = round((t1 - t0) / every_s)
    for k in range(n):
        t = t0 + k * every_s
        for msg in readings(t, volts):
            out.extend(b.react(t, msg))
    return out


def seated(t: float) -> LocomotionState:
    return locomotion_state(t, "seated")


def test_a_full_battery_says_nothing() -> None:
    b = battery()
    assert feed(b, 0.0, 10.0, 12.4) == []
    assert b.stage == Stage.NOMINAL
    assert not b.active


def test_a_low_battery_warns_once_after_the_hold_and_recovers_with_hysteresis() -> None:
    b = battery()
    assert feed(b, 0.0, 1.8, 10.6) == []  # not yet held for 2 s
    (low,) = feed(b, 1.8, 6.0, 10.6)
    assert isinstance(low, BatteryLow)
    assert (low.stage, low.voltage_v, low.threshold_v) == ("warning", 10.6, 10.8)
    assert low.t == pytest.approx(2.0)
    assert feed(b, 6.0, 10.0, 10.9) == []  # above warn_v, not above warn_v + recover_v
    (back,) = feed(b, 10.0, 13.0, 11.1)
    assert isinstance(back, BatteryRestored)
    assert b.stage == Stage.NOMINAL


def test_an_empty_battery_sits_the_robot_down_then_shuts_it_down() -> None:
    b = battery()
    said = feed(b, 0.0, 4.0, 10.0)
    empty, sit = said
    assert isinstance(empty, BatteryLow)
    assert empty.stage == "empty"
    assert isinstance(sit, ReflexRequest)
    assert sit.sit_down
    assert sit.reason == "battery at 10.0 V"
    assert b.active
    assert b.reason == "battery at 10.0 V, below 10.2 V: sitting down"
    assert feed(b, 4.0, 8.0, 11.5) == []  # the voltage rises as the load falls: still empty
    (stop,) = b.react(8.0, seated(8.0))
    assert isinstance(stop, Shutdown)
    assert b.stage == Stage.SHUT_DOWN
    assert list(b.react(8.1, seated(8.1))) == []


def test_sags_shorter_than_the_hold_do_not_fire() -> None:
    b = battery()
    out: list[Command] = []
    for k in range(20):  # a 1 s sag to 9.9 V in every 2.5 s
        t0 = k * 2.5
        out += feed(b, t0, t0 + 1.0, 9.9)
        out += feed(b, t0 + 1.0, t0 + 2.5, 11.6)
    assert out == []


def test_one_servo_reading_nonsense_moves_nothing() -> None:
    b = battery()
    out: list[Command] = []
    for k in range(50):
        t = k * 0.2
        for msg in readings(t, 11.8, SERVOS[1:]) + readings(t, 0.0, SERVOS[:1]):
            out.extend(b.react(t, msg))
    assert out == []
    assert b.voltage(9.8) == 11.8


def test_stale_readings_do_not_count() -> None:
    b = battery()
    feed(b, 0.0, 1.0, 11.8)  # the last readings at 0.8 s
    assert b.voltage(5.7) == 11.8
    assert b.voltage(5.9) is None


def test_levels_out_of_order_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"sit_v \(11.0 V\) must be below warn_v \(10.8 V\)"):
        check_params(Battery, {"sit_v": 11.0})
    with pytest.raises(ValueError, match=r"params\.hold_s = 0"):
        check_params(Battery, {"hold_s": 0})
