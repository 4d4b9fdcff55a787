"""The IMU reader: the LSM9DS1 on the Raspberry Pi's I²C bus, sampled on a ticker.

Theory of operation
-------------------
The thesis reads the LSM9DS1's accelerometer from the Pi over I²C and turns
it into body tilt (Žák 2023, 5.3.4, 5.4, eq. 5.6–5.7). This actor owns that
link (one device, one owner) and does it on the runtime's clock:

1. **Open**: open ``/dev/i2c-N``, probe WHO_AM_I, write the configuration
   and read it back (:mod:`whexar.sensors.lsm9ds1`); the chip samples at the
   lowest ODR at or above ``imu.rate_hz``. Then :meth:`~ImuReader.ready`.
2. **Sample** every ``1/rate_hz`` on a deadline ticker: one read of
   STATUS_REG + angular rate, one of acceleration. A read whose data-ready
   bits are clear found nothing new and publishes nothing; a new sample is
   published as :class:`ImuSample` and, from its acceleration,
   :class:`BodyTilt` (``sensor="imu"``), both with the same ``seq`` (from 0)
   and ``t`` the time the read ended.
3. **Where the work runs**: on a real bus each call blocks for a few
   transactions (≈0.3–0.5 ms at 400 kHz), so it runs in a worker thread
   (``anyio.to_thread``). A fake (``device = "fake…"``) is called inline:
   work in a thread is invisible to the virtual-time loop.
4. **Calibration**: every sample is published less this chip's zero-g and
   zero-rate levels (``imu.accel_offset_g``, ``imu.gyro_offset_dps``: what it
   reads at rest on level ground), before the gravity check and the tilt.

Failures never end the actor, except a wrong device at start:

* **Wrong device at start** (WHO_AM_I is not 0x68, or the configuration does
  not hold): :class:`~whexar.errors.DeviceError`, raised — the wiring points
  at something that is not our IMU, and retrying will not change that.
* **Link down**: any I/O error (a NAK, the adapter gone; at start too) is
  :class:`SensorLinkDown` with the reason; the link is closed and opened
  again (probe + configure) every ``retry_period_s`` (0.5 s) until it works,
  :class:`SensorLinkUp`. A retry that fails for a new cause (another errno,
  or a wrong answer) reports a new :class:`SensorLinkDown`; the same cause is
  said once.
* **Stale**: no new sample for ``imu.stale_after_s`` — the link is down, or
  the chip answers but produces nothing — is one :class:`SensorLinkStale`;
  the next new sample is :class:`SensorLinkFresh`. While stale and up, the
  reader reads the configuration back every ``retry_period_s``: a chip that
  reset itself (a brown-out leaves it powered down at its defaults) is
  reported down ("configuration lost") and configured again at once.
* **Not gravity**: eq. 5.6–5.7 hold only while the sensor feels gravity
  alone. A sample whose acceleration is further than ``imu.gravity_tolerance_g``
  from 1 g in magnitude — free fall, a shock, a chip that lost its
  calibration or range — is published, its :class:`BodyTilt` is not
  (:mod:`whexar.sensors.gravity`). The first such sample after plausible ones
  is one :class:`AccelImplausible`, the first plausible one after them
  :class:`AccelPlausible`.

The tilt is in the sensor's own axes (roll from X/Z, pitch from Y/Z, as eq.
5.6–5.7); mapping them onto the body frame is the consumer's business.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Final, TypeVar

import anyio
import anyio.to_thread
from pydantic import Field

from whexar.actors.messages import (
    BodyTilt,
    ImuSample,
    SensorLinkDown,
    SensorLinkFresh,
    SensorLinkStale,
    SensorLinkUp,
)
from whexar.actors.sensing.board import gravity_event
from whexar.config import ConfigFile, RobotConfig, load_config
from whexar.errors import DeviceError, DeviceGoneError, UsageError
from whexar.runtime.actor import Actor, ActorParams, Output
from whexar.runtime.devices import DEVICES
from whexar.sensors.gravity import GravityCheck
from whexar.sensors.imu_emulator import I2C_BUS, lsm9ds1_bus
from whexar.sensors.lsm9ds1 import (
    ODR_HZ,
    Calibration,
    I2CBus,
    Lsm9ds1,
    Reading,
    Settings,
    TappedBus,
    settings,
)
from whexar.sensors.replay import REPLAYED_I2C

T = TypeVar("T")

REAL_I2C: Final = "i2c"
"""The ``device`` that names the real bus, ``/dev/i2c-N`` (a graph file cannot say ``None``)."""


RETRY_PERIOD_S: Final = 0.5
"""How often a lost link is opened again, and a stale chip's configuration checked."""
STALE_MIN_PERIODS: Final = 2
"""``stale_after_s`` must span this many sample periods: one late sample is not a stale link."""


def open_bus(number: int) -> I2CBus:
    """Open ``/dev/i2c-<number>`` with smbus2; :class:`DeviceGoneError` if that fails."""
    from smbus2 import SMBus

    try:
        return SMBus(number)
    except OSError as exc:
        raise DeviceGoneError(f"cannot open /dev/i2c-{number}: {exc}") from exc


class ImuReader(Actor):
    """Reads the LSM9DS1 at ``imu.rate_hz``; publishes samples and body tilt, reports the link."""

    class Params(ActorParams):
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults (``RobotConfig().imu``)."""
        bus: int | None = Field(None, ge=0)
        """Overrides ``imu.i2c_bus``: the N of ``/dev/i2c-N``."""
        address: int | None = Field(None, ge=0x03, le=0x77)
        """Overrides ``imu.address`` (0x6B, or 0x6A with SDO_AG low)."""
        rate_hz: float | None = Field(None, gt=0, le=ODR_HZ[-1], allow_inf_nan=False)
        """Overrides ``imu.rate_hz``."""
        device: str | None = Field(None, pattern=r"^(i2c|fake(:.+)?|replay:.+)$")
        """``None`` or ``"i2c"``: the real ``/dev/i2c-N``; ``"fake"``: a fresh fake chip;
        ``"fake:NAME"``: the fake bus registered as NAME
        (:data:`~whexar.sensors.imu_emulator.I2C_BUS`);
        ``"replay:NAME"``: recorded calls played back (:mod:`whexar.sensors.replay`)."""
        retry_period_s: float = Field(RETRY_PERIOD_S, gt=0, allow_inf_nan=False)
        """How often a lost link is opened again."""

    params: Params
    tilt = Output(BodyTilt)
    samples = Output(ImuSample, optional=True)

    # ----------------------------------------------------------------- set-up

    def _setup(self) -> None:
        p = self.params
        cfg = load_config(p.config) if p.config else RobotConfig()
        spec = cfg.imu
        self.enabled = spec.enabled
        self.bus_number = spec.i2c_bus if p.bus is None else p.bus
        self.address = spec.address if p.address is None else p.address
        self.link = f"i2c-{self.bus_number}:0x{self.address:02x}"
        # Validates the rate and the ranges before anything opens.
        self.wanted: Settings = settings(
            spec.rate_hz if p.rate_hz is None else p.rate_hz,
            spec.accel_range_g,
            spec.gyro_range_dps,
        )
        self.period_s = 1.0 / self.wanted.rate_hz
        self.gravity = GravityCheck(spec.gravity_tolerance_g, spec.implausible_hold_s)
        self.calibration = Calibration(spec.accel_offset_g, spec.gyro_offset_dps)
        self.stale_after_s = spec.stale_after_s
        if self.stale_after_s < STALE_MIN_PERIODS * self.period_s:
            raise UsageError(
                f"imu.stale_after_s = {self.stale_after_s}: must be at least "
                f"{STALE_MIN_PERIODS} sample periods ({STALE_MIN_PERIODS * self.period_s:g} s "
                f"at {self.wanted.rate_hz:g} Hz), or a single late sample makes the link stale"
            )
        device = None if p.device == REAL_I2C else p.device
        self.inline = device is not None
        self._open_bus = self._opener(device)
        self.bus: I2CBus | None = None
        self.chip: Lsm9ds1 | None = None
        self.seq = 0
        self.last_seq: int | None = None
        self.last_ok = 0.0
        """Time of the last new sample (or of start, before the first)."""
        self.stale = False
        self.down_cause: int | str | None = None
        """What the last :class:`SensorLinkDown` was about (an errno, or the error's text);
        ``None`` while the link is up."""
        self.retry_at = 0.0
        self.check_at = 0.0

    def _opener(self, device: str | None) -> Callable[[], I2CBus]:
        opener = self._device_opener(device)
        tap = self.tap()
        if tap is None:
            return opener
        now = self.clock.now

        def tapped() -> I2CBus:
            try:
                bus = opener()
            except DeviceGoneError as exc:  # a replay opens as the recording did
                tap("gone", now(), str(exc).encode())
                raise
            tap("open", now(), b"")
            return TappedBus(bus, tap, now)

        return tapped

    def _device_opener(self, device: str | None) -> Callable[[], I2CBus]:
        number = self.bus_number
        if device is None:
            return lambda: open_bus(number)
        if device == I2C_BUS.scheme:
            fake = lsm9ds1_bus(number, self.address)
            return lambda: fake
        scheme, key = device.split(":", 1)
        if scheme == REPLAYED_I2C.scheme:
            replayed = DEVICES.get(REPLAYED_I2C, key, setting=f"device = {device!r}")
            clock = self.clock
            return lambda: replayed.open(clock.now)
        registered = DEVICES.get(I2C_BUS, key, setting=f"device = {device!r}")
        return lambda: registered

    async def _call(self, fn: Callable[[], T]) -> T:
        """Run a blocking bus call: inline on a fake, in a worker thread on a real bus."""
        if self.inline:
            return fn()
        self.clock.uses_real_io(f"I²C bus {self.bus_number}")  # refused on virtual time
        return await anyio.to_thread.run_sync(fn)

    # ----------------------------------------------------------------- the link

    def _connect(self) -> tuple[I2CBus, Lsm9ds1]:
        """Open, probe and configure (blocking: runs where :meth:`_call` puts it)."""
        bus = self._open_bus()
        try:
            chip = Lsm9ds1(bus, self.address, name=self.link)
            chip.probe()
            w = self.wanted
            chip.configure(w.rate_hz, w.accel_range_g, w.gyro_range_dps)
        except BaseException:
            with contextlib.suppress(OSError):
                bus.close()
            raise
        return bus, chip

    async def _open(self, *, first: bool = False) -> None:
        try:
            self.bus, self.chip = await self._call(self._connect)
        except DeviceGoneError as exc:
            self._report_down(exc)
        except DeviceError as exc:
            if first:
                raise  # not our IMU (or not working as one): fail fast
            self._report_down(exc)
        else:
            self.down_cause = None
            self.check_at = self.now() + self.params.retry_period_s  # just configured
            self.emit(SensorLinkUp(t=self.now(), source=self.name, link=self.link))

    def _report_down(self, exc: Exception, *, retry_in: float | None = None) -> None:
        now = self.now()
        self.retry_at = now + (self.params.retry_period_s if retry_in is None else retry_in)
        # The cause, not the text: a NAK on WHO_AM_I after a NAK on a read is the same news.
        os_error = exc.__cause__
        cause = os_error.errno if isinstance(os_error, OSError) else str(exc)
        if cause != self.down_cause:
            self.down_cause = cause
            self.emit(SensorLinkDown(t=now, source=self.name, link=self.link, reason=str(exc)))

    def _lose(self, exc: Exception, *, retry_in: float | None = None) -> None:
        self._close()
        self._report_down(exc, retry_in=retry_in)

    def _close(self) -> None:
        bus, self.bus, self.chip = self.bus, None, None
        if bus is not None:
            with contextlib.suppress(OSError):
                bus.close()

    # ----------------------------------------------------------------- the cycle

    async def _step(self) -> None:
        if self.chip is None:
            if self.now() >= self.retry_at:
                await self._open()
        else:
            await self._sample(self.chip)
        await self._watch()

    async def _sample(self, chip: Lsm9ds1) -> None:
        try:
            reading = await self._call(chip.read)
        except (DeviceGoneError, DeviceError) as exc:
            self._lose(exc)
            return
        if reading.new:
            await self._publish(reading)

    async def _publish(self, reading: Reading) -> None:
        t = self.now()
        reading = self.calibration.apply(reading)
        if self.stale:
            self.stale = False
            self.emit(
                SensorLinkFresh(t=t, source=self.name, link=self.link, silent_s=t - self.last_ok)
            )
        self.last_ok = t
        seq, self.seq = self.seq, self.seq + 1
        self.last_seq = seq
        if self.samples.connected:
            await self.samples.send(
                ImuSample(
                    t=t,
                    source=self.name,
                    seq=seq,
                    accel_g=reading.accel_g,
                    gyro_dps=reading.gyro_dps,
                )
            )
        verdict = self.gravity.check(reading.accel_g, t)
        event = gravity_event(
            verdict,
            reading.accel_g,
            self.gravity.tolerance_g,
            t=t,
            source=self.name,
            link=self.link,
            sensor="imu",
            seq=seq,
        )
        if event is not None:
            self.emit(event)
        if verdict.tilt is None:
            return  # not gravity: no tilt
        roll, pitch = verdict.tilt
        await self.tilt.send(
            BodyTilt(
                t=t,
                source=self.name,
                seq=seq,
                sensor="imu",
                roll_rad=roll,
                pitch_rad=pitch,
                accel_g=reading.accel_g,
            )
        )

    async def _watch(self) -> None:
        """Say stale once; while stale and up, check the chip still holds its configuration."""
        now = self.now()
        silent = now - self.last_ok
        if not self.stale and silent >= self.stale_after_s:
            self.stale = True
            self.check_at = now
            self.emit(
                SensorLinkStale(
                    t=now,
                    source=self.name,
                    link=self.link,
                    silent_s=silent,
                    last_seq=self.last_seq,
                )
            )
        chip = self.chip
        if not self.stale or chip is None or now < self.check_at:
            return
        self.check_at = now + self.params.retry_period_s
        try:
            wrong = await self._call(lambda: chip.mismatches(self.wanted))
        except (DeviceGoneError, DeviceError) as exc:
            self._lose(exc)
            return
        if wrong:
            # A brown-out resets the chip to power-down: configure it again now.
            lost = DeviceError(f"{self.link}: configuration lost ({'; '.join(wrong)})")
            self._lose(lost, retry_in=0.0)

    # ----------------------------------------------------------------- lifecycle

    async def run(self) -> None:
        self._setup()
        if not self.enabled:
            self.ready()  # imu.enabled = false: wired but idle
            await anyio.sleep_forever()
        try:
            await self._open(first=True)
            self.ready()
            self.last_ok = self.now()
            async for _ in self.ticker(self.period_s):
                await self._step()
        finally:
            self._close()


__all__ = [
    "RETRY_PERIOD_S",
    "STALE_MIN_PERIODS",
    "ImuReader",
    "open_bus",
]
