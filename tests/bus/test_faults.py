"""Fault plans: parsing, validation, and each kind of fault seen through the real SDK."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import dynamixel_sdk as dxl
import pytest

from whexar.bus.emulator.faults import (
    EVENTS,
    Fault,
    FaultInjector,
    FaultPlan,
    load_fault_plan,
    parse_fault_plan,
)
from whexar.bus.emulator.port import EmulatedPort
from whexar.config import RobotConfig
from whexar.errors import ConfigError
from whexar.testing.bus import servo_chain

FAULTS_DIR = Path(__file__).resolve().parents[2] / "config" / "faults"


# --------------------------------------------------------------------------- parsing


def _problems(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ConfigError) as exc:
        parse_fault_plan(data, source="plan.toml")
    assert exc.value.source == "plan.toml"
    return {p.path: str(p) for p in exc.value.problems}


def test_example_plans_load() -> None:
    plans = {p.stem: load_fault_plan(p) for p in sorted(FAULTS_DIR.glob("*.toml"))}
    assert set(plans) >= {"dead-femur", "noisy-bus", "overload", "brownout", "unplug"}
    dead = plans["dead-femur"].faults[0]
    assert (dead.kind, dead.ids, dead.at_s, dead.duration_s) == ("silent", [3], 2.0, None)
    overload = plans["overload"].faults[0]
    assert (overload.on, overload.count, overload.bits) == ("sync_write", 10, ["overload"])
    assert plans["noisy-bus"].seed == 1


def test_load_fault_plan_reads_toml(tmp_path: Path) -> None:
    path = tmp_path / "plan.toml"
    path.write_text('seed = 7\n[[faults]]\nkind = "drop"\nrate = 0.5\non = "reboot"\ncount = 2\n')
    plan = load_fault_plan(path)
    assert plan.seed == 7
    assert plan.faults[0].trigger() == "on the 2nd reboot"


def test_a_missing_file_and_bad_toml_are_config_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="a readable TOML file"):
        load_fault_plan(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[[faults]\n")
    with pytest.raises(ConfigError, match="valid TOML"):
        load_fault_plan(bad)


def test_per_key_problems_name_key_value_and_what_is_allowed() -> None:
    found = _problems(
        {
            "seed": 1,
            "faults": [
                {"kind": "corrupt", "rate": 1.5, "at_s": 1},
                {"kind": "sparks", "at_s": 1},
                {"kind": "hardware_error", "ids": [4], "bits": ["overlaod"], "at_s": 0},
                {"kind": "silent", "on": "sink", "ids": [3]},
                {"kind": "silent", "at_s": 1, "colour": "red"},
                {"kind": "silent", "at_s": -1, "ids": [300]},
            ],
        }
    )
    assert (
        found["faults[0].rate"] == "faults[0].rate = 1.5: Input should be less than or equal to 1"
    )
    assert "faults[1].kind = 'sparks'" in found["faults[1].kind"]
    assert "'voltage_sag'" in found["faults[1].kind"]
    assert "faults[2].bits[0] = 'overlaod'" in found["faults[2].bits[0]"]
    assert "'overload'" in found["faults[2].bits[0]"]
    assert "'torque_enabled'" in found["faults[3].on"]
    assert "unknown key; allowed here: kind, ids, at_s, on" in found["faults[4].colour"]
    assert "faults[5].at_s = -1" in found["faults[5].at_s"]
    assert "faults[5].ids[0] = 300" in found["faults[5].ids[0]"]


def test_relational_problems_triggers_and_fields_of_another_kind() -> None:
    found = _problems(
        {
            "faults": [
                {"kind": "silent", "ids": [3]},
                {"kind": "silent", "at_s": 1, "on": "reboot"},
                {"kind": "silent", "at_s": 1, "rate": 0.1, "count": 2},
                {"kind": "corrupt", "at_s": 1},
                {"kind": "drop", "rate": 0.1, "at_s": 1, "ids": [1]},
                {
                    "kind": "hardware_error",
                    "ids": [4],
                    "bits": ["overload"],
                    "at_s": 1,
                    "duration_s": 1.0,
                },
                {"kind": "voltage_sag", "at_s": 1, "bits": ["overload"]},
            ]
        }
    )
    assert found["faults[0].at_s"] == (
        "faults[0].at_s = (missing): a trigger is required: give at_s or on (not both)"
    )
    assert (
        found["faults[1].on"] == "faults[1].on = 'reboot': only one trigger: at_s or on, not both"
    )
    assert found["faults[2].rate"] == (
        "faults[2].rate = 0.1: only for kind corrupt or drop, not 'silent'"
    )
    assert found["faults[2].count"] == "faults[2].count = 2: only with on = an event"
    assert found["faults[3].rate"] == "faults[3].rate = (missing): required for kind 'corrupt'"
    assert "affects the whole bus" in found["faults[4].ids"]
    assert "latched until the servo is rebooted" in found["faults[5].duration_s"]
    assert "faults[6].volts" in found
    assert "only for kind hardware_error" in found["faults[6].bits"]


def test_a_fault_built_in_code_is_checked_too() -> None:
    with pytest.raises(ValueError, match="a trigger is required"):
        Fault(kind="silent")
    fault = Fault(kind="hardware_error", ids=[1, 2], bits=["overload", "overheating"], on="reboot")
    assert fault.describe() == "hardware_error overheating, overload on servos 1, 2"
    assert FaultPlan(faults=[fault]).seed == 0


def test_event_vocabulary() -> None:
    assert "torque_enabled" in EVENTS
    assert {"sync_write", "sync_read", "reboot", "ping", "write", "read"} <= set(EVENTS)


# --------------------------------------------------------------------------- injection

CFG = RobotConfig()
IDS = [sid for leg in CFG.legs for sid in leg.servo_ids]


class Bus:
    """A chain of WHexaR's 42 servos, a fault plan on it, and the real SDK over EmulatedPort."""

    def __init__(self, *faults: dict[str, Any], seed: int = 0) -> None:
        self.t = 0.0
        self.chain = servo_chain(CFG, return_delay_us=20)
        plan = parse_fault_plan({"seed": seed, "faults": list(faults)})
        self.injector = FaultInjector(plan).attach(self.chain)
        self.port = EmulatedPort(self.chain, lambda: self.t)
        self.ph = dxl.PacketHandler(2.0)

    def at(self, t: float) -> Bus:
        """Bus time ``t`` for the next transactions (each then adds its own cost)."""
        self.t = t
        self.port.take_elapsed()
        return self

    def ping(self, sid: int) -> int:
        _, result, _ = self.ph.ping(self.port, sid)
        return int(result)

    def read1(self, sid: int, address: int) -> tuple[int, int, int]:
        value, result, error = self.ph.read1ByteTxRx(self.port, sid, address)
        return int(value), int(result), int(error)

    def sync_read(self, start: int = 126, length: int = 10) -> int:
        group = dxl.GroupSyncRead(self.port, self.ph, start, length)
        for sid in IDS:
            group.addParam(sid)
        return int(group.txRxPacket())

    def sync_write(self, ids: list[int], address: int = 116, data: bytes = b"\0\x08\0\0") -> None:
        group = dxl.GroupSyncWrite(self.port, self.ph, address, len(data))
        for sid in ids:
            group.addParam(sid, data)
        assert group.txPacket() == dxl.COMM_SUCCESS

    def texts(self) -> list[str]:
        return [f"{t:g} {text}" for t, text in self.injector.log]


OK, TIMEOUT, CORRUPT = dxl.COMM_SUCCESS, dxl.COMM_RX_TIMEOUT, dxl.COMM_RX_CORRUPT
HW_ERROR = 70
ALERT = 0x80


def test_silent_servo_times_out_from_at_s_for_its_duration() -> None:
    bus = Bus({"kind": "silent", "ids": [3], "at_s": 2.0, "duration_s": 1.0})
    assert bus.at(1.0).ping(3) == OK
    assert bus.at(2.5).ping(3) == TIMEOUT
    assert bus.ping(4) == OK
    assert bus.sync_read() == TIMEOUT  # the SDK's group stops at the silent servo
    assert bus.at(3.2).ping(3) == OK
    assert bus.texts() == [
        "2 fault 0: silent servo 3 started (at 2 s, until 3.000 s)",
        "3 fault 0: silent servo 3 ended",
    ]
    assert bus.injector.active == []


def test_silent_for_good_with_every_servo() -> None:
    bus = Bus({"kind": "silent", "at_s": 0.0})
    assert bus.at(100.0).ping(1) == TIMEOUT
    assert bus.ping(42) == TIMEOUT
    assert "(at 0 s, for good)" in bus.texts()[0]


def test_corrupt_status_bytes_fail_the_crc_until_the_fault_ends() -> None:
    bus = Bus({"kind": "corrupt", "rate": 1e-3, "at_s": 1.0, "duration_s": 2.0}, seed=3)
    assert [bus.at(0.5 + 0.01 * k).sync_read() for k in range(5)] == [OK] * 5
    during = [bus.at(1.0 + 0.01 * k).sync_read() for k in range(30)]
    assert during.count(CORRUPT) >= 5, during
    assert bus.chain.stats.corrupted > 0
    assert [bus.at(3.0 + 0.01 * k).sync_read() for k in range(5)] == [OK] * 5
    assert bus.chain.faults.corrupt_rate == 0.0


def test_the_seed_makes_corruption_repeatable() -> None:
    def run(seed: int) -> list[int]:
        bus = Bus({"kind": "corrupt", "rate": 1e-3, "at_s": 0.0}, seed=seed)
        return [bus.at(0.01 * k).sync_read() for k in range(20)]

    assert run(5) == run(5)
    assert run(5) != run(6)


def test_drop_loses_status_packets() -> None:
    bus = Bus({"kind": "drop", "rate": 1.0, "on": "ping", "count": 2, "duration_s": 0.5})
    assert bus.at(0.0).ping(1) == OK
    assert bus.at(0.1).ping(1) == OK  # the 2nd ping triggers; it is answered
    assert bus.at(0.2).ping(1) == TIMEOUT
    assert bus.at(0.2).sync_read() == TIMEOUT
    assert bus.at(0.7).ping(1) == OK
    assert bus.chain.stats.dropped >= 2


def test_overload_on_the_nth_sync_write_that_includes_the_servo_latches_until_reboot() -> None:
    bus = Bus(
        {"kind": "hardware_error", "ids": [4], "bits": ["overload"], "on": "sync_write", "count": 3}
    )
    assert bus.ph.write1ByteTxRx(bus.port, 4, 64, 1) == (OK, 0)  # torque on
    bus.sync_write(IDS)
    bus.sync_write([1, 2])  # does not include servo 4: not counted
    bus.sync_write(IDS)
    assert bus.read1(4, HW_ERROR) == (0, OK, 0)
    bus.sync_write(IDS)  # the 3rd: the error starts after it
    assert bus.read1(4, HW_ERROR) == (0x20, OK, ALERT)
    assert bus.read1(4, 64) == (0, OK, ALERT)  # overload is in Shutdown: torque went off
    assert bus.read1(5, HW_ERROR) == (0, OK, 0)
    assert bus.at(50.0).read1(4, HW_ERROR) == (0x20, OK, ALERT)  # latched
    assert bus.ph.reboot(bus.port, 4) == (OK, ALERT)
    assert bus.read1(4, HW_ERROR)[1] == TIMEOUT  # booting
    assert bus.at(51.0).read1(4, HW_ERROR) == (0, OK, 0)
    assert [text for _, text in bus.injector.log] == [
        "fault 0: hardware_error overload on servo 4 started "
        "(on the 3rd sync_write, latched until reboot)"
    ]


def test_voltage_sag_below_min_voltage_limit_flags_input_voltage() -> None:
    bus = Bus(
        {"kind": "voltage_sag", "ids": [5], "volts": 9.0, "at_s": 1.0, "duration_s": 1.0},
        {"kind": "voltage_sag", "ids": [6], "volts": 10.0, "at_s": 1.0, "duration_s": 1.0},
    )
    volts, result, _ = bus.ph.read2ByteTxRx(bus.port, 5, 144)
    assert (volts, result) == (120, OK)
    bus.at(1.0).ping(1)
    bus.at(1.5)
    assert bus.ph.read2ByteTxRx(bus.port, 5, 144) == (90, OK, ALERT)
    assert bus.read1(5, HW_ERROR) == (0x01, OK, ALERT)
    assert bus.ph.read2ByteTxRx(bus.port, 6, 144) == (100, OK, 0)  # above 9.5 V: no error
    assert bus.read1(6, HW_ERROR) == (0, OK, 0)
    bus.at(2.5)
    # Input voltage is not in Shutdown (52): the error clears when the supply returns.
    assert bus.ph.read2ByteTxRx(bus.port, 5, 144) == (120, OK, 0)
    assert bus.read1(5, HW_ERROR) == (0, OK, 0)
    assert bus.chain.servos[5].input_voltage_v == 12.0


def test_unplug_on_torque_enabled_then_the_port_raises() -> None:
    bus = Bus({"kind": "unplug", "on": "torque_enabled"})
    assert bus.ph.write1ByteTxRx(bus.port, 2, 64, 0) == (OK, 0)  # torque off: not the event
    assert bus.ph.write1ByteTxRx(bus.port, 2, 64, 1) == (OK, 0)  # the trigger is answered
    with pytest.raises(OSError, match="disconnected"):
        bus.ping(1)
    bus.port.is_using = False  # the SDK leaves its port busy after an exception
    with pytest.raises(OSError, match="disconnected"):
        bus.ping(1)
    assert bus.chain.faults.unplugged


def test_a_timed_unplug_ends_when_the_injector_is_updated() -> None:
    bus = Bus({"kind": "unplug", "at_s": 1.0, "duration_s": 0.5})
    assert bus.at(0.5).ping(1) == OK
    with pytest.raises(OSError, match="disconnected"):
        bus.at(1.0).ping(1)
    bus.injector.update(1.6)  # EmulatedPort sends nothing while unplugged
    bus.port.is_using = False  # the SDK leaves its port busy after an exception
    assert bus.at(1.6).ping(1) == OK


def test_torque_enabled_by_sync_write_counts_per_request_for_the_ids() -> None:
    bus = Bus({"kind": "silent", "ids": [7], "on": "torque_enabled", "count": 2})
    bus.sync_write([1, 2, 3], address=64, data=b"\x01")  # not servo 7
    bus.sync_write(IDS, address=64, data=b"\x01")  # 1st
    assert bus.ping(7) == OK
    bus.sync_write(IDS, address=64, data=b"\x00")  # torque off: not counted
    bus.sync_write(IDS, address=64, data=b"\x01")  # 2nd
    assert bus.ping(7) == TIMEOUT
    assert bus.ping(6) == OK


def test_reboot_event_and_fault_on_a_servo_not_on_the_bus() -> None:
    bus = Bus({"kind": "hardware_error", "ids": [9], "bits": ["overheating"], "on": "reboot"})
    assert bus.ph.reboot(bus.port, 9) == (OK, 0)
    assert bus.at(1.0).read1(9, HW_ERROR) == (0x04, OK, ALERT)  # after the boot
    plan = parse_fault_plan({"faults": [{"kind": "silent", "ids": [1, 43], "at_s": 0}]})
    with pytest.raises(ConfigError, match=r"faults\[0\]\.ids = 43: an ID on the bus: 1–42"):
        FaultInjector(plan).attach(servo_chain(CFG))
