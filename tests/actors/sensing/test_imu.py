"""The LSM9DS1 driver, its register-level fake, and the IMU reader on virtual time.

Register values and sensitivities are written out here from the datasheet
(DocID025715, Table 3 and section 7), not taken from the driver, so a wrong
constant in the driver fails a test. The reader runs against
:class:`~whexar.sensors.imu_emulator.FakeLsm9ds1` through the real runtime.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from whexar.actors.messages import (
    AccelImplausible,
    AccelPlausible,
    BodyTilt,
    ImuSample,
    SensorLinkDown,
    SensorLinkFresh,
    SensorLinkStale,
    SensorLinkUp,
)
from whexar.actors.sensing.imu import ImuReader, open_bus
from whexar.config import load_config
from whexar.errors import ConfigError, DeviceError, DeviceGoneError, UsageError
from whexar.runtime.devices import DEVICES
from whexar.runtime.messages import ActorFailed, Event, TickOverrun
from whexar.runtime.wiring import WiringError
from whexar.sensors import lsm9ds1
from whexar.sensors.imu_emulator import I2C_BUS, FakeLsm9ds1, FakeSMBus
from whexar.sensors.lsm9ds1 import Lsm9ds1, choose_odr, decode_xyz, settings
from whexar.testing import Harness, RunResult, Scenario, run_actors, thesis
from whexar.testing.imu import imu_graph

G = 9.81
"""The table's m/s² per g (6.1.3 compares its readings with 9.81)."""

# Table 6.4 (6.1.3), rows 2–19 as printed, then row 1 with the sign of Z that its
# calculated angle needs (see whexar.testing.thesis).
_ANGLE, _X, _Y, _Z, _CALC = thesis.TABLE_6_4[0]
TABLE_6_4 = [*thesis.TABLE_6_4[1:], (_ANGLE, _X, _Y, -_Z, _CALC)]

LINK = "i2c-1:0x6b"
LINK_EVENTS = (SensorLinkDown, SensorLinkUp, SensorLinkStale, SensorLinkFresh)


@pytest.fixture
def chip() -> Iterator[FakeLsm9ds1]:
    """A fake LSM9DS1 at 0x6B on fake bus 1, registered as ``fake:test``."""
    bus = FakeSMBus(1)
    made = bus.attach(0x6B, FakeLsm9ds1())
    DEVICES.register(I2C_BUS, "test", bus)
    yield made
    DEVICES.unregister(I2C_BUS, "test")


def driver(accel_g: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> tuple[Lsm9ds1, FakeLsm9ds1]:
    bus = FakeSMBus(1)
    fake = bus.attach(0x6B, FakeLsm9ds1(accel_g=accel_g))
    return Lsm9ds1(bus, 0x6B, name=LINK), fake


def run(
    scenario: Scenario | None = None,
    *,
    duration: float | None = None,
    params: dict[str, object] | None = None,
    device: str = "fake:test",
) -> RunResult:
    return run_actors(
        imu_graph(device, params, max_restarts=0),
        duration=duration,
        scenario=scenario,
    )


def link_events(result: RunResult) -> list[Event]:
    return [e for e in result.events() if isinstance(e, LINK_EVENTS)]


def names(events: list[Event]) -> list[str]:
    return [type(e).__name__ for e in events]


# --------------------------------------------------------------------------- pure driver


def test_odr_is_the_lowest_at_or_above_the_rate() -> None:
    assert choose_odr(50) == (2, 59.5)  # the default 50 Hz: the chip samples at 59.5 Hz
    assert choose_odr(1) == (1, 14.9)
    assert choose_odr(14.9) == (1, 14.9)
    assert choose_odr(59.5) == (2, 59.5)
    assert choose_odr(60) == (3, 119.0)
    assert choose_odr(200) == (4, 238.0)
    assert choose_odr(400) == (5, 476.0)
    assert choose_odr(952) == (6, 952.0)
    for bad in (953, 0, -1, math.nan, math.inf):
        with pytest.raises(UsageError, match="rate_hz"):
            choose_odr(bad)


def test_sensitivities_are_table_3() -> None:
    # LA_So mg/LSB for ±2/4/8/16 g and G_So mdps/LSB for 245/500/2000 dps.
    assert lsm9ds1.accel_scale(2)[1] == pytest.approx(0.061e-3)
    assert lsm9ds1.accel_scale(4)[1] == pytest.approx(0.122e-3)
    assert lsm9ds1.accel_scale(8)[1] == pytest.approx(0.244e-3)
    assert lsm9ds1.accel_scale(16)[1] == pytest.approx(0.732e-3)
    assert lsm9ds1.gyro_scale(245)[1] == pytest.approx(8.75e-3)
    assert lsm9ds1.gyro_scale(500)[1] == pytest.approx(17.5e-3)
    assert lsm9ds1.gyro_scale(2000)[1] == pytest.approx(70e-3)
    with pytest.raises(UsageError, match="accel_range_g = 3"):
        lsm9ds1.accel_scale(3)
    with pytest.raises(UsageError, match="gyro_range_dps = 1000"):
        lsm9ds1.gyro_scale(1000)


def test_decode_is_little_endian_int16_times_scale() -> None:
    # X = 0x4000 = 16384, Y = 0xC000 = −16384, Z = 0x7FFF = 32767 (the saturated end).
    x, y, z = decode_xyz([0x00, 0x40, 0x00, 0xC0, 0xFF, 0x7F], 0.061e-3)
    assert x == pytest.approx(0.999424)
    assert y == pytest.approx(-0.999424)
    assert z == pytest.approx(1.998787)
    assert decode_xyz([0x00, 0x80, 0x01, 0x00, 0, 0], 70e-3) == pytest.approx((-2293.76, 0.07, 0))
    with pytest.raises(UsageError, match="5 bytes"):
        decode_xyz([0, 0, 0, 0, 0], 1.0)


@pytest.mark.parametrize(
    ("rate_hz", "accel_g", "gyro_dps", "reg1_g", "reg6_xl"),
    [
        # ODR bits 7:5; FS bits 4:3. FS_XL 00 ±2 g, 10 ±4 g, 11 ±8 g, 01 ±16 g.
        (50, 2, 245, 0b010_00_000, 0b010_00_000),
        (100, 4, 500, 0b011_01_000, 0b011_10_000),
        (50, 8, 245, 0b010_00_000, 0b010_11_000),
        (200, 16, 2000, 0b100_11_000, 0b100_01_000),
        (10, 2, 245, 0b001_00_000, 0b001_00_000),
        (952, 2, 245, 0b110_00_000, 0b110_00_000),
    ],
)
def test_settings_register_values(
    rate_hz: float, accel_g: int, gyro_dps: int, reg1_g: int, reg6_xl: int
) -> None:
    s = settings(rate_hz, accel_g, gyro_dps)
    assert s.value(0x10) == reg1_g  # CTRL_REG1_G
    assert s.value(0x20) == reg6_xl  # CTRL_REG6_XL
    assert s.value(0x22) == 0x44  # CTRL_REG8: BDU (bit 6) and IF_ADD_INC (bit 2)
    # CTRL_REG1_G last: setting its ODR starts both sensors, after everything else is set.
    assert s.registers[-1][0] == 0x10


# --------------------------------------------------------------------------- driver on the fake


def test_configure_writes_the_registers_and_reads_them_back() -> None:
    dev, fake = driver()
    assert fake.register(0x10) == 0
    assert fake.register(0x22) == 0x04
    done = dev.configure(50, 8, 500)
    assert done.odr_hz == 59.5
    assert fake.register(0x10) == 0b010_01_000  # 59.5 Hz, ±500 dps
    assert fake.register(0x20) == 0b010_11_000  # 59.5 Hz, ±8 g
    assert fake.register(0x22) == 0x44
    assert fake.register(0x13) == 0  # no gyroscope axis sign flips
    assert fake.register(0x1E) == 0x38
    assert fake.register(0x1F) == 0x38
    n = len(done.registers)
    assert fake.transactions == 2 * n  # one write and one read-back each


def test_configure_overrides_a_state_left_by_another_program() -> None:
    dev, fake = driver()
    fake.write(0x13, 0b111000)  # all gyroscope signs flipped
    fake.write(0x2E, 0xC0)  # FIFO in continuous mode
    dev.configure(50, 2, 245)
    assert fake.register(0x13) == 0
    assert fake.register(0x2E) == 0


def test_configure_refuses_a_chip_that_does_not_keep_its_registers() -> None:
    class DeafBus(FakeSMBus):
        def write_byte_data(
            self, i2c_addr: int, register: int, value: int, force: bool | None = None
        ) -> None:
            if register != 0x20:  # CTRL_REG6_XL never takes
                super().write_byte_data(i2c_addr, register, value, force)

    bus = DeafBus(1)
    bus.attach(0x6B, FakeLsm9ds1())
    with pytest.raises(DeviceError, match=r"CTRL_REG6_XL \(0x20\) = 0x00, expected 0x40"):
        Lsm9ds1(bus, 0x6B).configure(50, 2, 245)


def test_read_converts_quantised_outputs_per_full_scale() -> None:
    dev, fake = driver(accel_g=(0.5, -0.25, 1.0))
    fake.gyro_dps = (100.0, -50.0, 0.5)
    dev.configure(50, 2, 245)
    reading = dev.read()
    assert reading.new
    assert reading.accel_g == pytest.approx((0.5, -0.25, 1.0), abs=0.061e-3 / 2)
    assert reading.gyro_dps == pytest.approx((100.0, -50.0, 0.5), abs=8.75e-3 / 2)
    # The raw count of 1 g on Z: 1 / 0.061 mg = 16393 at ±2 g; 1 / 0.732 mg = 1366 at ±16 g.
    assert int.from_bytes(bytes([fake.register(0x2C), fake.register(0x2D)]), "little") == 16393
    dev.configure(50, 16, 2000)
    dev.read()
    assert int.from_bytes(bytes([fake.register(0x2C), fake.register(0x2D)]), "little") == 1366
    assert dev.read().accel_g[2] == pytest.approx(1366 * 0.732e-3)


def test_fake_saturates_at_the_full_scale() -> None:
    dev, fake = driver(accel_g=(3.0, -3.0, 0.0))
    fake.gyro_dps = (300.0, 0.0, 0.0)
    dev.configure(50, 2, 245)
    reading = dev.read()
    assert reading.accel_g[:2] == pytest.approx((32767 * 0.061e-3, -32768 * 0.061e-3))
    assert reading.gyro_dps[0] == pytest.approx(32767 * 8.75e-3)


def test_one_sample_is_two_block_reads_with_data_ready_from_status() -> None:
    dev, fake = driver()
    with pytest.raises(UsageError, match="before configure"):
        dev.read()
    dev.configure(50, 2, 245)
    before = fake.transactions
    assert dev.read().status & 0b11 == 0b11  # XLDA and GDA
    assert fake.transactions == before + 2
    fake.freeze()
    frozen = dev.read()
    assert not frozen.new  # both bits cleared by the last read, nothing new since
    assert frozen.accel_g[2] == pytest.approx(1.0, abs=1e-4)  # the outputs hold
    fake.thaw()
    assert dev.read().new


def test_fake_block_read_honours_if_add_inc() -> None:
    dev, fake = driver(accel_g=(0.25, 0.5, 1.0))
    dev.configure(50, 2, 245)
    incremented = dev.read_block(0x28, 6)
    fake.write(0x22, 0x40)  # IF_ADD_INC off
    repeated = dev.read_block(0x28, 6)
    assert len(set(incremented)) > 1
    assert repeated == [incremented[0]] * 6


def test_sw_reset_and_power_cycle_restore_the_reset_values() -> None:
    dev, fake = driver()
    dev.configure(119, 4, 500)
    dev.write_register(0x22, 0x44 | 0x01)  # SW_RESET
    assert fake.register(0x10) == 0
    assert fake.register(0x20) == 0
    assert fake.register(0x22) == 0x04  # SW_RESET clears itself
    dev.configure(119, 4, 500)
    dev.read()
    fake.power_cycle()
    assert dev.mismatches(settings(119, 4, 500))[-1] == "CTRL_REG1_G (0x10) = 0x00, expected 0x68"
    assert not dev.read().new  # powered down: no data


def test_probe_names_found_and_expected_who_am_i() -> None:
    bus = FakeSMBus(1)
    bus.attach(0x6B, FakeLsm9ds1(who_am_i=0x69))
    with pytest.raises(DeviceError, match=r"reads 0x69, expected 0x68") as caught:
        Lsm9ds1(bus, 0x6B, name=LINK).probe()
    assert LINK in str(caught.value)
    Lsm9ds1(_bus_with_chip(), 0x6B).probe()  # the real thing passes


def _bus_with_chip() -> FakeSMBus:
    bus = FakeSMBus(1)
    bus.attach(0x6B, FakeLsm9ds1())
    return bus


def test_io_errors_become_device_gone_with_errno_121() -> None:
    dev, fake = driver()
    fake.unplug()
    with pytest.raises(DeviceGoneError, match=r"i2c-1:0x6b: reading WHO_AM_I.*Errno 121"):
        dev.probe()
    assert fake.refused == 1
    assert fake.transactions == 0
    fake.replug()
    dev.probe()
    with pytest.raises(DeviceGoneError, match="Errno 121"):
        Lsm9ds1(_bus_with_chip(), 0x6A).probe()  # nothing at 0x6A


def test_open_bus_translates_a_missing_adapter() -> None:
    with pytest.raises(DeviceGoneError, match="/dev/i2c-250"):
        open_bus(250)


# --------------------------------------------------------------------------- the reader


def test_reader_configures_the_chip_from_robot_config_defaults(chip: FakeLsm9ds1) -> None:
    result = run(duration=0.1)
    assert result.exit_code == 0
    assert chip.register(0x10) == 0b010_00_000  # 50 Hz → 59.5 Hz ODR, ±245 dps
    assert chip.register(0x20) == 0b010_00_000  # ±2 g
    assert chip.register(0x22) == 0x44
    assert names(link_events(result)) == ["SensorLinkUp"]
    up = link_events(result)[0]
    assert isinstance(up, SensorLinkUp)
    assert up.link == LINK


def test_reader_rate_override_sets_the_odr(chip: FakeLsm9ds1) -> None:
    result = run(duration=0.5, params={"rate_hz": 200})
    assert chip.register(0x10) >> 5 == 0b100  # 238 Hz
    times = [s.t for s in result.messages("samples", of=ImuSample)]
    assert 99 <= len(times) <= 101
    assert times[1] - times[0] == pytest.approx(0.005)


def test_reader_samples_at_rate_hz_with_two_reads_each(chip: FakeLsm9ds1) -> None:
    result = run(duration=2.0)
    samples = result.messages("samples", of=ImuSample)
    tilts = result.messages("tilt", of=BodyTilt)
    assert 99 <= len(samples) <= 101  # 50 Hz for 2 virtual seconds
    assert [s.seq for s in samples] == list(range(len(samples)))
    steps = {round(b.t - a.t, 9) for a, b in itertools.pairwise(samples)}
    assert steps == {0.02}
    assert [t.seq for t in tilts] == [s.seq for s in samples]
    assert not result.events(TickOverrun)
    configure = 1 + 2 * len(settings(50, 2, 245).registers)  # WHO_AM_I, writes, read-back
    assert chip.transactions == configure + 2 * len(samples)


def test_reader_tilt_matches_table_6_4(chip: FakeLsm9ds1) -> None:
    seen: list[tuple[float, float, BodyTilt]] = []

    async def scenario(h: Harness) -> None:
        for _, x, y, z, calculated in TABLE_6_4:
            chip.accel_g = (x / G, y / G, z / G)
            after = h.now()

            def newer(m: BodyTilt, after: float = after) -> bool:
                return m.t > after

            tilt = await h.wait_for(BodyTilt, newer)
            seen.append((calculated, x / G, tilt))

    result = run(scenario)
    assert result.exit_code == 0
    assert len(seen) == len(TABLE_6_4)
    samples = {s.seq: s for s in result.messages("samples", of=ImuSample)}
    for calculated, x_g, tilt in seen:
        assert tilt.seq is not None
        # Table 6.4's angle is the one from Y and Z: pitch in eq. 5.7's naming.
        assert math.degrees(tilt.pitch_rad) == pytest.approx(calculated, abs=0.05)
        assert tilt.sensor == "imu"
        assert tilt.accel_g[0] == pytest.approx(x_g, abs=0.061e-3)
        assert tilt.roll_rad == pytest.approx(math.atan2(tilt.accel_g[0], tilt.accel_g[2]))
        assert samples[tilt.seq].accel_g == tilt.accel_g
        assert samples[tilt.seq].t == tilt.t


def test_unplug_reports_down_then_up_after_replug_and_samples_resume(
    chip: FakeLsm9ds1,
) -> None:
    marks: dict[str, float] = {}

    async def scenario(h: Harness) -> None:
        await h.wait_for(ImuSample)
        chip.unplug()
        marks["unplugged"] = h.now()
        await h.wait_for(SensorLinkDown)
        await h.sleep(1.2)  # two retries fail meanwhile
        chip.replug()  # powered off while out: the reader must configure it again
        marks["replugged"] = h.now()
        await h.wait_for(SensorLinkUp)
        await h.wait_for(ImuSample)
        await h.sleep(0.2)

    result = run(scenario)
    events = link_events(result)
    assert names(events) == [
        "SensorLinkUp",
        "SensorLinkDown",
        "SensorLinkStale",
        "SensorLinkUp",
        "SensorLinkFresh",
    ]
    down, up = events[1], events[3]
    assert isinstance(down, SensorLinkDown)
    assert "Errno 121" in down.reason
    assert down.link == LINK
    assert down.t - marks["unplugged"] <= 0.02  # the next read notices
    assert marks["replugged"] < up.t <= marks["replugged"] + 0.5  # the next retry
    assert chip.refused >= 3  # the first failing read and two retries
    assert chip.register(0x10) == 0b010_00_000  # configured again after the power-off
    samples = result.messages("samples", of=ImuSample)
    assert not [s for s in samples if down.t <= s.t <= up.t]
    assert [s.seq for s in samples] == list(range(len(samples)))  # numbering goes on
    assert samples[-1].t > up.t
    assert not result.events(ActorFailed)


def test_stale_once_then_fresh_when_samples_resume(chip: FakeLsm9ds1) -> None:
    async def scenario(h: Harness) -> None:
        await h.wait_for(ImuSample)
        chip.freeze()  # answers, but no new data
        await h.wait_for(SensorLinkStale)
        await h.sleep(1.0)
        chip.thaw()
        await h.wait_for(SensorLinkFresh)
        await h.sleep(0.1)

    result = run(scenario)
    assert result.exit_code == 0
    events = link_events(result)
    assert names(events) == ["SensorLinkUp", "SensorLinkStale", "SensorLinkFresh"]
    stale, fresh = events[1], events[2]
    assert isinstance(stale, SensorLinkStale)
    assert isinstance(fresh, SensorLinkFresh)
    samples = result.messages("samples", of=ImuSample)
    before = [s for s in samples if s.t <= stale.t]
    after = [s for s in samples if s.t > stale.t]
    last = before[-1]
    assert stale.last_seq == last.seq
    assert 0.1 <= stale.silent_s <= 0.1 + 0.02 + 1e-9  # at the first tick past stale_after_s
    assert stale.t - last.t == pytest.approx(stale.silent_s)
    assert after[0].t == fresh.t  # the fresh event comes with the first new sample
    assert fresh.silent_s == pytest.approx(fresh.t - last.t)
    assert fresh.silent_s > 1.0
    assert after[0].seq == last.seq + 1  # nothing was published while frozen


def test_a_chip_that_reset_itself_is_configured_again(chip: FakeLsm9ds1) -> None:
    async def scenario(h: Harness) -> None:
        await h.wait_for(ImuSample)
        chip.power_cycle()  # brown-out: on the bus, powered down, defaults
        await h.wait_for(SensorLinkFresh)

    result = run(scenario)
    events = link_events(result)
    assert names(events) == [
        "SensorLinkUp",
        "SensorLinkStale",
        "SensorLinkDown",
        "SensorLinkUp",
        "SensorLinkFresh",
    ]
    down = events[2]
    assert isinstance(down, SensorLinkDown)
    assert "configuration lost" in down.reason
    assert "CTRL_REG1_G (0x10) = 0x00" in down.reason
    assert events[3].t - events[1].t <= 0.02 + 1e-9  # reconfigured at the next tick
    assert chip.register(0x10) == 0b010_00_000


def test_absent_at_start_is_reported_and_retried(chip: FakeLsm9ds1) -> None:
    chip.unplug()

    async def scenario(h: Harness) -> None:
        await h.sleep(0.7)
        assert not h.log.messages("samples")
        chip.replug()
        await h.wait_for(ImuSample)

    result = run(scenario)
    assert result.exit_code == 0
    events = link_events(result)
    assert names(events) == ["SensorLinkDown", "SensorLinkStale", "SensorLinkUp", "SensorLinkFresh"]
    stale = events[1]
    assert isinstance(stale, SensorLinkStale)
    assert stale.last_seq is None
    assert events[2].t == pytest.approx(1.0)  # retries at 0.5 (failed) and 1.0


def test_wrong_who_am_i_at_start_fails_naming_both_values(chip: FakeLsm9ds1) -> None:
    chip.who_am_i = 0x69
    chip.power_cycle()
    result = run(duration=1.0)
    failed = result.events(ActorFailed)
    assert result.exit_code == 3  # escalated: no restarts allowed here
    assert [f.phase for f in failed] == ["start"]
    assert "DeviceError" in failed[0].error
    assert "WHO_AM_I (0x0F) reads 0x69, expected 0x68" in failed[0].error
    assert LINK in failed[0].error
    assert not result.messages("tilt")
    assert not result.messages("samples")


def test_free_fall_publishes_the_sample_but_no_tilt(chip: FakeLsm9ds1) -> None:
    async def scenario(h: Harness) -> None:
        await h.wait_for(BodyTilt)
        chip.accel_g = (0.0, 0.0, 0.0)
        falling = h.now()
        await h.sleep(0.4)  # a fall longer than the hold-off (0.25 s): said
        chip.accel_g = (0.0, 0.0, 1.0)
        landed = h.now()
        await h.wait_for(BodyTilt, lambda m: m.t > landed)
        assert [m for m in h.log.messages("tilt", of=BodyTilt) if falling < m.t < landed] == []

    result = run(scenario)
    assert result.exit_code == 0
    assert not result.events(ActorFailed)
    zero = [s for s in result.messages("samples", of=ImuSample) if s.accel_g == (0.0, 0.0, 0.0)]
    assert len(zero) >= 19  # 0.4 s at 50 Hz
    tilt_seqs = {t.seq for t in result.messages("tilt", of=BodyTilt)}
    assert not tilt_seqs & {s.seq for s in zero}
    (fell,) = result.events(AccelImplausible)
    (landed,) = result.events(AccelPlausible)
    said = next(s for s in zero if s.t - zero[0].t >= 0.25)  # the hold-off
    assert (fell.seq, fell.magnitude_g, fell.sensor, fell.link) == (said.seq, 0.0, "imu", LINK)
    assert landed.withheld == len(zero)


def test_tilt_needs_a_reading_near_1_g(chip: FakeLsm9ds1, tmp_path: Path) -> None:
    # Tilted 30° about x, at 1 g (a tilt), 1.15 g (inside the default 0.2 g: a tilt),
    # 1.3 g and 0.7 g (a shock: none), and 1 g again.
    tilt = (0.0, math.sin(math.radians(30)), math.cos(math.radians(30)))
    scales = [1.0, 1.15, 1.3, 0.7, 1.0]
    got: list[tuple[float, BodyTilt | None]] = []

    async def scenario(h: Harness) -> None:
        for k in scales:
            chip.accel_g = (tilt[0] * k, tilt[1] * k, tilt[2] * k)
            await h.sleep(0.15)  # the shock's 0.3 s outlast the hold-off (0.25 s)
            after = h.now() - 0.05
            latest = [m for m in h.log.messages("tilt", of=BodyTilt) if m.t > after]
            got.append((k, latest[-1] if latest else None))

    result = run(scenario)
    for k, msg in got:
        if abs(k - 1.0) <= 0.2:
            assert msg is not None, k
            assert math.degrees(msg.pitch_rad) == pytest.approx(30.0, abs=0.01)
        else:
            assert msg is None, k
    bad = result.events(AccelImplausible)
    good = result.events(AccelPlausible)
    assert len(bad) == 1  # 1.3 g then 0.7 g: one implausible spell, said 0.25 s in
    assert bad[0].magnitude_g == pytest.approx(0.7, abs=1e-3)
    assert bad[0].tolerance_g == 0.2
    assert len(good) == 1
    assert good[0].withheld == 15  # 0.3 s at 50 Hz
    # A tighter tolerance from the configuration refuses 1.15 g too.
    config = tmp_path / "robot.toml"
    config.write_text("[imu]\ngravity_tolerance_g = 0.1\n")
    chip.accel_g = (tilt[0] * 1.15, tilt[1] * 1.15, tilt[2] * 1.15)
    tight = run(duration=0.3, params={"config": str(config)})
    assert not tight.messages("tilt")
    (refused,) = tight.events(AccelImplausible)
    assert refused.tolerance_g == 0.1


def test_calibration_takes_the_chips_levels_off_every_sample(
    chip: FakeLsm9ds1, tmp_path: Path
) -> None:
    # A chip 90 mg off in X (the datasheet's typical zero-g offset, a 5° false roll) and
    # 40 mg in Y, with a 25 dps zero-rate level, on level ground, at rest.
    chip.accel_g = (0.090, -0.040, 1.010)
    chip.gyro_dps = (25.0, -3.0, 1.0)
    raw = run(duration=0.2)
    tilt = raw.messages("tilt", of=BodyTilt)[-1]
    assert math.degrees(tilt.roll_rad) == pytest.approx(5.09, abs=0.02)  # uncalibrated
    config = tmp_path / "robot.toml"
    config.write_text(
        "[imu]\naccel_offset_g = [0.090, -0.040, 0.010]\ngyro_offset_dps = [25.0, -3.0, 1.0]\n"
    )
    calibrated = run(duration=0.2, params={"config": str(config)})
    tilt = calibrated.messages("tilt", of=BodyTilt)[-1]
    assert tilt.roll_rad == pytest.approx(0.0, abs=1e-3)
    assert tilt.pitch_rad == pytest.approx(0.0, abs=1e-3)
    sample = calibrated.messages("samples", of=ImuSample)[-1]
    assert sample.accel_g == pytest.approx((0.0, 0.0, 1.0), abs=1e-3)  # 0.061 mg/LSB
    assert sample.gyro_dps == pytest.approx((0.0, 0.0, 0.0), abs=0.01)  # 8.75 mdps/LSB
    assert tilt.accel_g == sample.accel_g


def test_calibration_beyond_what_a_chip_can_be_off_is_refused(tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[imu]\naccel_offset_g = [0.0, 0.3, 0.0]\n")
    with pytest.raises(ConfigError) as err:
        load_config(config)
    text = str(err.value)
    assert "imu.accel_offset_g" in text
    assert "0.3" in text
    assert "0.25" in text


def test_unknown_fake_and_too_short_stale_window_are_refused(
    chip: FakeLsm9ds1, tmp_path: Path
) -> None:
    result = run(duration=0.1, device="fake:nope")
    failed = result.events(ActorFailed)
    assert failed
    assert "no fake I²C bus registered as 'nope' (registered: test)" in failed[0].error
    config = tmp_path / "robot.toml"
    config.write_text("[imu]\nrate_hz = 10\nstale_after_s = 0.15\n")
    # A bad configuration file is a wiring problem: refused before any actor starts.
    with pytest.raises(WiringError) as caught:
        run(duration=0.1, params={"config": str(config)})
    assert "actors.imu.params.config" in str(caught.value)
    assert "imu.stale_after_s = 0.15" in str(caught.value)


def test_disabled_imu_stays_idle(chip: FakeLsm9ds1, tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[imu]\nenabled = false\n")
    result = run(duration=0.5, params={"config": str(config)})
    assert result.exit_code == 0
    assert chip.transactions == 0
    assert not link_events(result)
    assert not result.messages("tilt")


def test_unnamed_fake_runs_for_simulation() -> None:
    result = run(duration=0.2, device="fake", params={"address": 0x6A})
    tilts = result.messages("tilt", of=BodyTilt)
    assert len(tilts) >= 10
    assert tilts[0].roll_rad == 0.0
    assert tilts[0].pitch_rad == 0.0
    assert names(link_events(result)) == ["SensorLinkUp"]
    up = link_events(result)[0]
    assert isinstance(up, SensorLinkUp)
    assert up.link == "i2c-1:0x6a"


def test_params_are_validated() -> None:
    with pytest.raises(ValueError, match="device"):
        ImuReader.Params(device="real")
    with pytest.raises(ValueError, match="rate_hz"):
        ImuReader.Params(rate_hz=1000)
