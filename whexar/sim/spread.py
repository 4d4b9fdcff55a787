"""The spread of real parts: a seeded world where no two robots are quite the same.

Theory of operation
-------------------
Without a spread the simulated WHexaR is the nominal robot of the datasheets, and
every run of a scenario is the same run. :class:`Spread` draws, from
``numpy.random.default_rng(seed)``, what differs from one real part to the next,
each within the amplitude its datasheet gives (the constants below; docs/sim.md,
"Spread of real parts", sets them side by side with their sources):

* the sensors: each force sensor's gain and the scatter of its readings, each
  rangefinder's gain, the IMU's zero-g level as its calibration leaves it and its
  zero-rate level;
* the ground: each wheel's sliding friction;
* the masses: every link of the robot heavier or lighter, the body's centre of mass
  moved;
* the servos: each joint's gear backlash (play between the motor and the horn);
* the USB adapter: each reply's delay jittered by the latency timer.

:func:`apply` puts a spread into a world before it runs; the draws that go on
during the run (readings, reply delays) come from generators seeded by the same
seed, called in an order that virtual time fixes, so that the same seed gives the
same run bit for bit and another seed another run. :meth:`Spread.none` is the
perfect world: :func:`apply` then changes nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

import mujoco
import numpy as np

from whexar.robot import LEG_NAMES
from whexar.sim.terrain import GROUND_FRICTION
from whexar.sim.world import fsr_counts

if TYPE_CHECKING:
    from whexar.sim.world import SimWorld

# Every amplitude is a half-width: a part's value is drawn uniformly within ± it
# (a datasheet's typical or guaranteed band, not a standard deviation).

FSR_GAIN: Final = 0.06
"""Force sensor gain, part to part: ±6 % (Interlink FSR 400 series data sheet, "force
repeatability, part to part, single batch")."""
FSR_REPEAT: Final = 0.02
"""Force sensor reading to reading: ±2 % (the same data sheet, "force repeatability,
single part")."""
IR_GAIN: Final = 0.25 / 1.9
"""Rangefinder gain, part to part: the output swing from 80 cm to 10 cm is 1.65–2.15 V,
typically 1.9 V (Sharp GP2Y0A21YK data sheet, "difference of output voltage")."""
ACCEL_OFFSET_G: Final = math.sin(math.radians(0.26))
"""Accelerometer zero-g level per axis left by the robot's calibration
(``imu.accel_offset_g``): ±4.5 mg, the sine of the largest tilt error the thesis
measured on its calibrated IMU between −80° and +80° (Žák 2023, Table 6.4: 0.26° at
30°). Uncalibrated, the part is off by up to ±90 mg (LSM9DS1 data sheet DocID025715,
Table 3), a false tilt of 5° that the trochanters would follow."""
GYRO_OFFSET_DPS: Final = 30.0
"""Gyroscope zero-rate level per axis: ±30 dps (LSM9DS1 data sheet, Table 3, "angular
rate typical zero-rate level"), uncalibrated: the thesis reads only the accelerometer
(5.4), and nothing in whexar's control reads the rate yet."""
FRICTION_RANGE: Final = (0.8 / 0.9, 1.0 / 0.9)
"""A wheel's sliding friction on the ground, as a factor on the nominal
(:data:`~whexar.sim.terrain.GROUND_FRICTION`, 1.3, which standing on the thesis's 50°
needs): ±11 %, the spread of rubber on concrete, µk 0.8 to µs 1.0 about their middle
(Serway and Beichner, Table 5.2)."""
MASS_TOLERANCE: Final = 0.05
"""Every link's mass and inertia: ±5 %, cables, screws and glue that no drawing lists
(an estimate; the servos' own masses are single figures in their e-manuals)."""
COM_SHIFT_M: Final = 0.005
"""The body's centre of mass per axis: ±5 mm, where the battery and the cables sit
(an estimate, a twelfth of the body tube's width)."""
BACKLASH_RAD: Final = math.radians(20 / 60)
"""Gear backlash, at most: 20 arcmin (0.33°), MX-64 and MX-106 e-manuals,
"Specifications"; a joint's is drawn within 0 … this."""
REPLY_JITTER_S: Final = 0.0005
"""A status packet's delay through the USB adapter: ±0.5 ms about the fitted mean. The
FTDI chip hands bytes to the host when its latency timer expires, and 1 ms, the
setting used, is the USB frame length (FTDI AN232B-04, "latency timer"): a reply
waits anywhere within one frame."""

_READINGS: Final = 1
_REPLIES: Final = 2
"""Streams of the draws made while running, beside the parts' own (stream 0)."""


@dataclass(frozen=True)
class Spread:
    """One robot's parts and the seed of its running draws (see the module docstring).

    Neutral values (gain 1, offset 0, …) leave the world as it is."""

    seed: int | None
    """``None``: the perfect world (:meth:`none`)."""
    fsr_gain: tuple[float, ...] = (1.0,) * 6
    ir_gain: tuple[float, float] = (1.0, 1.0)
    accel_offset_g: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_offset_dps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wheel_friction: tuple[float, ...] = ()
    """Sliding friction of each leg's wheel (empty: the model's)."""
    mass_factor: tuple[float, ...] = ()
    """A factor on each robot body's mass and inertia, in body id order (empty: none)."""
    com_shift_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    backlash_rad: tuple[float, ...] = ()
    """Each joint's backlash, in the world's joint order (empty: none)."""

    @classmethod
    def none(cls) -> Spread:
        """The perfect world: the datasheets' nominal parts, no running draws."""
        return cls(seed=None)

    @classmethod
    def draw(cls, seed: int, model: mujoco.MjModel, joints: int) -> Spread:
        """The parts of the robot ``seed`` names, for ``model`` with ``joints`` servo joints."""
        rng = np.random.default_rng([seed, 0])

        def within(half: float, n: int) -> tuple[float, ...]:
            return tuple(float(v) for v in rng.uniform(-half, half, n))

        base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base")
        robot = [b for b in range(model.nbody) if int(model.body_rootid[b]) == base]
        lo, hi = FRICTION_RANGE
        ax, ay, az = within(ACCEL_OFFSET_G, 3)
        gx, gy, gz = within(GYRO_OFFSET_DPS, 3)
        cx, cy, cz = within(COM_SHIFT_M, 3)
        ir_right, ir_left = (1.0 + g for g in within(IR_GAIN, 2))
        return cls(
            seed=seed,
            fsr_gain=tuple(1.0 + g for g in within(FSR_GAIN, 6)),
            ir_gain=(ir_right, ir_left),
            accel_offset_g=(ax, ay, az),
            gyro_offset_dps=(gx, gy, gz),
            wheel_friction=tuple(
                GROUND_FRICTION[0] * float(v) for v in rng.uniform(lo, hi, len(LEG_NAMES))
            ),
            mass_factor=tuple(1.0 + f for f in within(MASS_TOLERANCE, len(robot))),
            com_shift_m=(cx, cy, cz),
            backlash_rad=tuple(float(v) for v in rng.uniform(0.0, BACKLASH_RAD, joints)),
        )


def apply(spread: Spread, world: SimWorld) -> None:
    """Put ``spread`` into ``world`` (before it runs): its model's parts, its servo law's
    dead zone, its sensors' readings and its chain's reply delays."""
    if spread.seed is None:
        return
    m = world.model
    if spread.wheel_friction:
        # The world grips with these, lowered while a wheel rolls (SimWorld._grip).
        world.wheel_friction[:] = spread.wheel_friction
        for leg, mu in zip(LEG_NAMES, spread.wheel_friction, strict=True):
            m.geom_friction[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{leg}_wheel"), 0] = mu
    if spread.mass_factor:
        base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base")
        robot = [b for b in range(m.nbody) if int(m.body_rootid[b]) == base]
        for b, f in zip(robot, spread.mass_factor, strict=True):
            m.body_mass[b] *= f
            m.body_inertia[b] *= f
        m.body_ipos[base] += spread.com_shift_m
    if spread.backlash_rad:
        # The gears' play, between the motor and the horn that the encoder reads
        # (SimWorld._through_the_play).
        world.dead_zone_rad = np.asarray(spread.backlash_rad) / 2
    readings = np.random.default_rng([spread.seed, _READINGS])
    world.sense_hook = lambda w: _read(spread, w, readings)
    replies = np.random.default_rng([spread.seed, _REPLIES])
    world.chain.reply_jitter = lambda: float(replies.uniform(-REPLY_JITTER_S, REPLY_JITTER_S))


def _read(spread: Spread, world: SimWorld, rng: np.random.Generator) -> None:
    """The sensors as this robot's parts read what the world just sensed."""
    scatter = rng.uniform(1.0 - FSR_REPEAT, 1.0 + FSR_REPEAT, 6)
    world.fsr_counts = [
        0 if leg in world.dead_fsr else fsr_counts(f * g * float(s))
        for leg, (f, g, s) in enumerate(
            zip(world.contact_forces, spread.fsr_gain, scatter, strict=True)
        )
    ]
    world.ir_counts = [
        0 if c == 0 else max(1, min(1023, round(c * g)))
        for c, g in zip(world.ir_counts, spread.ir_gain, strict=True)
    ]
    if world.imu is not None:
        # What the chip's calibration leaves, on top of what the configuration took off
        # (SimWorld); the board's analog accelerometer is another part.
        ax, ay, az = world.imu.accel_g
        ox, oy, oz = spread.accel_offset_g
        world.imu.accel_g = (ax + ox, ay + oy, az + oz)
        wx, wy, wz = world.imu.gyro_dps
        gx, gy, gz = spread.gyro_offset_dps
        world.imu.gyro_dps = (wx + gx, wy + gy, wz + gz)


__all__ = [
    "ACCEL_OFFSET_G",
    "BACKLASH_RAD",
    "COM_SHIFT_M",
    "FRICTION_RANGE",
    "FSR_GAIN",
    "FSR_REPEAT",
    "GYRO_OFFSET_DPS",
    "IR_GAIN",
    "MASS_TOLERANCE",
    "REPLY_JITTER_S",
    "Spread",
    "apply",
]
