"""The device links: the servo bus, the sensor board, the IR and force-sensor calibration,
the IMU (5.3, 5.4)."""

from __future__ import annotations

from typing import Annotated, Final, Literal

from pydantic import (
    AfterValidator,
    Discriminator,
    Field,
    Tag,
    field_validator,
)

from whexar.bus.plan import PRESETS, ReadPlan
from whexar.config.common import AdcCounts
from whexar.errors import Problem
from whexar.kinematics.sensing import IR_EXPONENT, IR_K_CM
from whexar.runtime.schema import (
    Finite,
    Positive,
    Section,
)
from whexar.sensors.gravity import GRAVITY_TOLERANCE_G
from whexar.sensors.usart import baudrate_problem

# --------------------------------------------------------------------------- links


class BusSpec(Section):
    """The Dynamixel bus behind the U2D2 adapter (5.3.6, 6.1.1)."""

    port: str = Field(default="/dev/ttyUSB0", min_length=1)
    protocol: float = 2.0
    """Dynamixel protocol; the MX servos run the MX (2.0) firmware (5.3.6)."""
    baudrate: Literal[9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000] = 1_000_000
    """1 Mbps: the fastest rate at which the thesis's bus ran without errors (6.1.1).

    The allowed values are the MX (2.0) rates that dynamixel-sdk's ``setBaudRate``
    accepts (it has no 4.5 Mbps)."""
    return_delay_time_us: int = Field(default=20, ge=0, le=508, multiple_of=2)
    """Return Delay Time; the register counts 2 µs units (thesis used 20 µs, 5.3.6)."""
    plan: Annotated[
        Annotated[str, Tag("<name>")] | Annotated[ReadPlan, Tag("<table>")],
        # Tagged, so a bad table is reported as a table, not also as "not a string";
        # angle brackets keep the tag out of a problem's key path (whexar.runtime.schema).
        Discriminator(lambda v: "<name>" if isinstance(v, str) else "<table>"),
    ] = "default"
    """A read plan: a preset's name (``whexar.bus.plan.PRESETS``) or a ``[bus.plan]`` table."""
    on_stop: Literal["torque_off", "hold"] = "torque_off"
    """The servos' state when the runtime stops: limp (default) or holding their goals."""
    retries: int = Field(default=1, ge=0, le=10)
    """Retries of a failed transaction within one cycle before the failure counts."""
    degrade_after: int = Field(default=5, ge=1)
    """Consecutive failed cycles after which a servo is left out and probed instead."""
    probe_period_s: float = Field(default=0.5, gt=0)
    """How often a degraded servo is pinged to see whether it is back."""
    torque_retries: int = Field(default=3, ge=1)
    """Attempts to enable a servo's torque at start-up and after a reboot."""
    watchdog_ms: int = Field(default=100, ge=0, le=2540, multiple_of=20)
    """Bus Watchdog (98): a servo under torque stops when the host has sent it nothing for
    this long — after a crash, a kill or a pulled cable the wheels stop. 0 turns it off.
    The register counts 20 ms units, 1–127 (e-manual); the scheduler addresses every servo
    at least twice per period."""
    boot_timeout_s: float = Field(default=1.5, gt=0, le=10, allow_inf_nan=False)
    """How long a servo may take to answer after a Reboot or a power-up (about 0.4 s
    measured) before it counts as lost."""

    @field_validator("plan")
    @classmethod
    def _known_plan(cls, value: str | ReadPlan) -> str | ReadPlan:
        if isinstance(value, str) and value not in PRESETS:
            raise ValueError(f"a preset ({', '.join(PRESETS)}) or a [bus.plan] table")
        return value

    @field_validator("protocol")
    @classmethod
    def _protocol_2(cls, value: float) -> float:
        if value != 2.0:
            raise ValueError("2.0: whexar speaks Dynamixel Protocol 2.0 only (MX (2.0) firmware)")
        return value


def board_baudrate(rate: int) -> int:
    """Check a sensor-board rate: one the ATmega2560 at 16 MHz runs at, as its firmware sets it.

    The rule, from the ATmega2560 datasheet's USART baud-rate tables (Atmel 2549Q,
    Table 22-12 for 16 MHz; ±2 % recommended receiver error for 8-bit frames,
    Table 22-2) and the Arduino core's choice of U2X and UBRR in ``Serial.begin``,
    is :mod:`whexar.sensors.usart`: the rate the USART actually produces must be
    within ±2 % of the one asked for, with U2X or without as the core picks it —
    which leaves out 115200 (+2.1 %) and 57600 bps (+2.1 %, normal speed forced) —
    and it must carry the firmware's longest frame at 50 frames/s (63.5 kbps).
    The firmware's ``BAUD`` build option is checked by the same rule, so every
    rate allowed here is one the firmware can be built for:
    76800, 250000, 500000, 1000000 and 2000000 bps.
    """
    problem = baudrate_problem(rate)
    if problem is not None:
        raise ValueError(problem)
    return rate


BoardBaudrate = Annotated[int, AfterValidator(board_baudrate)]
"""A serial rate of the sensor board (:func:`board_baudrate`)."""

GravityTolerance = Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)]
"""How far from 1 g an accelerometer reading may be and still give a tilt (under 1 g, or
free fall would pass); :mod:`whexar.sensors.gravity` explains the default."""
GravityHold = Annotated[float, Field(ge=0, le=10, allow_inf_nan=False)]
"""How long (s) readings must stay implausible before the reader says so
(:mod:`whexar.sensors.gravity`, "Hold-off"); 0: at the first one."""
GRAVITY_HOLD_S: Final = 0.25
"""The default hold-off: 2.5× the longest run of implausible readings a footfall gave in
the simulated course (0.1 s; docs/robot.md, "The accelerometer's hold-off")."""


class AccelerometerSpec(Section):
    """The board's optional analog accelerometer (``accx/accy/accz``), read in ADC counts.

    ``fitted``: whether the board has one. The thesis names none — body tilt
    comes from the LSM9DS1 on the Pi (5.3.4, 5.4) — so by default it is not
    fitted, and the firmware's default build (``WITH_ACCEL=0``) does not send
    ``acc*``. When frames carry them anyway (a ``WITH_ACCEL=1`` build, a thesis
    frame), the reader shows the counts but makes no tilt of them.

    Calibration defaults: an ADXL335 on 3.3 V read against the 5 V reference.
    Its zero-g output is half its supply and its sensitivity is ratiometric,
    300 mV/g at 3 V (ADXL335 datasheet, Rev. B), so 1.65 V = 337.6 counts and
    330 mV/g = 67.5 counts/g.
    """

    fitted: bool = False
    zero_g_counts: tuple[Finite, Finite, Finite] = (337.6, 337.6, 337.6)
    counts_per_g: tuple[Positive, Positive, Positive] = (67.5, 67.5, 67.5)
    gravity_tolerance_g: GravityTolerance = GRAVITY_TOLERANCE_G
    """A reading whose magnitude is further than this from 1 g gives no tilt."""
    implausible_hold_s: GravityHold = GRAVITY_HOLD_S
    """Readings implausible for this long are said to be (:class:`AccelImplausible`)."""


class SensorBoardSpec(Section):
    """The ATmega2560 sensor board on its serial line (5.4, 6.1.2, 6.1.5)."""

    port: str = Field(default="/dev/ttyACM0", min_length=1)
    baudrate: BoardBaudrate = 1_000_000
    """1 Mbps (5.4): U2X, UBRR = 1 on the 16 MHz board, exact. Must be a rate the firmware can
    run at (:data:`~whexar.sensors.usart.BOARD_BAUDRATES`, :func:`board_baudrate`)."""
    sample_rate_hz: Positive = 50.0
    """ADC sampling of the IR and FSR inputs (6.1.2, 6.1.5)."""
    frame_rate_hz: float = Field(default=20.0, ge=10.0, le=50.0, allow_inf_nan=False)
    """Frames sent to the host: 20 Hz in 5.4 (10 Hz in 6.1.5); the reader tells the board."""
    protocol: Literal["checked", "thesis"] = "checked"
    """``checked``: frames must carry ``seq`` and ``crc``; ``thesis``: the plain 5.4 frame
    is accepted too (firmware/PROTOCOL.md)."""
    stale_after_frames: float = Field(default=3.0, ge=1.0, allow_inf_nan=False)
    """The link is stale when no valid frame arrived for this many frame periods after one
    did: a connection's silence before its first frame (the board's boot) is not staleness."""
    reconnect_period_s: Positive = 0.5
    """How often a vanished serial device is looked for again."""
    accelerometer: AccelerometerSpec = AccelerometerSpec()

    def problems(self, at: str) -> list[Problem]:
        if self.frame_rate_hz > self.sample_rate_hz:
            return [
                Problem(
                    f"{at}.frame_rate_hz",
                    self.frame_rate_hz,
                    f"at most sample_rate_hz ({self.sample_rate_hz:g}): "
                    "a frame carries at least one new sample",
                )
            ]
        return []


class IRSpec(Section):
    """IR rangefinders on the front legs, calibrated by eq. 5.5 (5.3.5, Table 5.4)."""

    k_cm: Positive = IR_K_CM
    """Coefficient of the trend line y[cm] = k·x^e, x the 10-bit ADC value (eq. 5.5)."""
    exponent: Finite = IR_EXPONENT
    """Exponent e of eq. 5.5."""
    min_distance_mm: Positive = 100.0
    """Nearest calibrated distance (Table 5.4: 10 cm)."""
    max_distance_mm: Positive = 1500.0
    """Detection range: up to 150 cm (5.3.5)."""
    pitch_deg: float = Field(default=20.0, ge=-10.0, le=45.0, allow_inf_nan=False)
    """The mount, pitched down from the femur axis, degrees. The thesis gives no angle
    (5.3.5), but counts obstacles "that can be overcome" from the rangefinders (4.2.3),
    which a level ray at the coxa joints' height (29 cm) never sees. Pitched 20° down,
    the rays meet the flat 0.84 m ahead (two tripod steps and a stop), a 5 cm rise
    0.66 m ahead, a 30° upslope 0.38 m ahead, and profile what lies there (the obstacle
    reflex, :mod:`whexar.actors.reactive.obstacle`)."""

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        if self.exponent >= 0:
            found.append(
                Problem(f"{at}.exponent", self.exponent, "negative: distance falls as counts rise")
            )
        if self.min_distance_mm >= self.max_distance_mm:
            found.append(
                Problem(
                    f"{at}.min_distance_mm",
                    self.min_distance_mm,
                    f"below max_distance_mm ({self.max_distance_mm:g})",
                )
            )
        return found


class FSRSpec(Section):
    """Force-sensitive resistors under each leg, read as raw ADC counts (5.3.3).

    The thesis sets the threshold from each leg's load after calibration
    (6.7.3) and gives no number; these defaults suit the 10 kΩ divider of
    Fig. 5.7 and are meant to be tuned on the robot. Two thresholds give
    hysteresis so a contact flag does not chatter.
    """

    contact_on_counts: AdcCounts = 200
    """A reading at or above this sets the leg's contact flag."""
    contact_off_counts: AdcCounts = 120
    """A reading below this clears it."""

    def problems(self, at: str) -> list[Problem]:
        if self.contact_off_counts >= self.contact_on_counts:
            return [
                Problem(
                    f"{at}.contact_off_counts",
                    self.contact_off_counts,
                    f"below contact_on_counts ({self.contact_on_counts}) for hysteresis",
                )
            ]
        return []


AccelOffset = Annotated[float, Field(ge=-0.25, le=0.25, allow_inf_nan=False)]
"""A calibrated zero-g level, g: beyond ±0.25 g (almost 3× the datasheet's typical
offset) the chip or its calibration is broken."""
GyroOffset = Annotated[float, Field(ge=-100.0, le=100.0, allow_inf_nan=False)]
"""A calibrated zero-rate level, dps: beyond ±100 dps (over 3× the datasheet's typical
level) the chip or its calibration is broken."""


class ImuSpec(Section):
    """The LSM9DS1 IMU on the Raspberry Pi's I²C bus (5.3.4, 5.4)."""

    enabled: bool = True
    i2c_bus: int = Field(default=1, ge=0)
    """``/dev/i2c-N``: bus 1 is the Pi's header pins 3 and 5."""
    address: int = Field(default=0x6B, ge=0x03, le=0x77)
    """Accelerometer/gyroscope address: 0x6B (SDO_AG high, breakout default) or 0x6A."""
    rate_hz: float = Field(default=50.0, gt=0, le=952, allow_inf_nan=False)
    """Samples per second read by the host (the sensor runs at the next ODR above)."""
    accel_range_g: Literal[2, 4, 8, 16] = 2
    """Accelerometer full scale (LSM9DS1 datasheet, Table 3)."""
    gyro_range_dps: Literal[245, 500, 2000] = 245
    """Gyroscope full scale (LSM9DS1 datasheet, Table 3)."""
    stale_after_s: Positive = 0.1
    """The IMU link is stale when no sample was read for this long."""
    gravity_tolerance_g: GravityTolerance = GRAVITY_TOLERANCE_G
    """A sample whose acceleration is further than this from 1 g gives no tilt."""
    implausible_hold_s: GravityHold = GRAVITY_HOLD_S
    """Samples implausible for this long are said to be (:class:`AccelImplausible`)."""
    accel_offset_g: tuple[AccelOffset, AccelOffset, AccelOffset] = (0.0, 0.0, 0.0)
    """This chip's zero-g level per axis, in its own axes, subtracted from every
    sample: what X and Y read with the robot still on level ground, and Z less 1 g.
    Uncalibrated, an LSM9DS1 reads up to ±90 mg (datasheet Table 3, typical zero-g
    level offset accuracy), a tilt of up to 5°."""
    gyro_offset_dps: tuple[GyroOffset, GyroOffset, GyroOffset] = (0.0, 0.0, 0.0)
    """This chip's zero-rate level per axis, subtracted from every sample: the mean
    rate read at rest (datasheet Table 3: typically ±30 dps uncalibrated)."""

    def problems(self, at: str) -> list[Problem]:
        # One late sample must not read as a stale link (whexar.actors.sensing.imu).
        if self.stale_after_s < 2.0 / self.rate_hz:
            return [
                Problem(
                    f"{at}.stale_after_s",
                    self.stale_after_s,
                    f"at least two sample periods (2 / rate_hz = {2.0 / self.rate_hz:g} s)",
                )
            ]
        return []
