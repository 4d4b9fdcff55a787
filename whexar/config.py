"""Robot configuration: pydantic models of everything physical or tunable.

Every default is a value of the reference thesis (Žák 2023, *Biology-Inspired
Control of a Walking Robot*), so ``RobotConfig()`` *is* WHexaR; the file
``config/whexar.toml`` spells the same values out, key by key, with sources.

Unit rule: the file names every unit in its keys (``_mm``, ``_deg``, ``_g``,
``_us``, ``_hz``, ``_counts``…); code converts to SI once, at the edge: the
``*_rad`` properties, and :meth:`RobotConfig.leg_geometry` and
:meth:`RobotConfig.stance`, which build what the kinematics takes. The
kinematics never reads the configuration; the configuration calls it to
check that every stance preset is reachable.

A file needs only the keys it changes: :func:`merge_defaults` merges it into
``RobotConfig()`` first — tables key by key, recursively (mapping-valued
sections such as ``stances`` too, so a stance can be added or partly
changed), arrays (``legs``) whole. Then validation runs on the merged
document in two layers, so that one bad key never hides another:

1. per key — types, ranges, allowed values, unknown keys (pydantic);
2. relations — servo IDs unique, limits ordered, DH lengths consistent with
   segment lengths, gait thresholds ordered along the gait ranking, stance
   presets reachable. Checks inside one section run whenever that section is
   valid on its own; checks across sections run once every section is.

:func:`load_config` raises :class:`~whexar.errors.ConfigError` listing every
:class:`~whexar.errors.Problem` found (key path, bad value, what is allowed).
"""

from __future__ import annotations

import copy
import functools
import itertools
import math
import typing
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Final, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    Discriminator,
    Field,
    Tag,
    TypeAdapter,
    ValidationError,
    field_validator,
)

from whexar.bus.plan import PRESETS, ReadPlan
from whexar.bus.protocol import MAX_ID
from whexar.errors import MISSING, ConfigError, KinematicsError, Problem
from whexar.kinematics.body import Stance, stance_feet
from whexar.kinematics.gait import GAIT_RANKING
from whexar.kinematics.geometry import LegGeometry
from whexar.kinematics.indices import STANDARD_GRAVITY, SUPPLY_VOLTAGE, WHEXAR_MASS
from whexar.kinematics.leg import ik
from whexar.kinematics.sensing import IR_EXPONENT, IR_K_CM
from whexar.robot import JOINT_NAMES, LEG_NAMES, POSITIONING_JOINTS, servo_id
from whexar.runtime.schema import (
    CheckedSection,
    Finite,
    NonNegative,
    Positive,
    Section,
    format_path,
    loads,
    problem_from_error,
    read_toml,
)
from whexar.sensors.gravity import GRAVITY_TOLERANCE_G
from whexar.sensors.usart import baudrate_problem

ServoModelName = Literal["MX-28", "MX-64", "MX-106"]

DH_SEGMENT_TOLERANCE_MM: Final = 5.0
"""How far a DH length may differ from the measured segment length of Table 5.2.

The thesis itself differs by 2 mm: trochanter offset d₁ = 65 mm in the DH
table (Table 5.3) against 63 mm measured (Table 5.2). Table 6.5 is reproduced
only with 65 mm, so the DH value drives the kinematics and the check allows
a few millimetres of measuring slack, not a different leg.
"""

AdcCounts = Annotated[int, Field(ge=0, le=1023)]
"""A 10-bit ATmega2560 ADC reading."""


# --------------------------------------------------------------------------- robot & body


class RobotSpec(Section):
    """Whole-robot constants."""

    name: str = "WHexaR"
    mass_kg: Positive = WHEXAR_MASS
    """Total mass used for the cost of transport (6.8.1)."""
    supply_voltage_v: Positive = SUPPLY_VOLTAGE
    """Supply voltage in the experiments (5.3.1, 6.8)."""
    gravity_m_s2: Positive = STANDARD_GRAVITY
    """Gravitational acceleration used by the thesis (6.8.1)."""


class BodySpec(Section):
    """The body tube: an aluminium rectangular profile 60 × 10 × 6 cm (5.2)."""

    length_mm: Positive = 600.0
    width_mm: Positive = 100.0
    height_mm: Positive = 60.0


# --------------------------------------------------------------------------- servos & joints


class ServoModelSpec(Section):
    """One Dynamixel MX model (Table 5.1; ROBOTIS e-manual, MX (2.0) pages)."""

    model_number: int = Field(ge=0, le=65535)
    """Value of the Model Number register (address 0) under Protocol 2.0."""
    mass_g: Positive
    stall_torque_nm: Positive
    """Stall torque at 12 V (Table 5.1)."""
    stall_current_a: Positive
    """Current at stall torque, 12 V (5.3.1)."""
    resolution_ticks: int = Field(default=4096, gt=0)
    """Encoder ticks per revolution (Table 5.1)."""


def _default_servo_models() -> dict[ServoModelName, ServoModelSpec]:
    return {
        "MX-28": ServoModelSpec(
            model_number=30, mass_g=77.0, stall_torque_nm=2.5, stall_current_a=1.4
        ),
        "MX-64": ServoModelSpec(
            model_number=311, mass_g=135.0, stall_torque_nm=6.0, stall_current_a=4.1
        ),
        "MX-106": ServoModelSpec(
            model_number=321, mass_g=153.0, stall_torque_nm=8.4, stall_current_a=5.2
        ),
    }


class JointSpec(Section):
    """One joint of every leg: its servo, range and segment (Table 5.2)."""

    model: ServoModelName
    min_deg: Finite | None = None
    """Lower limit; absent only for an endless joint."""
    max_deg: Finite | None = None
    """Upper limit; absent only for an endless joint."""
    endless: bool = False
    """Continuous rotation (the wheel), no limits."""
    length_mm: NonNegative
    """Distance to the next joint, or to the ground for the wheel (Table 5.2)."""

    @property
    def limits_rad(self) -> tuple[float, float] | None:
        """(min, max) in radians, or ``None`` for an endless joint."""
        if self.endless or self.min_deg is None or self.max_deg is None:
            return None
        return math.radians(self.min_deg), math.radians(self.max_deg)

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        if self.endless:
            for key in ("min_deg", "max_deg"):
                if getattr(self, key) is not None:
                    found.append(
                        Problem(f"{at}.{key}", getattr(self, key), "an endless joint has no limits")
                    )
            return found
        for key in ("min_deg", "max_deg"):
            if getattr(self, key) is None:
                found.append(Problem(f"{at}.{key}", MISSING, "required unless endless = true"))
        if self.min_deg is not None and self.max_deg is not None and self.min_deg >= self.max_deg:
            found.append(
                Problem(
                    f"{at}.min_deg",
                    self.min_deg,
                    f"must be below max_deg ({self.max_deg:g}); limits are (min, max)",
                )
            )
        return found


class JointsSpec(Section):
    """The seven joints, coxa to wheel (Fig. 4.1, Table 5.2)."""

    coxa: JointSpec = JointSpec(model="MX-64", min_deg=-135, max_deg=135, length_mm=0)
    trochanter: JointSpec = JointSpec(model="MX-106", min_deg=-360, max_deg=360, length_mm=63)
    femur: JointSpec = JointSpec(model="MX-106", min_deg=-120, max_deg=120, length_mm=127)
    tibia: JointSpec = JointSpec(model="MX-64", min_deg=-150, max_deg=150, length_mm=124)
    tarsus: JointSpec = JointSpec(model="MX-64", min_deg=-155, max_deg=170, length_mm=95)
    direction: JointSpec = JointSpec(model="MX-28", min_deg=-360, max_deg=360, length_mm=42)
    wheel: JointSpec = JointSpec(model="MX-28", endless=True, length_mm=33)

    def by_name(self, name: str) -> JointSpec:
        """The joint called ``name`` (one of :data:`whexar.robot.JOINT_NAMES`)."""
        spec: JointSpec = getattr(self, name)
        return spec

    def problems(self, at: str) -> list[Problem]:
        return [p for name in JOINT_NAMES for p in self.by_name(name).problems(f"{at}.{name}")]


class DHRow(Section):
    """One row of the Denavit–Hartenberg table (eq. 4.4–4.5, Table 5.3).

    The DH angle of the joint is ``theta_sign · q + theta_offset`` where q is
    the joint angle in the servo convention of Table 6.5 (positive femur lifts
    the leg; the tarsus keeps the last segment vertical at −90° − femur − tibia).
    """

    d_mm: Finite
    a_mm: Finite
    alpha_deg: Finite
    theta_offset_deg: Finite = 0.0
    theta_sign: Literal[1, -1] = 1


class DHSpec(Section):
    """DH table of the five positioning joints (Table 5.3).

    Table 5.3 gives d, a, α and the trochanter's +π/2. The femur's +90° and the
    sign flips of femur, tibia and tarsus map Table 6.5's joint convention onto
    these DH angles: with them FK reproduces every row of Table 6.5.
    """

    coxa: DHRow = DHRow(d_mm=0, a_mm=0, alpha_deg=90)
    trochanter: DHRow = DHRow(d_mm=65, a_mm=0, alpha_deg=90, theta_offset_deg=90)
    femur: DHRow = DHRow(d_mm=0, a_mm=127, alpha_deg=0, theta_offset_deg=90, theta_sign=-1)
    tibia: DHRow = DHRow(d_mm=0, a_mm=124, alpha_deg=0, theta_sign=-1)
    tarsus: DHRow = DHRow(d_mm=0, a_mm=95, alpha_deg=0, theta_sign=-1)

    def rows(self) -> tuple[DHRow, ...]:
        """The five rows in joint order."""
        return tuple(getattr(self, name) for name in POSITIONING_JOINTS)


# --------------------------------------------------------------------------- legs


def _default_legs() -> tuple[LegSpec, ...]:
    # Coxa joints 300 mm apart along the body (5.2) and 74 mm from its axis
    # (Table 5.2, "Body 74 mm"); body frame x forward, y left, z up.
    xs = {"F": 300.0, "M": 0.0, "R": -300.0}
    return tuple(
        LegSpec(
            name=name,
            mount_mm=(xs[name[1]], -74.0 if name[0] == "R" else 74.0, 0.0),
            servo_ids=tuple(servo_id(name, joint) for joint in JOINT_NAMES),
        )
        for name in LEG_NAMES
    )


class LegSpec(Section):
    """One leg: where its coxa sits on the body and which servo drives each joint."""

    name: Literal["RF", "LF", "RM", "LM", "RR", "LR"]
    mount_mm: tuple[Finite, Finite, Finite]
    """Coxa joint in the body frame (x forward, y left, z up)."""
    servo_ids: tuple[int, int, int, int, int, int, int]
    """Servo ID of each joint, coxa to wheel; default i = 7l + j + 1 (eq. 4.1)."""

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        lo, hi = 0, MAX_ID
        for j, sid in enumerate(self.servo_ids):
            if not lo <= sid <= hi:
                found.append(
                    Problem(
                        f"{at}.servo_ids[{j}]",
                        sid,
                        f"a Dynamixel ID in {lo}–{hi} ({JOINT_NAMES[j]} of {self.name})",
                    )
                )
        y = self.mount_mm[1]
        if (self.name[0] == "R" and y >= 0) or (self.name[0] == "L" and y <= 0):
            side = "right (y < 0)" if self.name[0] == "R" else "left (y > 0)"
            found.append(
                Problem(f"{at}.mount_mm[1]", y, f"{self.name} is a {side} leg in the body frame")
            )
        return found


def _check_legs(legs: Sequence[LegSpec], at: str) -> list[Problem]:
    found: list[Problem] = []
    names = tuple(leg.name for leg in legs)
    if names != LEG_NAMES:
        found.append(
            Problem(at, list(names), f"exactly six legs in the order {', '.join(LEG_NAMES)}")
        )
    seen: dict[int, str] = {}
    for i, leg in enumerate(legs):
        found.extend(leg.problems(f"{at}[{i}]"))
        for j, sid in enumerate(leg.servo_ids):
            here = f"{at}[{i}].servo_ids[{j}]"
            if sid in seen:
                found.append(
                    Problem(
                        here,
                        sid,
                        f"servo IDs must be unique; {sid} is already used by {seen[sid]}",
                    )
                )
            else:
                seen[sid] = f"{here} ({leg.name} {JOINT_NAMES[j]})"
    return found


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


# --------------------------------------------------------------------------- gait selection


class GaitThresholds(Section):
    """Limits of one locomotion mode; beyond any of them a more stable mode is chosen.

    An absent ``max_obstacles`` or ``max_bumps`` means no limit (Table 5.9 "> 0",
    "> 10": walking gaits accept any count).
    """

    max_step_height_mm: NonNegative
    max_tilt_deg: float = Field(gt=0, le=90, allow_inf_nan=False)
    """Body tilt (roll or pitch) tolerated, symmetric about level."""
    max_obstacles: int | None = Field(default=None, ge=0)
    max_bumps: int | None = Field(default=None, ge=0)
    """IMU bumps counted by the terrain controller (4.2.3)."""
    max_lost_supports: int = Field(ge=0)
    """Disappeared leg supports within the window (4.2.3, 6.7.5)."""


class GaitSelectorSpec(Section):
    """Gait-selector thresholds: Table 5.9, wheel tilt raised from 7° to 20° (6.7.5)."""

    lost_support_window_cycles: Positive = 1.0
    """Disappeared supports are counted over a floating window of one gait cycle (6.7.5)."""
    wheels: GaitThresholds = GaitThresholds(
        max_step_height_mm=0, max_tilt_deg=20, max_obstacles=0, max_bumps=10, max_lost_supports=3
    )
    tripod: GaitThresholds = GaitThresholds(
        max_step_height_mm=100, max_tilt_deg=20, max_lost_supports=3
    )
    tetrapod: GaitThresholds = GaitThresholds(
        max_step_height_mm=120, max_tilt_deg=25, max_lost_supports=4
    )
    ripple: GaitThresholds = GaitThresholds(
        max_step_height_mm=220, max_tilt_deg=30, max_lost_supports=5
    )
    wave: GaitThresholds = GaitThresholds(
        max_step_height_mm=350, max_tilt_deg=30, max_lost_supports=5
    )

    def ranked(self) -> tuple[tuple[str, GaitThresholds], ...]:
        """(mode, thresholds) from wheels to wave."""
        return tuple((name, getattr(self, name)) for name in GAIT_RANKING)

    def problems(self, at: str) -> list[Problem]:
        # A more stable mode must tolerate at least what a less stable one does,
        # or the selector could escalate into a mode that rejects the terrain.
        found: list[Problem] = []
        keys = (
            "max_step_height_mm",
            "max_tilt_deg",
            "max_obstacles",
            "max_bumps",
            "max_lost_supports",
        )
        ranked = self.ranked()
        for key in keys:
            for (lo_name, lo), (hi_name, hi) in itertools.pairwise(ranked):
                a, b = getattr(lo, key), getattr(hi, key)
                a_val = math.inf if a is None else a
                b_val = math.inf if b is None else b
                if b_val < a_val:
                    shown = "no limit" if a is None else f"{a:g}"
                    found.append(
                        Problem(
                            f"{at}.{hi_name}.{key}",
                            b,
                            f"at least {lo_name}'s {shown}: thresholds may not fall along "
                            f"the ranking {' < '.join(GAIT_RANKING)}",
                        )
                    )
        return found


# --------------------------------------------------------------------------- stances


class StanceSpec(Section):
    """A standing posture, the same for all legs up to the front/rear yaw (6.3, 6.4).

    ``reach_mm`` is the horizontal distance from the coxa joint to the wheel's
    contact point, ``height_mm`` the height of the coxa joints above the ground,
    ``front_rear_yaw_deg`` how far front legs turn forward and rear legs
    backward (6.4: 25° stopped the tripod gait from tipping backwards).
    """

    reach_mm: Positive
    height_mm: Positive
    front_rear_yaw_deg: float = Field(default=0.0, ge=-90, le=90, allow_inf_nan=False)
    description: str = ""

    def to_stance(self) -> Stance:
        """This preset in SI, as the kinematics takes it."""
        return Stance(
            reach=self.reach_mm / 1000,
            height=self.height_mm / 1000,
            front_rear_yaw=math.radians(self.front_rear_yaw_deg),
        )


def _default_stances() -> dict[str, StanceSpec]:
    # Fig. 6.1 shows the stances without joint values; reach and height are
    # chosen to match its captions and Table 6.5 (row 1: tarsus at x = 190,
    # y = 120 mm, i.e. contact 120 + 170 mm below the coxa).
    return {
        "default": StanceSpec(
            reach_mm=190,
            height_mm=290,
            front_rear_yaw_deg=25,
            description="walking stance of 6.4: Table 6.5 row 1, front/rear legs turned 25 deg",
        ),
        "basic": StanceSpec(
            reach_mm=190,
            height_mm=290,
            description="Table 6.5 row 1 on every leg (Fig. 6.1 b)",
        ),
        "high": StanceSpec(
            reach_mm=160,
            height_mm=380,
            front_rear_yaw_deg=25,
            description="highest stance, for stepping over high obstacles (Fig. 6.1 a)",
        ),
        "low": StanceSpec(
            reach_mm=240,
            height_mm=200,
            front_rear_yaw_deg=25,
            description="20 cm stance for crawling under low obstacles (Fig. 6.1 c)",
        ),
        "narrow": StanceSpec(
            reach_mm=140,
            height_mm=290,
            description="shortest stance (Fig. 6.1 e)",
        ),
    }


# --------------------------------------------------------------------------- locomotion

Trajectory = Literal["parabola", "half_sine", "hopf", "van_der_pol", "rayleigh", "stick_slip"]
"""Swing shapes: Diosdado 2014, 3.3–3.4, and the CPG orbits of Grzelczyk et al., 8.4."""
ContactSource = Literal["auto", "fsr", "current", "none"]


class LocomotionSpec(Section):
    """The coordinator's and the leg actors' settings (4.2.5, 4.2.6, 5.4, 6.3–6.6).

    Speeds follow from steps: a gait covers one step length per stance, so
    v = L / (β·T) for step length L, duty factor β and cycle time T. The
    coordinator keeps every swing at least ``min_swing_s`` long, T at most
    ``max_cycle_s`` and L within ``max_step_length_mm``; a faster command is
    clamped with an event.
    """

    stance: str = "default"
    """Stance at start (a ``[stances]`` preset); the walking stance of 6.4."""
    ride_stance: str = "basic"
    """Stance for riding: every leg square to the body, so the wheels sit symmetric."""
    gait: Literal["tripod", "tetrapod", "ripple", "wave"] = "tripod"
    hybrid_gait: Literal["tripod", "tetrapod", "ripple", "wave"] = "ripple"
    """The gait stepping while the wheels drive; ripple for its stability (6.6)."""
    trajectory: Trajectory = "parabola"
    min_swing_s: Positive = 0.4
    """Shortest swing: the tripod gait's cycle then lasts 0.8 s, half the 1.6 s of 6.8.1."""
    max_cycle_s: Positive = 6.0
    """Longest gait cycle; slower commands take shorter steps instead."""
    step_length_mm: Positive = 100.0
    """Preferred step. The cycle follows the speed, T = L / (β·v): the tripod gait at
    0.125 m/s steps every 1.6 s, as in 6.8.1 (0.07–0.12 m/s, 1.6 s)."""
    max_step_length_mm: Positive = 140.0
    """Longest step the workspace of every stance preset allows with margin."""
    step_height_mm: Positive = 60.0
    max_step_height_mm: Positive = 120.0
    """Table 5.9: tetrapod steps over 120 mm; the swing apex may not exceed it."""
    max_accel_m_s2: Positive = 0.25
    """Body acceleration limit while walking or riding; velocity changes ramp."""
    max_yaw_accel_deg_s2: Positive = 60.0
    ride_max_speed_m_s: Positive = 0.2
    """Top riding speed measured in 6.5.1."""
    min_turn_radius_mm: Positive = 400.0
    """A circle about a point inside the body (half its length, 300 mm) is refused."""
    hybrid_wheel_share: float = Field(default=0.5, gt=0, lt=1)
    """Share of the hybrid gait's speed the wheels make; the legs step the rest (6.6)."""
    min_stability_margin_mm: Positive = 30.0
    """No leg lifts when the static margin of the remaining feet would fall below this."""
    trochanter_follows_pitch: bool = True
    """Turn the trochanters with the body pitch (eq. 4.18), commanded and measured."""
    tilt_filter_s: Positive = 1.0
    """Time constant of the low-pass on the measured pitch the trochanters follow: a slope
    is steady, the accelerations of walking are not."""
    transition_s: Positive = 1.0
    """Duration of a stance change, a leg re-placement, a body pose change."""
    stand_up_s: Positive = 2.0
    sit_height_mm: Positive = 80.0
    """Coxa joints above the ground when seated: the 60 mm body resting on the ground."""
    sit_down_s: Positive = 1.5
    flip_s: Positive = 2.0
    """Time to turn the legs 180° about their trochanters (6.8.1)."""
    align_tolerance_deg: Positive = 3.0
    """Direction servos within this of their heading before the wheels turn."""
    align_timeout_s: Positive = 1.5
    wheel_stop_speed_m_s: Positive = 0.005
    """A wheel slower than this counts as stopped before its leg lifts."""
    contact: ContactSource = "auto"
    """Foot contact: the force sensor when frames arrive (auto), always it, the femur
    current (6.7.3), or none (no adaptive swing)."""
    contact_current_a: Positive = 0.8
    """|femur current| above this means the foot carries load (6.7.3)."""
    reflex_hold_s: Positive = 0.3
    """A reflex goal keeps its joint this long after it was sent."""
    reflex_blend_s: Positive = 0.3
    """Then the leg blends back from the reflex's pose to its own in this time."""

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        if self.min_swing_s >= self.max_cycle_s:
            found.append(
                Problem(
                    f"{at}.min_swing_s",
                    self.min_swing_s,
                    f"below max_cycle_s ({self.max_cycle_s:g})",
                )
            )
        if self.step_length_mm > self.max_step_length_mm:
            found.append(
                Problem(
                    f"{at}.step_length_mm",
                    self.step_length_mm,
                    f"at most max_step_length_mm ({self.max_step_length_mm:g})",
                )
            )
        if self.step_height_mm > self.max_step_height_mm:
            found.append(
                Problem(
                    f"{at}.step_height_mm",
                    self.step_height_mm,
                    f"at most max_step_height_mm ({self.max_step_height_mm:g})",
                )
            )
        return found


# --------------------------------------------------------------------------- the whole robot


class RobotConfig(CheckedSection):
    """Everything physical or tunable about WHexaR. ``RobotConfig()`` is the thesis robot."""

    schema_version: Literal[1] = 1
    robot: RobotSpec = RobotSpec()
    body: BodySpec = BodySpec()
    servo_models: dict[ServoModelName, ServoModelSpec] = Field(
        default_factory=_default_servo_models
    )
    joints: JointsSpec = JointsSpec()
    dh: DHSpec = DHSpec()
    legs: tuple[LegSpec, ...] = Field(default_factory=_default_legs)
    bus: BusSpec = BusSpec()
    sensor_board: SensorBoardSpec = SensorBoardSpec()
    ir: IRSpec = IRSpec()
    fsr: FSRSpec = FSRSpec()
    imu: ImuSpec = ImuSpec()
    gait_selector: GaitSelectorSpec = GaitSelectorSpec()
    stances: dict[str, StanceSpec] = Field(default_factory=_default_stances)
    locomotion: LocomotionSpec = LocomotionSpec()

    def problems(self, at: str = "") -> list[Problem]:
        """Every relational problem of the whole configuration."""
        found: list[Problem] = []
        for name in type(self).model_fields:
            found.extend(_section_problems(name, getattr(self, name)))
        for check in _CROSS_CHECKS:
            found.extend(check(self))
        return found

    def stance(self, name: str) -> Stance:
        """The stance preset called ``name``, in SI; a ConfigError names the known ones."""
        try:
            return self.stances[name].to_stance()
        except KeyError:
            allowed = ", ".join(sorted(self.stances))
            raise ConfigError("stances", [Problem("stances", name, f"one of {allowed}")]) from None

    def leg_geometry(self) -> LegGeometry:
        """The legs' geometry in SI, as the kinematics takes it (Tables 5.2, 5.3)."""
        rows = self.dh.rows()
        limits = []
        for name in POSITIONING_JOINTS:
            rad = self.joints.by_name(name).limits_rad
            limits.append(rad if rad is not None else (-math.inf, math.inf))
        return LegGeometry(
            dh_d=np.array([r.d_mm / 1000 for r in rows]),
            dh_a=np.array([r.a_mm / 1000 for r in rows]),
            dh_alpha=np.array([math.radians(r.alpha_deg) for r in rows]),
            theta_offset=np.array([math.radians(r.theta_offset_deg) for r in rows]),
            theta_sign=np.array([float(r.theta_sign) for r in rows]),
            limits=np.array(limits),
            direction_length=self.joints.direction.length_mm / 1000,
            wheel_radius=self.joints.wheel.length_mm / 1000,
            mounts=np.array([[c / 1000 for c in leg.mount_mm] for leg in self.legs]),
        )

    def servos(self) -> dict[int, ServoModelName]:
        """Every servo's ID and model, legs in order and coxa to wheel within each."""
        return {
            sid: self.joints.by_name(JOINT_NAMES[j]).model
            for leg in self.legs
            for j, sid in enumerate(leg.servo_ids)
        }


def _section_problems(name: str, value: object) -> list[Problem]:
    """Relational problems inside one top-level section."""
    if name == "legs":
        return _check_legs(typing.cast(Sequence[LegSpec], value), name)
    if isinstance(value, Section):
        return value.problems(name)
    if isinstance(value, Mapping):
        return [
            p
            for key, item in value.items()
            if isinstance(item, Section)
            for p in item.problems(format_path((name, key)))
        ]
    return []


def _check_dh_lengths(cfg: RobotConfig) -> list[Problem]:
    # Each DH length against the measured segment it stands for (Tables 5.2–5.3).
    pairs = (
        ("trochanter", "d_mm"),
        ("femur", "a_mm"),
        ("tibia", "a_mm"),
        ("tarsus", "a_mm"),
    )
    found: list[Problem] = []
    for joint, key in pairs:
        value = getattr(getattr(cfg.dh, joint), key)
        segment = cfg.joints.by_name(joint).length_mm
        if abs(value - segment) > DH_SEGMENT_TOLERANCE_MM:
            found.append(
                Problem(
                    f"dh.{joint}.{key}",
                    value,
                    f"within {DH_SEGMENT_TOLERANCE_MM:g} mm of joints.{joint}.length_mm "
                    f"({segment:g} mm, the measured segment)",
                )
            )
    return found


def _check_servo_models(cfg: RobotConfig) -> list[Problem]:
    return [
        Problem(f"joints.{name}.model", cfg.joints.by_name(name).model, msg)
        for name in JOINT_NAMES
        if cfg.joints.by_name(name).model not in cfg.servo_models
        for msg in [f"a model described under servo_models ({', '.join(cfg.servo_models)})"]
    ]


def _check_stances(cfg: RobotConfig) -> list[Problem]:
    # Each preset must be reachable by every leg within the joint limits, or
    # the robot could be commanded into a posture it cannot take.
    if _check_servo_models(cfg) or cfg.joints.problems("joints") or cfg.dh.problems("dh"):
        return []
    geometry = cfg.leg_geometry()
    found: list[Problem] = []
    for name, stance in cfg.stances.items():
        try:
            ik(stance_feet(stance.to_stance()), geometry, target="contact")
        except KinematicsError as exc:
            found.append(
                Problem(
                    format_path(("stances", name)),
                    {"reach_mm": stance.reach_mm, "height_mm": stance.height_mm},
                    f"a stance every leg can reach within its joint limits ({exc})",
                )
            )
    return found


def _check_locomotion_stances(cfg: RobotConfig) -> list[Problem]:
    found: list[Problem] = []
    allowed = ", ".join(sorted(cfg.stances))
    for key in ("stance", "ride_stance"):
        name = getattr(cfg.locomotion, key)
        if name not in cfg.stances:
            found.append(Problem(f"locomotion.{key}", name, f"a stance preset: {allowed}"))
    sit = cfg.locomotion.sit_height_mm
    if any(sit >= s.height_mm for s in cfg.stances.values()):
        low = min(s.height_mm for s in cfg.stances.values())
        found.append(
            Problem("locomotion.sit_height_mm", sit, f"below every stance height ({low:g})")
        )
    return found


_CROSS_CHECKS: Final[tuple[Callable[[RobotConfig], list[Problem]], ...]] = (
    _check_locomotion_stances,
    _check_dh_lengths,
    _check_servo_models,
    _check_stances,
)


# --------------------------------------------------------------------------- loading


@functools.cache
def _defaults() -> dict[str, Any]:
    """``RobotConfig()`` as a document: what a file's keys are merged into."""
    return RobotConfig().model_dump(mode="python")


def _merge(default: object, given: object) -> object:
    """``given`` over ``default``: tables merge key by key, recursively; anything else replaces."""
    if isinstance(default, Mapping) and isinstance(given, Mapping):
        merged = {key: copy.deepcopy(value) for key, value in default.items()}
        for key, value in given.items():
            merged[key] = _merge(default[key], value) if key in default else value
        return merged
    return given


def merge_defaults(data: Mapping[str, Any]) -> dict[str, Any]:
    """A configuration document completed with the defaults of ``RobotConfig()``.

    The merge rule: a table merges with the default table key by key,
    recursively, so a file names only the keys it changes
    (``[joints.femur]`` with ``min_deg = -100`` keeps the femur's model, limit
    and length). Mapping-valued sections are tables too: ``[stances.crouch]``
    adds a stance next to the presets, ``[stances.high]`` with one key changes
    that key of the preset, and likewise ``[servo_models."MX-64"]``. An array —
    ``legs``, ``mount_mm``, ``zero_g_counts`` — replaces the default whole, as
    does a value whose type differs from the default's (``bus.plan``: a preset
    name or a table). Nothing can be deleted: a key the defaults have stays.
    An unknown key stays unknown and is reported as such.
    """
    merged = _merge(_defaults(), data)
    assert isinstance(merged, dict)
    return merged


def parse_config(data: Mapping[str, Any], source: str = "<config>") -> RobotConfig:
    """Validate a configuration document (as parsed from TOML) into a :class:`RobotConfig`.

    The document needs only the keys it changes: it is merged with the
    defaults first (:func:`merge_defaults`). Raises
    :class:`~whexar.errors.ConfigError` listing every problem found.
    """
    data = merge_defaults(data)
    try:
        cfg = RobotConfig.model_validate(data, context={"defer_relations": True})
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
    else:
        found = cfg.problems()
        if found:
            raise ConfigError(source, found)
        return cfg
    problems = [problem_from_error(error, RobotConfig) for error in errors]
    # Sections that validated on their own still get their relational checks,
    # so a bad key in one section does not hide a duplicate ID in another.
    failed = {e["loc"][0] for e in errors if e["loc"]}
    for name, field in RobotConfig.model_fields.items():
        if name in failed or name not in data or field.annotation is None:
            continue
        try:
            section = TypeAdapter(field.annotation).validate_python(data[name])
        except ValidationError:
            continue
        problems.extend(_section_problems(name, section))
    raise ConfigError(source, problems)


def load_config(path: str | Path) -> RobotConfig:
    """Read and validate a TOML robot configuration.

    Raises :class:`~whexar.errors.ConfigError` listing every problem: the key
    path, the value found and what is allowed.
    """
    return parse_config(read_toml(path), str(path))


def config_schema() -> dict[str, Any]:
    """JSON Schema of the configuration file, for editors.

    It follows the merge rule (:func:`merge_defaults`): inside a table that
    has a default no key is required, and so on down; the presets of a
    mapping-valued section (``stances``, ``servo_models``) are listed with
    nothing required, while a new entry (a new stance) and an array item (a
    leg) must be complete.
    """
    schema = RobotConfig.model_json_schema()
    defs: dict[str, Any] = schema.get("$defs", {})
    partial = _partial(schema, _defaults(), defs)
    partial["title"] = "WHexaR robot configuration"
    # Keep only the definitions still referred to (a section's full form is
    # not, once its relaxed form took its place).
    used: set[str] = set()
    todo: list[object] = [{k: v for k, v in partial.items() if k != "$defs"}]
    while todo:
        item = todo.pop()
        if isinstance(item, dict):
            ref = item.get("$ref")
            if isinstance(ref, str) and (name := ref.rsplit("/", 1)[-1]) not in used:
                used.add(name)
                todo.append(defs[name])
            todo.extend(item.values())
        elif isinstance(item, list):
            todo.extend(item)
    partial["$defs"] = {name: value for name, value in defs.items() if name in used}
    return partial


def _partial(node: dict[str, Any], default: object, defs: dict[str, Any]) -> dict[str, Any]:
    """``node``'s schema for a value merged into ``default``: see :func:`config_schema`."""
    if not isinstance(default, Mapping):
        return node
    ref = node.get("$ref")
    target = defs[ref.rsplit("/", 1)[-1]] if isinstance(ref, str) else node
    if "properties" in target:
        relaxed = {key: value for key, value in target.items() if key != "required"}
        relaxed["properties"] = {
            key: _partial(value, default.get(key), defs)
            for key, value in target["properties"].items()
        }
    elif isinstance(target.get("additionalProperties"), dict):
        item = target["additionalProperties"]
        relaxed = dict(target)
        relaxed["properties"] = {key: _partial(item, value, defs) for key, value in default.items()}
    else:
        return node
    if not isinstance(ref, str):
        return relaxed
    name = f"{ref.rsplit('/', 1)[-1]}Partial"
    defs[name] = relaxed
    return {**{k: v for k, v in node.items() if k != "$ref"}, "$ref": f"#/$defs/{name}"}


@functools.cache
def default_geometry() -> LegGeometry:
    """The leg geometry of the thesis robot, ``RobotConfig().leg_geometry()``, made once."""
    return RobotConfig().leg_geometry()


ConfigFile = Annotated[str, AfterValidator(loads(load_config, "a robot configuration"))]
"""An actor parameter naming a robot configuration file, checked with the wiring."""
