"""Servo emulator: dynamixel-sdk in the loop, in-process, on bus time."""

from __future__ import annotations

import errno
import math
from dataclasses import dataclass
from pathlib import Path

import pytest
from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    COMM_TX_FAIL,
    GroupBulkRead,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
)

from whexar.bus.control_table import MODELS, HardwareError
from whexar.bus.emulator.chain import ServoChain
from whexar.bus.emulator.dynamics import _trapezoid
from whexar.bus.emulator.port import EmulatedPort
from whexar.bus.emulator.servo import VirtualServo
from whexar.bus.emulator.timing import TimingModel
from whexar.bus.protocol import (
    ALERT,
    BROADCAST_ID,
    Instruction,
    Packet,
    PacketDecoder,
    StatusError,
    encode_instruction,
    read_params,
    split_fast_status,
    sync_read_params,
    write_params,
)
from whexar.config import load_config
from whexar.errors import UsageError
from whexar.robot import JOINT_NAMES
from whexar.testing.bus import servo_chain

CONFIG = Path(__file__).resolve().parents[2] / "config" / "whexar.toml"
PH = PacketHandler(2.0)


@dataclass
class Bus:
    chain: ServoChain
    port: EmulatedPort
    clock: list[float]

    def at(self, t: float) -> None:
        """Continue at bus time ``t``: forget the bus time spent so far."""
        self.port.take_elapsed()
        self.clock[0] = t

    @property
    def ids(self) -> list[int]:
        return sorted(self.chain.servos)


def make_bus(**kw: object) -> Bus:
    clock = [0.0]
    chain = servo_chain(load_config(CONFIG), **kw)
    return Bus(chain, EmulatedPort(chain, lambda: clock[0]), clock)


@pytest.fixture
def bus() -> Bus:
    return make_bus()


def sync_write(bus: Bus, address: int, size: int, values: dict[int, int]) -> int:
    group = GroupSyncWrite(bus.port, PH, address, size)
    for sid, value in values.items():
        group.addParam(sid, list(value.to_bytes(size, "little", signed=value < 0)))
    result: int = group.txPacket()
    return result


def sync_read(bus: Bus, address: int, size: int, fast: bool = False) -> tuple[int, GroupSyncRead]:
    group = GroupSyncRead(bus.port, PH, address, size)
    for sid in bus.ids:
        group.addParam(sid)
    result = group.fastSyncRead() if fast else group.txRxPacket()
    return result, group


# --------------------------------------------------------------------------- basics


def test_ping_reads_each_joints_model(bus: Bus) -> None:
    cfg = load_config(CONFIG)
    for leg in cfg.legs:
        for j, sid in enumerate(leg.servo_ids):
            number, result, error = PH.ping(bus.port, sid)
            assert (result, error) == (COMM_SUCCESS, 0)
            assert number == MODELS[cfg.joints.by_name(JOINT_NAMES[j]).model].model_number
    assert PH.ping(bus.port, 43)[1] == COMM_RX_TIMEOUT
    found, result = PH.broadcastPing(bus.port)
    assert result == COMM_SUCCESS
    assert sorted(found) == list(range(1, 43))
    assert found[2] == [321, VirtualServo.FIRMWARE_VERSION]  # trochanter: MX-106
    assert bus.port.take_elapsed() > 0.8  # the SDK waits its whole broadcast timeout


def test_torque_goal_and_present_position(bus: Bus) -> None:
    sid = 4  # RF tibia, MX-64
    assert PH.read1ByteTxRx(bus.port, sid, 64) == (0, COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(bus.port, sid, 64, 1) == (COMM_SUCCESS, 0)
    assert PH.read1ByteTxRx(bus.port, sid, 64)[0] == 1
    bus.at(1.0)
    assert PH.write4ByteTxRx(bus.port, sid, 116, 2548) == (COMM_SUCCESS, 0)
    assert PH.read1ByteTxRx(bus.port, sid, 122)[0] == 1  # Moving
    bus.at(2.0)
    assert PH.read2ByteTxRx(bus.port, sid, 120)[0] == 2000  # Realtime Tick, ms
    assert PH.read4ByteTxRx(bus.port, sid, 132)[0] == 2548
    assert PH.read1ByteTxRx(bus.port, sid, 122)[0] == 0
    assert PH.read2ByteTxRx(bus.port, sid, 144)[0] == 120  # 12.0 V
    assert PH.read1ByteTxRx(bus.port, sid, 146)[0] == 35  # °C
    # Standby current with torque on: 100 mA ≈ 30 units of 3.36 mA.
    assert PH.read2ByteTxRx(bus.port, sid, 126)[0] == round(0.1 / 0.00336)


def test_trapezoidal_profile_timing(bus: Bus) -> None:
    sid = 3  # RF femur, MX-106
    servo = bus.chain.servos[sid]
    PH.write4ByteTxRx(bus.port, sid, 108, 50)  # Profile Acceleration
    PH.write4ByteTxRx(bus.port, sid, 112, 100)  # Profile Velocity
    PH.write1ByteTxRx(bus.port, sid, 64, 1)
    bus.at(1.0)
    assert PH.write4ByteTxRx(bus.port, sid, 116, 3048)[1] == COMM_SUCCESS
    vmax = 100 * 0.229 / 60 * 4096  # ticks/s
    amax = 50 * 214.577 / 3600 * 4096  # ticks/s²
    total = 1000 / vmax + vmax / amax  # accelerate, cruise, brake
    bus.at(1.0 + total / 2)
    assert PH.read4ByteTxRx(bus.port, sid, 132)[0] == 2548  # symmetric profile: halfway
    assert PH.read4ByteTxRx(bus.port, sid, 128)[0] == 100  # cruising at Profile Velocity
    assert servo.acceleration == 0.0
    bus.at(1.0 + total - 0.05)
    assert PH.read1ByteTxRx(bus.port, sid, 123)[0] == 0x32  # trapezoidal, profile ongoing
    assert 3000 < PH.read4ByteTxRx(bus.port, sid, 132)[0] < 3048
    bus.at(1.0 + total + 1e-6)
    assert PH.read4ByteTxRx(bus.port, sid, 132)[0] == 3048
    assert PH.read1ByteTxRx(bus.port, sid, 122)[0] == 0


@pytest.mark.parametrize(
    ("x", "v", "goal"), [(0.0, 0.0, 900.0), (0.0, 800.0, -300.0), (5, -1e3, 6)]
)
def test_profile_does_not_depend_on_time_slicing(x: float, v: float, goal: float) -> None:
    one = _trapezoid(x, v, goal, 1000.0, 5000.0, 0.3)
    state = (x, v, 0.0)
    for _ in range(300):
        state = _trapezoid(state[0], state[1], goal, 1000.0, 5000.0, 0.001)
    assert state[0] == pytest.approx(one[0], abs=1e-6)
    assert state[1] == pytest.approx(one[1], abs=1e-6)
    assert abs(state[1]) <= 1000.0 + 1e-9
    assert _trapezoid(x, v, goal, 1000.0, 5000.0, 10.0)[:2] == (goal, 0.0)


def test_velocity_mode_ramps_the_wheel(bus: Bus) -> None:
    sid = 7  # RF wheel, MX-28
    assert PH.write1ByteTxRx(bus.port, sid, 11, 1) == (COMM_SUCCESS, 0)  # velocity mode
    PH.write4ByteTxRx(bus.port, sid, 108, 10)
    PH.write1ByteTxRx(bus.port, sid, 64, 1)
    assert PH.write4ByteTxRx(bus.port, sid, 104, 300)[1] == StatusError.DATA_LIMIT  # > 230
    bus.at(1.0)
    assert PH.write4ByteTxRx(bus.port, sid, 104, 200) == (COMM_SUCCESS, 0)
    ramp = 200 * 0.229 * 60 / (10 * 214.577)  # s to reach 200 units at 10 units of accel
    bus.at(1.0 + ramp / 2)
    assert PH.read4ByteTxRx(bus.port, sid, 128)[0] == 100
    bus.at(3.0)
    assert PH.read4ByteTxRx(bus.port, sid, 128)[0] == 200
    assert PH.read4ByteTxRx(bus.port, sid, 132)[0] > 2048 + 4096  # past one turn
    # MX-28 reports Present Load: standby 0.1 A of 1.4 A stall = 7.1 % = 71 units.
    assert PH.read2ByteTxRx(bus.port, sid, 126)[0] == 71


# --------------------------------------------------------------------------- rules


def test_eeprom_is_locked_while_torque_is_on(bus: Bus) -> None:
    assert PH.write1ByteTxRx(bus.port, 10, 9, 10) == (COMM_SUCCESS, 0)
    PH.write1ByteTxRx(bus.port, 10, 64, 1)
    assert PH.write1ByteTxRx(bus.port, 10, 9, 20) == (COMM_SUCCESS, StatusError.ACCESS)
    assert PH.read1ByteTxRx(bus.port, 10, 9)[0] == 10
    assert PH.write2ByteTxRx(bus.port, 10, 0, 99)[1] == StatusError.ACCESS  # read-only
    assert PH.write2ByteTxRx(bus.port, 10, 116, 99)[1] == StatusError.DATA_LENGTH  # half
    assert PH.write1ByteTxRx(bus.port, 10, 68, 3)[1] == StatusError.DATA_RANGE
    assert PH.write1ByteTxRx(bus.port, 10, 700, 1)[1] == StatusError.ACCESS  # beyond table
    assert PH.read1ByteTxRx(bus.port, 10, 700)[2] == StatusError.ACCESS
    assert PH.write2ByteTxRx(bus.port, 7, 102, 10)[1] == StatusError.ACCESS  # MX-28: none


def test_goal_outside_position_limits_is_refused(bus: Bus) -> None:
    sid = 1
    PH.write4ByteTxRx(bus.port, sid, 48, 3000)  # Max Position Limit
    PH.write1ByteTxRx(bus.port, sid, 64, 1)
    assert PH.write4ByteTxRx(bus.port, sid, 116, 3500) == (COMM_SUCCESS, StatusError.DATA_LIMIT)
    assert PH.read4ByteTxRx(bus.port, sid, 116)[0] == 2048
    # Within a sync write nobody answers, but the goal is still refused and counted.
    assert sync_write(bus, 116, 4, {sid: 3600, 2: 2100}) == COMM_SUCCESS
    assert bus.chain.servos[sid].rejected_goals == 2
    assert bus.chain.servos[2].goal == 2100


def test_hardware_error_sets_alert_and_reboot_clears_it(bus: Bus) -> None:
    sid = 9
    servo = bus.chain.servos[sid]
    PH.write1ByteTxRx(bus.port, sid, 64, 1)
    servo.raise_error(HardwareError.OVERLOAD)  # in Shutdown (52) by default
    value, result, error = PH.read1ByteTxRx(bus.port, sid, 70)
    assert (value, result, error) == (HardwareError.OVERLOAD, COMM_SUCCESS, ALERT)
    assert PH.read1ByteTxRx(bus.port, sid, 64)[0] == 0  # shutdown: torque off
    assert PH.write1ByteTxRx(bus.port, sid, 64, 1)[1] == ALERT | StatusError.RESULT_FAIL
    assert PH.reboot(bus.port, sid) == (COMM_SUCCESS, ALERT)  # the status precedes the reboot
    assert PH.read1ByteTxRx(bus.port, sid, 70)[1] == COMM_RX_TIMEOUT  # booting: silent
    bus.at(1.0)  # past the boot time (0.4 s)
    assert PH.read1ByteTxRx(bus.port, sid, 70) == (0, COMM_SUCCESS, 0)
    assert PH.read1ByteTxRx(bus.port, sid, 64)[0] == 0
    assert PH.write1ByteTxRx(bus.port, sid, 64, 1) == (COMM_SUCCESS, 0)


def test_input_voltage_below_the_limit_raises_an_alert_only(bus: Bus) -> None:
    servo = bus.chain.servos[12]
    PH.write1ByteTxRx(bus.port, 12, 64, 1)
    servo.input_voltage_v = 9.0  # Min Voltage Limit 9.5 V
    assert PH.read1ByteTxRx(bus.port, 12, 70) == (HardwareError.INPUT_VOLTAGE, COMM_SUCCESS, ALERT)
    assert PH.read2ByteTxRx(bus.port, 12, 144)[0] == 90
    assert servo.torque_enabled  # input voltage is not in the default Shutdown (52)
    servo.input_voltage_v = 12.0  # the supply is back: the error clears by itself
    assert PH.read1ByteTxRx(bus.port, 12, 70) == (0, COMM_SUCCESS, 0)
    assert servo.torque_enabled


def test_status_return_level_and_reg_write_action(bus: Bus) -> None:
    PH.write1ByteTxRx(bus.port, 20, 68, 1)  # answer Ping and Read only
    assert PH.write1ByteTxRx(bus.port, 20, 65, 1)[0] == COMM_RX_TIMEOUT
    assert bus.port.take_elapsed() > 0.034  # SDK timeout: 11 bytes + 2·16 ms + 2 ms
    assert PH.read1ByteTxRx(bus.port, 20, 65)[:2] == (1, COMM_SUCCESS)
    assert PH.regWriteTxRx(bus.port, 21, 116, 4, list((2222).to_bytes(4, "little")))[0] == 0
    assert PH.read1ByteTxRx(bus.port, 21, 69)[0] == 1
    assert bus.chain.servos[21].goal == 2048
    assert PH.action(bus.port, BROADCAST_ID) == COMM_SUCCESS
    assert bus.chain.servos[21].goal == 2222
    assert PH.read1ByteTxRx(bus.port, 21, 69)[0] == 0


def test_indirect_address_maps_data(bus: Bus) -> None:
    for k in range(4):  # Indirect Data 1–4 → Present Position
        assert PH.write2ByteTxRx(bus.port, 5, 168 + 2 * k, 132 + k) == (COMM_SUCCESS, 0)
    bus.chain.servos[5].set_state(1234.0)
    assert PH.read4ByteTxRx(bus.port, 5, 224)[0] == 1234
    for k in range(4):  # Indirect Data 5–8 → Goal Position
        PH.write2ByteTxRx(bus.port, 5, 176 + 2 * k, 116 + k)
    assert PH.write4ByteTxRx(bus.port, 5, 228, 3000) == (COMM_SUCCESS, 0)
    assert bus.chain.servos[5].goal == 3000


def test_id_change_rekeys_the_chain(bus: Bus) -> None:
    assert PH.write1ByteTxRx(bus.port, 42, 7, 60) == (COMM_SUCCESS, 0)  # answered as 42
    assert 42 not in bus.chain.servos
    assert PH.ping(bus.port, 60)[:2] == (30, COMM_SUCCESS)


def test_raw_requests_follow_the_broadcast_rules(bus: Bus) -> None:
    chain = bus.chain
    t = 0.5
    # Unknown instruction to one ID: Instruction Error; to everyone: silence.
    reply = chain.transact(encode_instruction(3, 0x7E), t).reply
    assert PacketDecoder().feed(reply) == [Packet(3, Instruction.STATUS, b"", 2)]
    assert chain.transact(encode_instruction(BROADCAST_ID, 0x7E), t).reply == b""
    # A broadcast write executes everywhere and answers nowhere.
    tx = chain.transact(
        encode_instruction(BROADCAST_ID, Instruction.WRITE, write_params(65, b"\x01")), t
    )
    assert tx.reply == b""
    assert tx.cost_s == pytest.approx(13 * 10e-6)
    assert all(s.table[65] == 1 for s in chain.servos.values())
    # Broadcast read is not executed; a bad CRC is ignored and counted.
    assert chain.transact(encode_instruction(BROADCAST_ID, 2, read_params(0, 2)), t).reply == b""
    bad = bytearray(encode_instruction(1, Instruction.PING))
    bad[-1] ^= 1
    assert chain.transact(bytes(bad), t).reply == b""
    assert chain.stats.bad_requests == 1
    # Sync read answers in the order the instruction lists the IDs (e-manual).
    request = encode_instruction(
        BROADCAST_ID, Instruction.SYNC_READ, sync_read_params(7, 1, [9, 2, 30])
    )
    replies = PacketDecoder().feed(chain.transact(request, t).reply)
    assert [(p.id, p.params) for p in replies] == [(9, b"\x09"), (2, b"\x02"), (30, b"\x1e")]


# --------------------------------------------------------------------------- group reads


def test_sync_and_bulk_read_through_the_sdk(bus: Bus) -> None:
    for sid, servo in bus.chain.servos.items():
        servo.set_state(1000.0 + sid)
    result, group = sync_read(bus, 126, 10)
    assert result == COMM_SUCCESS
    assert all(group.getData(sid, 132, 4) == 1000 + sid for sid in bus.ids)
    bulk = GroupBulkRead(bus.port, PH)
    bulk.addParam(1, 132, 4)
    bulk.addParam(7, 146, 1)
    bulk.addParam(3, 0, 2)
    assert bulk.txRxPacket() == COMM_SUCCESS
    assert (bulk.getData(1, 132, 4), bulk.getData(7, 146, 1)) == (1001, 35)
    assert bulk.getData(3, 0, 2) == 321


def test_fast_sync_read_works_when_enabled_and_times_out_when_not() -> None:
    fast = make_bus(fast_sync_read=True)
    for sid, servo in fast.chain.servos.items():
        servo.set_state(500.0 + sid)
    result, group = sync_read(fast, 126, 10, fast=True)
    assert result == COMM_SUCCESS
    assert all(group.getData(sid, 132, 4) == 500 + sid for sid in fast.ids)
    reply = fast.port.last.reply if fast.port.last else b""
    assert len(reply) == 8 + 42 * 14  # one packet from 0xFE
    [packet] = PacketDecoder().feed(reply)
    assert [e[1] for e in split_fast_status(packet, 10)] == fast.ids
    # One packet and one Return Delay Time (factory 500 µs) instead of 42.
    timing = fast.chain.timing
    assert fast.port.take_elapsed() == pytest.approx(timing.sync_read_s(42, 10, 500e-6, True))
    assert timing.sync_read_s(42, 10, 500e-6, True) < timing.sync_read_s(42, 10, 500e-6) / 3

    plain = make_bus()
    assert sync_read(plain, 126, 10, fast=True)[0] == COMM_RX_TIMEOUT
    mixed = make_bus(fast_sync_read=True)
    mixed.chain.servos[17].fast_sync_read = False  # this one does not know 0x8A
    assert sync_read(mixed, 126, 10, fast=True)[0] in (COMM_RX_TIMEOUT, COMM_RX_CORRUPT)
    assert sync_read(mixed, 126, 10)[0] == COMM_SUCCESS


# --------------------------------------------------------------------------- timing


def test_bus_time_reproduces_the_thesis_rates(bus: Bus) -> None:
    assert sync_write(bus, 9, 1, dict.fromkeys(bus.ids, 10)) == COMM_SUCCESS  # RDT 20 µs
    assert all(s.return_delay_s == pytest.approx(20e-6) for s in bus.chain.servos.values())
    bus.port.take_elapsed()
    rates = {}
    for name, address, size in [("temperature", 146, 1), ("current", 126, 2), ("position", 132, 4)]:
        assert sync_read(bus, address, size)[0] == COMM_SUCCESS
        rates[name] = 1 / bus.port.take_elapsed()
    assert sync_read(bus, 132, 4)[0] == sync_read(bus, 126, 2)[0] == COMM_SUCCESS
    rates["position+current"] = 1 / bus.port.take_elapsed()
    assert sync_write(bus, 116, 4, dict.fromkeys(bus.ids, 2048)) == COMM_SUCCESS
    rates["goal position"] = 1 / bus.port.take_elapsed()
    assert sync_write(bus, 102, 2, dict.fromkeys(bus.ids, 0)) == COMM_SUCCESS
    rates["goal current"] = 1 / bus.port.take_elapsed()
    thesis = {  # Tables 6.1 and 6.2
        "temperature": 118.18,
        "current": 111.2,
        "position": 100.2,
        "position+current": 52.8,
        "goal position": 446.6,
        "goal current": 714.6,
    }
    for name, hz in thesis.items():
        assert rates[name] == pytest.approx(hz, rel=0.03), name
    timing = bus.chain.timing
    assert 1 / timing.sync_read_s(42, 4, 20e-6) == pytest.approx(rates["position"])
    assert 1 / timing.sync_write_s(42, 4) == pytest.approx(rates["goal position"])
    assert timing.sync_read_s(42, 10, 20e-6, True) < 0.7 * timing.sync_read_s(42, 10, 20e-6)


def test_timing_model_arithmetic() -> None:
    timing = TimingModel(baudrate=2_000_000)
    assert timing.wire_s(100) == pytest.approx(0.5e-3)
    assert timing.write_s(100) == timing.wire_s(100)
    read = timing.read_s(56, 42, 42 * 15, 20e-6)
    assert read == pytest.approx(
        timing.wire_s(56 + 630) + 42 * 20e-6 + timing.turnaround_s + 630 * timing.per_status_byte_s
    )
    with pytest.raises(UsageError):
        TimingModel(baudrate=0)


# --------------------------------------------------------------------------- faults


def test_a_silent_servo_costs_the_sdks_timeout(bus: Bus) -> None:
    bus.chain.faults.silent_until[5] = math.inf
    assert sync_read(bus, 132, 4)[0] == COMM_RX_TIMEOUT
    timeout = ((11 + 4) * 42 * 0.01 + 2 * 16 + 2) / 1000
    assert bus.port.take_elapsed() >= timeout
    bus.chain.faults.silent_until[5] = 1.0  # back at t = 1 s
    bus.at(1.0)
    assert sync_read(bus, 132, 4)[0] == COMM_SUCCESS


def test_dropped_status_packets_time_out(bus: Bus) -> None:
    bus.chain.faults.drop_rate = 1.0
    assert PH.ping(bus.port, 1)[1] == COMM_RX_TIMEOUT
    assert bus.chain.stats.dropped == 1


def test_corrupted_bytes_never_pass_as_data(bus: Bus) -> None:
    for sid, servo in bus.chain.servos.items():
        servo.set_state(100.0 * sid)
    bus.chain.faults.corrupt_rate = 0.002
    outcomes: dict[int, int] = {}
    for _ in range(60):
        result, group = sync_read(bus, 132, 4)
        outcomes[result] = outcomes.get(result, 0) + 1
        if result == COMM_SUCCESS:
            assert all(group.getData(sid, 132, 4) == 100 * sid for sid in bus.ids)
        else:
            assert result in (COMM_RX_TIMEOUT, COMM_RX_CORRUPT)
    assert bus.chain.stats.corrupted > 0
    assert outcomes.get(COMM_SUCCESS, 0) > 0
    assert len(outcomes) > 1


def test_unplugged_port_raises_eio(bus: Bus) -> None:
    bus.chain.faults.unplugged = True
    with pytest.raises(OSError, match="disconnected") as info:
        PH.ping(bus.port, 1)
    assert info.value.errno == errno.EIO


def test_port_at_another_baud_rate_hears_nothing(bus: Bus) -> None:
    assert bus.port.setBaudRate(57600)
    assert not bus.port.setBaudRate(4_500_000)  # not in the SDK's list
    assert PH.ping(bus.port, 1)[1] == COMM_RX_TIMEOUT


def test_hooks_see_every_request(bus: Bus) -> None:
    seen: list[tuple[float, list[int]]] = []
    bus.chain.hooks.append(lambda chain, t, packets: seen.append((t, [p.id for p in packets])))
    bus.at(2.5)
    PH.ping(bus.port, 8)
    assert seen == [(2.5, [8])]


# --------------------------------------------------------------------------- boot, watchdog


def test_a_servo_is_silent_while_it_boots_after_a_power_up(bus: Bus) -> None:
    servo = bus.chain.servos[3]
    PH.write1ByteTxRx(bus.port, 3, 64, 1)
    bus.at(1.0)
    bus.chain.power_up(1.0)
    assert PH.ping(bus.port, 3)[1] == COMM_RX_TIMEOUT
    assert sync_write(bus, 116, 4, {3: 2500}) == COMM_SUCCESS  # unheard while booting
    bus.at(1.0 + servo.boot_time_s - 0.01)
    assert PH.ping(bus.port, 3)[1] == COMM_RX_TIMEOUT
    bus.at(1.0 + servo.boot_time_s)
    assert PH.ping(bus.port, 3)[1] == COMM_SUCCESS
    assert PH.read1ByteTxRx(bus.port, 3, 64)[0] == 0  # RAM at its initial values: torque off
    assert servo.goal != 2500


def test_the_bus_watchdog_stops_a_driving_wheel_and_locks_its_goals(bus: Bus) -> None:
    wheel = 7  # RF wheel: velocity mode
    servo = bus.chain.servos[wheel]
    assert PH.write1ByteTxRx(bus.port, wheel, 11, 1) == (COMM_SUCCESS, 0)  # velocity mode
    assert PH.write1ByteTxRx(bus.port, wheel, 64, 1) == (COMM_SUCCESS, 0)
    assert PH.write4ByteTxRx(bus.port, wheel, 104, 50) == (COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(bus.port, wheel, 98, 5) == (COMM_SUCCESS, 0)  # 5 × 20 ms
    bus.at(0.09)
    assert PH.read4ByteTxRx(bus.port, wheel, 128)[0] == 50  # still driving: fed at 0.09
    bus.at(0.15)
    assert PH.read4ByteTxRx(bus.port, wheel, 128)[0] == 50  # 60 ms since: not yet
    bus.at(0.5)  # silence from 0.15: the watchdog expired at 0.25
    assert PH.read1ByteTxRx(bus.port, wheel, 98)[0] == 0xFF  # −1: Bus Watchdog Error
    assert PH.read4ByteTxRx(bus.port, wheel, 128)[0] == 0
    stopped_at = servo.position
    turned = 50 * 0.229 / 60 * 4096 * 0.25  # ticks from 0 to 0.25 s at 50 units
    # (less the few ms the set-up writes took before the goal: 0.5 s would be 195 more)
    assert stopped_at == pytest.approx(2048 + turned, abs=5)
    assert servo.torque_enabled  # it stops and holds, with torque
    # Goals are read-only until 0 is written to Bus Watchdog; only 0 clears it.
    assert PH.write4ByteTxRx(bus.port, wheel, 104, 60)[1] == StatusError.DATA_RANGE
    assert PH.write1ByteTxRx(bus.port, wheel, 98, 5)[1] == StatusError.DATA_RANGE
    assert PH.write1ByteTxRx(bus.port, wheel, 98, 0) == (COMM_SUCCESS, 0)
    assert PH.write4ByteTxRx(bus.port, wheel, 104, 60) == (COMM_SUCCESS, 0)


def test_the_watchdog_is_fed_only_by_packets_addressed_to_the_servo(bus: Bus) -> None:
    for sid in (7, 14):
        PH.write1ByteTxRx(bus.port, sid, 64, 1)
        PH.write1ByteTxRx(bus.port, sid, 98, 5)
    for k in range(1, 10):
        bus.at(0.05 * k)
        PH.ping(bus.port, 14)  # servo 14 hears a packet every 50 ms, servo 7 none
    assert PH.read1ByteTxRx(bus.port, 14, 98)[0] == 5
    assert PH.read1ByteTxRx(bus.port, 7, 98)[0] == 0xFF
    for k in range(10, 20):
        bus.at(0.05 * k)
        sync_write(bus, 116, 4, {14: 2048})  # a Sync Write that lists it feeds it too
    assert PH.read1ByteTxRx(bus.port, 14, 98)[0] == 5


def test_without_torque_the_watchdog_watches_nothing(bus: Bus) -> None:
    PH.write1ByteTxRx(bus.port, 4, 98, 1)
    bus.at(10.0)
    assert PH.read1ByteTxRx(bus.port, 4, 98)[0] == 1


def test_a_lost_host_write_reaches_no_servo(bus: Bus) -> None:
    bus.chain.faults.tx_fail = 1
    assert sync_write(bus, 116, 4, {2: 2100}) == COMM_TX_FAIL
    assert bus.chain.servos[2].goal == 2048
    assert sync_write(bus, 116, 4, {2: 2100}) == COMM_SUCCESS
    assert bus.chain.servos[2].goal == 2100
