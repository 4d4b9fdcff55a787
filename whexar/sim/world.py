"""The physics world behind the servo emulator and the sensor emulators.

Theory of operation
-------------------
whexar runs against the simulation exactly as against the robot: the bus
scheduler talks to an emulated servo chain through dynamixel-sdk, the sensor
reader decodes the emulated board's frames, the IMU reader reads a fake
LSM9DS1. :class:`SimWorld` puts a MuJoCo model behind all three.

*Time.* Nothing advances the world but the bus: every transaction brings the
servos up to the transaction's bus time, and here the world does it as the
chain's :attr:`~whexar.bus.emulator.chain.ServoChain.mover`
(:meth:`SimWorld.move_servos`): it steps itself to that time, then hands each
servo its joint's state (:meth:`~whexar.bus.emulator.servo.VirtualServo.follow`).
A servo advanced on its own reads its joint through :class:`_JointDynamics`.
A transaction taking 6 ms of wire time costs 6 ms of simulated time; on
virtual time the whole run is deterministic. The world steps in whole
timesteps, so it lags bus time by less than one.

*Servos.* Each step, every joint's torque is what an MX servo's firmware and
motor make of its control table (:mod:`whexar.sim.motors`):

* position modes: the firmware's profile moves a desired position toward Goal
  Position at Profile Velocity (or the Velocity Limit) and Profile
  Acceleration; the duty cycle is the Position P Gain (84) times the error,
  clipped to ±96 %; velocity mode (the wheels): PI on the velocity error with
  Velocity P and I Gains (78, 76);
* the H-bridge puts duty × supply voltage on the motor, whose torque is
  τ = kt·V/R − kt²·ω/R (BAM); armature and Coulomb and viscous friction are the
  joint's own, and every step the joint's friction budget grows with the torques
  the gears carry (BAM's model m6, :class:`~whexar.sim.motors.GearFriction`);
* torque off: no voltage and an open bridge: the joint coasts.

Present Position and Velocity are the joint's; Present Current is τ / kt (the
MX-28 reports Present Load, the same as a fraction of its stall current).

*Divergence.* A world MuJoCo can no longer integrate (a non-finite or huge
position, velocity or acceleration: a robot that tumbled for seconds down an
endless 50° plane reached 23 m/s before it did) is not reset to the model's
first pose, as MuJoCo would by default (the robot would stand up again where it
started): the world goes back to its state at the start of that transaction,
holds it still from then on, and says when (:attr:`SimWorld.diverged_at`,
:attr:`SimWorld.divergence`); the run stops there (:mod:`whexar.sim.run`).
MuJoCo's own line on stderr for it is not printed: the run says it.

*Supply* (:mod:`whexar.sim.power`). Each step the world adds up what the
servos' bridges draw from the 12 V line, Σ duty × winding current; with the
standby currents and the electronics that is the supply current the thesis
measured (Table 6.7). A bench supply holds its voltage; a battery's sags, and
the servos' voltage (their torque, Present Input Voltage, Input Voltage
Error) follows it after every transaction.

*Sensors*, refreshed as the world advances (every :data:`SENSE_PERIOD_S`):
the force sensor under each leg reads the wheel's contact force through an
FSR divider (:func:`fsr_counts`); the IR rangefinders cast rays
(eq. 5.5 inverted); the IMU reads the specific force and angular rate at the
``imu`` site, mounted with its x axis to the body's left and its y axis to
the rear, so that the tilt angles of eq. 5.6–5.7 are the body's roll and
pitch (nose down positive).

*Physical faults* (:mod:`whexar.sim.faults`), each begun and ended by its caller under a
key of its own: :meth:`SimWorld.push` (a force on the body), :meth:`SimWorld.slip`
(another friction under a wheel or an area, through the wheels' grip),
:meth:`SimWorld.limp` (servos without power: no torque, no reply) and
:meth:`SimWorld.snag` (a joint held by a limit narrowed to its angle).
"""

from __future__ import annotations

import hashlib
import math
import sys
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass, fields
from operator import is_not
from typing import Final

import mujoco
import numpy as np

from whexar.bus import control_table as ct
from whexar.bus.emulator.chain import ServoChain
from whexar.bus.emulator.dynamics import VELOCITY_MODE, Drive, Motion, ServoView
from whexar.bus.emulator.servo import VirtualServo
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.sensors.board_emulator import (
    SensorBoardEmulator,
    counts_for_acceleration,
    counts_for_distance,
)
from whexar.sensors.frame import ACC_KEYS, FSR_KEYS, IR_KEYS
from whexar.sensors.imu_emulator import FakeLsm9ds1
from whexar.sim.motors import (
    CONTROL_PERIOD_S,
    DEFAULT_MOTORS,
    MAX_DUTY,
    PWM_LIMIT,
    TICKS_PER_RAD,
    GearFriction,
    MotorModel,
    MotorSource,
    motors,
    position_duty_per_rad,
    position_id_duty,
)
from whexar.sim.power import BenchSupply, Supply, supply_amps
from whexar.sim.terrain import GROUND_FRICTION, ROLLING_RAD_S, ROLLING_TRACTION
from whexar.sim.tilt import BoardTilt

_ROLLING_SHARE: Final = ROLLING_TRACTION / GROUND_FRICTION[0]
"""A rolling wheel's grip as a share of its static grip (:meth:`SimWorld._grip`)."""
_GAINS_SPAN: Final = slice(76, 86)
"""Velocity I (76), Velocity P (78) … Position P Gain (84): the gain registers (e-manual)."""
_INSTABILITIES: Final = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
)
"""MuJoCo's warnings of a state it cannot integrate: the world has diverged."""
_UNSTABLE: Final = "Nan, Inf or huge value in "
"""How MuJoCo's text for each of them begins (mju_warningText)."""


def _mujoco_warning(text: str) -> None:
    """MuJoCo's warnings, as its own handler prints them to stderr but with no
    ``MUJOCO_LOG.TXT`` left in the working folder; a divergence is the run's to say."""
    if not text.startswith(_UNSTABLE):
        sys.stderr.write(f"WARNING: {text}\n")


SENSE_PERIOD_S: Final = 0.02
"""How often the simulated sensors are refreshed: 50 Hz, the rate the board samples its
inputs at (firmware/PROTOCOL.md) and the IMU reader reads (``imu.rate_hz``)."""
STANDARD_G: Final = 9.80665
FSR_DIVIDER_OHM: Final = 10_000.0
"""The FSR's divider resistor on the sensor board (Fig. 5.7: 10 kΩ)."""
FSR_OHM_NEWTON: Final = 100_000.0
"""FSR resistance × force, Ω·N: an FSR's conductance grows about linearly with force
(Interlink FSR 400 series integration guide, "force vs. conductance"): 100 kΩ at 1 N,
7 kΩ under a sixth of WHexaR's weight (14.4 N)."""
ADC_MAX: Final = 1023
VELOCITY_UNIT_RAD_S: Final = ct.velocity_to_rad_s(1)
"""Velocity registers count 0.229 rev/min (e-manual)."""
KVP_DIVISOR: Final = 128
KVI_DIVISOR: Final = 65536
"""Velocity P Gain (78) / 128 and Velocity I Gain (76) / 65536 (e-manual, MX (2.0))."""
_FRICTION_DOF: Final = int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF)


class _GearTerms:
    """Every joint's :class:`~whexar.sim.motors.GearFriction` as arrays (zeros where a
    motor has none), for :meth:`SimWorld._gear_friction`."""

    def __init__(self, table: Sequence[MotorModel]) -> None:
        # A joint without gear terms gets zeros, and a harmless speed and exponent of 1.
        for f in fields(GearFriction):
            none = 1.0 if f.name in ("dtheta_stribeck", "alpha") else 0.0
            column = [getattr(m.gear, f.name) if m.gear else none for m in table]
            setattr(self, f.name, np.array(column))
        self.has = np.array([m.gear is not None for m in table])
        self.coulomb = np.array([m.coulomb for m in table])
        self.inv_speed = 1.0 / self.dtheta_stribeck

    friction_stribeck: np.ndarray
    load_friction_motor: np.ndarray
    load_friction_external: np.ndarray
    load_friction_motor_stribeck: np.ndarray
    load_friction_external_stribeck: np.ndarray
    load_friction_motor_quad: np.ndarray
    load_friction_external_quad: np.ndarray
    dtheta_stribeck: np.ndarray
    alpha: np.ndarray


def fsr_counts(force_n: float) -> int:
    """ADC counts of the FSR divider under ``force_n`` newtons (0 with no load)."""
    if force_n <= 0.0:
        return 0
    r_fsr = FSR_OHM_NEWTON / force_n
    return min(ADC_MAX, round(ADC_MAX * FSR_DIVIDER_OHM / (FSR_DIVIDER_OHM + r_fsr)))


@dataclass(eq=False)
class _Joint:
    """One joint of the world and the servo that drives it."""

    leg: int
    joint: int
    servo: VirtualServo
    qadr: int
    dadr: int
    actuator: int
    kt: float
    resistance: float
    stall_current: float
    amps_unit: float | None
    index: int = 0
    """Position in the world's joint arrays."""
    gains_raw: bytes = b""
    """The gain registers' bytes the arrays were last computed from."""


class _JointDynamics:
    """A virtual servo's dynamics: the world's joint (the seam of emulator.dynamics)."""

    def __init__(self, world: SimWorld, joint: _Joint) -> None:
        self.world = world
        self.joint = joint

    def advance(self, motion: Motion, drive: Drive, dt: float) -> None:
        """Step the world to the servo's time, then read the joint.

        A servo advanced by itself (a test, a watchdog's expiry) comes here; the
        chain's transactions move every servo at once (:meth:`SimWorld.move_servos`).
        """
        j = self.joint
        world = self.world
        t = j.servo.time
        if world.time + world.h <= t + 1e-12:
            world.advance_to(t)
        k = j.index
        motion.position = world.position_ticks[k]
        motion.velocity = world.velocity_ticks[k]
        motion.acceleration = world.accel_ticks[k]


def gear_play(
    tau: np.ndarray,
    free_w: np.ndarray,
    w: np.ndarray,
    play: np.ndarray,
    half: np.ndarray,
    h: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The torque that reaches each horn through gears with play ``±half`` (rad), and
    where the motor's side sits in the play after a step of ``h`` s.

    An MX servo's encoder (AS5045) reads the horn, so its position loop sees the horn's
    error however the gears sit: the play is in the drive, not in the loop. While the
    motor's side is inside it, the motor turns unloaded at the speed its duty gives
    (``free_w``, output scale) and no torque reaches the horn; at the flank its torque
    pushes on, the gears are engaged and the torque acts. A load that keeps one flank
    engaged meets no play; a torque that changes sign is lost while the motor crosses it
    (0.9 ms at full duty for the MX's 20 arcmin)."""
    play = np.minimum(np.maximum(play + (free_w - w) * h, -half), half)
    engaged = ((play >= half) & (tau >= 0.0)) | ((play <= -half) & (tau <= 0.0))
    return np.where(engaged, tau, 0.0), play


Span = tuple[float, float]
"""(min, max), m."""


@dataclass(frozen=True)
class Patch:
    """Ground of another friction: under one wheel (``leg``), or under the area
    ``x`` × ``y`` (a span ``None`` is unbounded: a strip)."""

    friction: float
    """The nominal tyre's sliding µ on it."""
    leg: int | None = None
    x: Span | None = None
    y: Span | None = None

    def covers(self, xy: np.ndarray) -> np.ndarray:
        """Which of the wheels touching at ``xy`` (one row of x, y, m, per wheel) it lies
        under."""
        if self.leg is not None:
            under: np.ndarray = np.arange(len(xy)) == self.leg
            return under
        inside = np.ones(len(xy), dtype=bool)
        for axis, span in enumerate((self.x, self.y)):
            if span is not None:
                inside &= (xy[:, axis] >= span[0]) & (xy[:, axis] <= span[1])
        return inside


class SimWorld:
    """A MuJoCo model of WHexaR driving the emulated servos, board and IMU.

    ``model`` is the robot on its terrain (:func:`whexar.sim.model.load_model`);
    ``chain`` the servo chain the bus scheduler opens; ``board`` and ``imu`` the
    sensor emulators, when the graph reads them.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        chain: ServoChain,
        *,
        cfg: RobotConfig | None = None,
        board: SensorBoardEmulator | None = None,
        imu: FakeLsm9ds1 | None = None,
        tilt: BoardTilt | None = None,
        supply: Supply | None = None,
        motor_source: MotorSource = DEFAULT_MOTORS,
    ) -> None:
        self.cfg = cfg or RobotConfig()
        self.supply: Supply = supply or BenchSupply(self.cfg.robot.supply_voltage_v)
        """What feeds the servos' line (:mod:`whexar.sim.power`)."""
        self.supply_a = 0.0
        """The line's mean current over the last transaction's steps, A."""
        self._bridge_c = 0.0
        """Charge the bridges drew over the steps of one :meth:`advance_to`, C."""
        self._bridge_a = 0.0
        """Σ duty × winding current of the last step, A."""
        table = motors(motor_source)
        self.model = model
        self.tilt = tilt
        """The board's tilt (:mod:`whexar.sim.tilt`): gravity turns with it."""
        self._g = float(np.linalg.norm(model.opt.gravity))
        # A diverged step is held, not reset to the model's first pose (module docstring).
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        if mujoco.get_mju_user_warning() is None:  # process-wide: every world's, once
            mujoco.set_mju_user_warning(_mujoco_warning)
        self.data = mujoco.MjData(model)
        self.diverged_at: float | None = None
        """When the physics diverged (s), after which the world holds still; ``None``: it
        has not."""
        self.divergence = ""
        """What diverged, in words (MuJoCo's warning: the quantity and the DOF)."""
        self._instabilities = [self.data.warning[w] for w in _INSTABILITIES]
        self.chain = chain
        self.board = board
        self.imu = imu
        self._imu_levels = (self.cfg.imu.accel_offset_g, self.cfg.imu.gyro_offset_dps)
        self.h = float(model.opt.timestep)
        self.steps = 0
        self.time = 0.0
        self._sensed_at = -math.inf
        self._imu_v = np.zeros(3)
        self.accel_g: tuple[float, float, float] = (0.0, 0.0, 1.0)
        """The specific force at the IMU site in g, in the sensors' axes."""
        self._imu_t = 0.0
        self.joints: list[_Joint] = []
        self.by_servo: dict[int, _Joint] = {}
        chosen: list[MotorModel] = []
        for leg, spec in enumerate(self.cfg.legs):
            for j, sid in enumerate(spec.servo_ids):
                name = f"{LEG_NAMES[leg]}_{JOINT_NAMES[j]}"
                jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
                aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
                servo = chain.servos[sid]
                model_name = servo.model.name
                motor = table[model_name]
                joint = _Joint(
                    leg,
                    j,
                    servo,
                    int(model.jnt_qposadr[jid]),
                    int(model.jnt_dofadr[jid]),
                    aid,
                    motor.kt,
                    motor.resistance,
                    self.cfg.servo_models[model_name].stall_current_a,  # type: ignore[index]
                    servo.model.current_unit_a,
                )
                joint.index = len(self.joints)
                self.joints.append(joint)
                self.by_servo[sid] = joint
                servo.dynamics = _JointDynamics(self, joint)
                chosen.append(motor)
        n = len(self.joints)
        # Friction and armature are the run's motors' (the model file has BAM's m6).
        dofs = [j.dadr for j in self.joints]
        model.dof_armature[dofs] = [m.armature for m in chosen]
        model.dof_damping[dofs] = [m.viscous for m in chosen]
        model.dof_frictionloss[dofs] = [m.coulomb for m in chosen]
        mujoco.mj_setConst(model, self.data)
        self._gear = _GearTerms(chosen) if any(m.gear for m in chosen) else None
        self._dofs = np.array(dofs)
        self._own_friction = np.zeros(model.nv)
        self._servos = [j.servo for j in self.joints]
        self._others = [s for s in chain.servos.values() if s not in self._servos]
        """Servos on the chain that drive no joint of the world: their own dynamics."""
        chain.mover = self.move_servos
        self._qadr = _index([j.qadr for j in self.joints])
        self._dadr = _index([j.dadr for j in self.joints])
        self._act = _index([j.actuator for j in self.joints])
        self._kt = np.array([j.kt for j in self.joints])
        # Present Current is τ / kt; the MX-28's Present Load is that over its stall current.
        self._load_scale = np.array(
            [1.0 if j.amps_unit is not None else j.stall_current for j in self.joints]
        )
        self._index_of: dict[ServoView, int] = {j.servo: j.index for j in self.joints}
        self._amps: list[float] = [0.0] * n
        self._resistance = np.array([j.resistance for j in self.joints])
        self._on = np.zeros(n, dtype=bool)
        self._velocity_mode = np.zeros(n, dtype=bool)
        self._goal, self._vmax, self._amax = np.zeros(n), np.zeros(n), np.full(n, np.inf)
        self._drives: Sequence[Drive | None] = [None] * n
        """The drive each joint's arrays were last computed from."""
        self._orders_now: tuple[list[bool], list[bool], list[float], list[float], list[float]] = (
            [False] * n,
            [False] * n,
            [0.0] * n,
            [0.0] * n,
            [math.inf] * n,
        )
        """Torque on, velocity mode, goal, top speed, acceleration: :meth:`_orders`' lists."""
        self._kp, self._kvp, self._kvi = np.zeros(n), np.zeros(n), np.zeros(n)
        self._kpi, self._kpd = np.zeros(n), np.zeros(n)
        self._pid = False
        """Whether any joint's Position I or D Gain is set (else the loop is P alone)."""
        self._sum = np.zeros(n)
        """The position loop's summed error (rad·periods), for Position I Gain."""
        self._volts = np.zeros(n)
        self._volts_seen: list[float] = []
        self._desired, self._desired_v = np.zeros(n), np.zeros(n)
        self._integral, self._torque = np.zeros(n), np.zeros(n)
        self._position = np.zeros(n, dtype=bool)
        self._velocity = np.zeros(n, dtype=bool)
        self._finite = np.zeros(n, dtype=bool)
        self._position_f, self._on_f = np.zeros(n), np.zeros(n)
        self._amax_finite = np.ones(n)
        self._ramped = False
        self._drive_gain, self._emf_gain = np.zeros(n), np.zeros(n)
        self.q: list[float] = [0.0] * n
        """The joints' angles, rad, in :attr:`joints` order."""
        # What the servos are told, in their units (ticks, ticks/s, ticks/s²).
        self.position_ticks: list[float] = [0.0] * n
        self.velocity_ticks: list[float] = [0.0] * n
        self.accel_ticks: list[float] = [0.0] * n
        chain.load_model = self._current
        self._base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base")
        self._imu_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "imu")
        self._wheel_geoms = [
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{leg}_wheel") for leg in LEG_NAMES
        ]
        self._wheel_of = {g: leg for leg, g in enumerate(self._wheel_geoms)}
        self._wheel_geom_index = np.array(self._wheel_geoms)
        self.wheel_friction = model.geom_friction[self._wheel_geom_index, 0].copy()
        """Each wheel's static friction on the ground, RF…LR (the spread of real parts sets
        it, :mod:`whexar.sim.spread`); a rolling wheel grips with a share of it."""
        self._wheel_dofs = [
            int(
                model.jnt_dofadr[
                    mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{leg}_wheel")
                ]
            )
            for leg in LEG_NAMES
        ]
        self._wrench = np.zeros(6)
        self._ray_geom = np.zeros(1, dtype=np.int32)
        self._ir_sites = [
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
            for name in ("ir_right", "ir_left")
        ]
        # Rays see the terrain, not the robot: its geoms go to a group the rays skip.
        robot = {b for b in range(model.nbody) if model.body_rootid[b] == self._base}
        for g in range(model.ngeom):
            if int(model.geom_bodyid[g]) in robot:
                model.geom_group[g] = ROBOT_GEOM_GROUP
        self._ray_groups = np.ones(6, dtype=np.uint8)
        self._ray_groups[ROBOT_GEOM_GROUP] = 0
        self.dead_fsr: set[int] = set()
        """Legs whose force sensor reads 0 (a sensor fault, :mod:`whexar.sim.faults`)."""
        self.dead_ir: set[int] = set()
        """Rangefinders (0 right, 1 left) that read 0 counts: no reading."""
        self.fsr_counts: list[int] = [0] * 6
        self.contact_forces: list[float] = [0.0] * 6
        """Each leg's wheel's normal force on the ground (N), as the force sensors see it."""
        self.ir_counts: list[int] = [0, 0]
        self.sense_hook: Callable[[SimWorld], None] | None = None
        """Called after every refresh of the sensors: the parts' spread reads them
        (:mod:`whexar.sim.spread`)."""
        self.dead_zone_rad: np.ndarray | None = None
        """Each joint's half backlash, the gears' play either way (``None``: none); see
        :meth:`_through_the_play`."""
        self._play = np.zeros(n)
        """Where the motor's side of the gears sits in the play, relative to the horn."""
        # Physical faults (whexar.sim.faults), each held under its caller's key.
        self._pushes: dict[Hashable, np.ndarray] = {}
        self._patches: dict[Hashable, Patch] = {}
        self._limp: dict[Hashable, tuple[int, ...]] = {}
        self._snags: dict[Hashable, int] = {}
        self._free_limits: dict[int, tuple[int, np.ndarray]] = {}
        """A snagged joint's (limited, range) before its snag, by MuJoCo joint id."""
        self.unpowered: frozenset[int] = frozenset()
        """Servos without power (a limp fault), by ID."""
        self._wheel_slot = np.full(model.ngeom, -1)
        self._wheel_slot[self._wheel_geom_index] = np.arange(len(self._wheel_geoms))
        """Each geom's leg if it is a wheel, else −1: which wheel a contact is of."""
        if board is not None:
            board.script = self._board_inputs
        mujoco.mj_forward(model, self.data)
        self._sync_servos()
        self._feed_servos()

    # ----------------------------------------------------------------- state

    def set_pose(
        self,
        angles: Mapping[tuple[int, int], float],
        *,
        base_xyz: tuple[float, float, float] = (0.0, 0.0, 0.3),
        base_quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
    ) -> None:
        """Place the robot: joint angles by (leg, joint) in rad, the base pose; at rest."""
        d = self.data
        d.qpos[0:3] = base_xyz
        d.qpos[3:7] = base_quat
        d.qvel[:] = 0.0
        for j in self.joints:
            d.qpos[j.qadr] = angles.get((j.leg, j.joint), 0.0)
        mujoco.mj_forward(self.model, d)
        self._sync_servos()
        self._sense()

    def _sync_servos(self) -> None:
        d = self.data
        self._desired = d.qpos[self._qadr].copy()
        self._desired_v = np.zeros(len(self.joints))
        self._read_joints(d.qpos[self._qadr], d.qvel[self._dadr], np.zeros(len(self.joints)))
        for j in self.joints:
            j.servo.set_state(self.position_ticks[j.index], 0.0)

    def _read_joints(self, q: np.ndarray, w: np.ndarray, accel: np.ndarray) -> None:
        self.q = q.tolist()
        self.position_ticks = (q * TICKS_PER_RAD + ct.CENTER_TICKS).tolist()
        self.velocity_ticks = (w * TICKS_PER_RAD).tolist()
        self.accel_ticks = (accel * TICKS_PER_RAD).tolist()

    def move_servos(self, t: float) -> None:
        """The chain's :attr:`~whexar.bus.emulator.chain.ServoChain.mover`: step the world
        to bus time ``t``, then hand every servo its joint's state."""
        self.advance_to(t)
        for servo, position, velocity, accel in zip(
            self._servos, self.position_ticks, self.velocity_ticks, self.accel_ticks, strict=True
        ):
            servo.follow(t, position, velocity, accel)
        for servo in self._others:
            servo.advance(t)

    # ----------------------------------------------------------------- stepping

    def advance_to(self, t: float) -> None:
        """Step the physics until the next step would pass bus time ``t``."""
        if self.time + self.h > t + 1e-12:
            return
        if self.diverged_at is not None:
            self._hold(t)
            return
        self._orders()
        m, d, h = self.model, self.data, self.h
        if self.tilt is not None:  # a board raised by degrees a second: per transaction
            m.opt.gravity[:] = self.tilt.gravity(self.time, self._g)
        self._grip()
        qadr, dadr, act = self._qadr, self._dadr, self._act
        start, w0 = self.time, d.qvel[dadr].copy()  # a view when dadr is a slice
        held = d.qpos.copy()  # where a diverged step goes back to
        bad_q, bad_v, bad_a = self._instabilities  # live views of MuJoCo's counters
        bridge_c = 0.0
        while self.time + h <= t + 1e-12:
            d.ctrl[act] = tau = self._control(d.qpos[qadr], d.qvel[dadr])
            if self._gear is not None:
                self._gear_friction(tau)
            # The bridges' net draw of this step; a net surplus is lost (power module).
            bridge_c += max(0.0, self._bridge_a) * h
            mujoco.mj_step(m, d)
            self.steps += 1
            self.time = self.steps * h
            if bad_q.number or bad_v.number or bad_a.number:
                self._diverged(held)
                self._hold(t)
                return
        self._draw(bridge_c, self.time - start)
        w1 = d.qvel[dadr]
        self._amps = (self._torque / self._kt / self._load_scale).tolist()
        # The mean acceleration since the last transaction: what the servo's Moving and
        # profile registers are told (no register reports acceleration itself).
        self._read_joints(d.qpos[qadr], w1, (w1 - w0) / (self.time - start))
        if self.time - self._sensed_at >= SENSE_PERIOD_S - 1e-12:
            self._sense()

    def _diverged(self, held: np.ndarray) -> None:
        """MuJoCo found the state non-finite or huge at this step: the world goes back to
        ``held`` (qpos at the transaction's start), at rest, and says when and what."""
        d = self.data
        w, stat = next(
            (w, s) for w, s in zip(_INSTABILITIES, self._instabilities, strict=True) if s.number
        )
        self.diverged_at = self.time
        self.divergence = mujoco.mju_warningText(w, stat.lastinfo)
        d.qpos[:] = held
        d.qvel[:] = 0.0
        d.qacc[:] = 0.0
        d.qacc_warmstart[:] = 0.0
        mujoco.mj_forward(self.model, d)

    def _hold(self, t: float) -> None:
        """A diverged world to bus time ``t``: the clock goes on, nothing moves; the servos
        read their joints still, the sensors the pose held."""
        while self.time + self.h <= t + 1e-12:
            self.steps += 1
            self.time = self.steps * self.h
        still = np.zeros(len(self.joints))
        self._read_joints(self.data.qpos[self._qadr], still, still)
        if self.time - self._sensed_at >= SENSE_PERIOD_S - 1e-12:
            self._sense()

    def _gear_friction(self, tau: np.ndarray) -> None:
        """Each joint's friction budget for the coming step (BAM's m6, as its MuJoCo
        controller sets it: bam/mujoco.py), from the motor's torque ``tau`` and the
        external torque on the joint at the last step: gravity, inertia and the
        constraints (contacts, limits), less the joint's own friction."""
        d, g, dofs = self.data, self._gear, self._dofs
        assert g is not None
        ne = d.nefc
        own = self._own_friction
        own[:] = 0.0
        if ne:
            rows = d.efc_type[:ne] == _FRICTION_DOF
            np.add.at(own, d.efc_id[:ne][rows], d.efc_force[:ne][rows])
        ext = d.qfrc_constraint[dofs] - d.qfrc_bias[dofs] - own[dofs]
        w = d.qvel[dofs]
        load = np.abs(ext * g.load_friction_external - tau * g.load_friction_motor)
        load_rest = np.abs(
            ext * g.load_friction_external_stribeck - tau * g.load_friction_motor_stribeck
        )
        rest = np.exp(-(np.abs(w * g.inv_speed) ** g.alpha))
        quad = np.where(
            np.abs(ext) < np.abs(tau),
            g.load_friction_external_quad * ext * ext,
            g.load_friction_motor_quad * tau * tau,
        ) * (np.sign(ext) != np.sign(tau))
        budget = g.coulomb + load + rest * (g.friction_stribeck + load_rest + quad)
        self.model.dof_frictionloss[dofs] = np.where(g.has, budget, g.coulomb)

    def _grip(self) -> None:
        """A rolling wheel grips less than a still one (:data:`~whexar.sim.terrain.
        ROLLING_TRACTION`): each wheel's friction for the coming steps, from its speed and
        the ground it is on (:meth:`slip`).

        The wheels' geoms have the higher priority (:mod:`whexar.sim.model`), so a
        wheel's contacts take its geom's friction whatever they touch: setting it is
        setting the friction of that wheel's contacts."""
        rolling = np.abs(self.data.qvel[self._wheel_dofs]) > ROLLING_RAD_S
        still = self.wheel_friction
        if self._patches:  # the patch's µ, scaled by this tyre's spread as the floor's is
            still = still * self._ground_factor()
        self.model.geom_friction[self._wheel_geom_index, 0] = np.where(
            rolling, still * _ROLLING_SHARE, still
        )

    def _orders(self) -> None:
        """Every servo's orders as arrays, read again only where a write made a new drive."""
        servos = self._servos
        # The supply (a brownout fault changes it without a write).
        volts = [s.input_voltage_v for s in servos]
        changed = volts != self._volts_seen
        if changed:
            self._volts_seen = volts
            self._volts = np.array(volts)
        drives = [s.drive for s in servos]
        seen = self._drives
        if any(map(is_not, drives, seen)):
            # Per joint in Python lists (a numpy element costs more than a list item),
            # then the arrays at once.
            on, velocity, goal, vmax, amax = self._orders_now
            for k, drive in enumerate(drives):
                if drive is seen[k]:
                    continue
                velocity_mode = drive.mode == VELOCITY_MODE
                ramp = drive.max_acceleration / TICKS_PER_RAD
                if on[k] != drive.torque or velocity[k] != velocity_mode or amax[k] != ramp:
                    changed = True  # the masks change, not only a goal
                on[k] = drive.torque
                velocity[k] = velocity_mode
                goal[k] = (
                    drive.goal_velocity / TICKS_PER_RAD
                    if velocity_mode
                    else (drive.goal_position - ct.CENTER_TICKS) / TICKS_PER_RAD
                )
                vmax[k] = drive.max_velocity / TICKS_PER_RAD
                amax[k] = ramp
                self._read_gains(self.joints[k])
                if not drive.torque:
                    self._integral[k] = 0.0
                    self._sum[k] = 0.0
            self._drives = drives
            self._goal, self._vmax = np.array(goal), np.array(vmax)
            if changed:
                self._on = np.array(on, dtype=bool)
                self._velocity_mode = np.array(velocity, dtype=bool)
                self._amax = np.array(amax)
        if changed:
            # What the per-step law needs, derived again when torque, mode, profile
            # acceleration or supply changed (a new goal changes none of them).
            torque, vel = self._on, self._velocity_mode
            self._position = torque & ~vel
            self._position_f = self._position.astype(float)
            self._velocity = torque & vel
            self._on_f = torque.astype(float)
            self._finite = np.isfinite(self._amax) & self._position
            self._ramped = bool(self._finite.any())
            self._amax_finite = np.where(self._finite, self._amax, 1.0)
            self._drive_gain = self._kt * self._volts / self._resistance
            self._emf_gain = self._kt * self._kt / self._resistance

    def _read_gains(self, j: _Joint) -> None:
        """The joint's gains, read from the table as the firmware does, when they changed
        (a new drive is mostly a new goal)."""
        table = j.servo.table
        raw = bytes(table[_GAINS_SPAN])
        if raw == j.gains_raw:
            return
        j.gains_raw = raw
        k = j.index
        reg = j.servo.model.register
        self._kp[k] = position_duty_per_rad(reg("position_p_gain").decode(table))
        self._kvp[k] = reg("velocity_p_gain").decode(table) / KVP_DIVISOR
        self._kvi[k] = reg("velocity_i_gain").decode(table) / KVI_DIVISOR
        self._kpi[k], self._kpd[k] = position_id_duty(
            reg("position_i_gain").decode(table), reg("position_d_gain").decode(table)
        )
        self._pid = bool(self._kpi.any() or self._kpd.any())

    def _control(self, q: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The firmware and the motor of every servo for one step: the joints' torques.

        Written for numpy's per-call cost (about a microsecond an operation, 42 joints):
        the masks and constants come from :meth:`_orders`, once per drive change."""
        h = self.h
        # Position modes: the firmware's profile runs the desired position toward the goal
        # at the profile's velocity, ramping at its acceleration (a step when that is 0).
        gap = self._goal - self._desired
        vmax = self._vmax
        v = np.minimum(np.maximum(gap * (1.0 / h), -vmax), vmax)
        if self._ramped:
            amax, v0 = self._amax_finite, self._desired_v
            stop = v0 * v0 / (2 * amax)
            want = np.where(np.abs(gap) > stop, np.copysign(vmax, gap), 0.0)
            ramped = v0 + np.minimum(np.maximum(want - v0, -amax * h), amax * h)
            ramped = np.where(np.abs(ramped * h) > np.abs(gap), gap / h, ramped)
            v = np.where(self._finite, ramped, v)
        position = self._position_f  # 1.0 where a position mode drives, else 0.0
        v = v * position
        self._desired_v = v
        self._desired = np.where(self._position, self._desired + v * h, q)
        # Velocity mode (the wheels): PI on the error in velocity units (e-manual).
        error = (self._goal - w) * (1.0 / VELOCITY_UNIT_RAD_S)
        stepped = self._integral + error * (h / CONTROL_PERIOD_S)
        duty_velocity = (self._kvp * error + self._kvi * stepped) * (1.0 / PWM_LIMIT)
        free = self._velocity & (np.abs(duty_velocity) < MAX_DUTY)  # no wind-up saturated
        self._integral = np.where(free, stepped, self._integral)
        lag = self._desired - q
        duty_position = self._kp * lag
        if self._pid:  # Position I and D Gain (e-manual's PID; 0 unless configured)
            summed = self._sum + lag * (h / CONTROL_PERIOD_S)
            duty_position = duty_position + self._kpi * summed + self._kpd * (v - w)
            # No wind-up while saturated, as the velocity loop above.
            free = self._position & (np.abs(duty_position) < MAX_DUTY)
            self._sum = np.where(free, summed, self._sum)
        duty = np.where(self._velocity_mode, duty_velocity, duty_position)
        duty = np.minimum(np.maximum(duty, -MAX_DUTY), MAX_DUTY)
        # BAM's motor: τ = kt·V/R − kt²·ω/R at the output shaft; torque off: coasting.
        tau: np.ndarray = (duty * self._drive_gain - self._emf_gain * w) * self._on_f
        if self.dead_zone_rad is not None:  # gear backlash (whexar.sim.spread)
            tau = self._through_the_play(tau, duty, w, self.dead_zone_rad)
        self._torque = tau
        # What the bridges take from the line: duty × winding current (0 with torque off).
        self._bridge_a = float(np.dot(duty, tau / self._kt))
        return tau

    def _through_the_play(
        self, tau: np.ndarray, duty: np.ndarray, w: np.ndarray, half: np.ndarray
    ) -> np.ndarray:
        """The torque that reaches the horns through the gears' play (:func:`gear_play`)."""
        free = duty * self._drive_gain / self._emf_gain  # the unloaded speed at this duty
        out, self._play = gear_play(tau, free, w, self._play, half, self.h)
        return out

    def _draw(self, bridge_c: float, elapsed: float) -> None:
        """Take the line's current over ``elapsed`` s from the supply; feed its voltage on."""
        if elapsed <= 0.0:
            return
        supply = self.supply
        powered = len(self.chain.servos) - len(self.unpowered)
        self.supply_a = supply_amps(bridge_c / elapsed, powered, supply.terminal_volts)
        supply.draw(self.supply_a, elapsed)
        self._feed_servos()

    def _feed_servos(self) -> None:
        """Every servo on the line sees the battery's voltage (a bench supply's is left
        alone: the servos start at 12 V, and a voltage-sag fault sets its own)."""
        if isinstance(self.supply, BenchSupply):
            return
        volts = self.supply.terminal_volts
        for servo in self.chain.servos.values():
            servo.input_voltage_v = volts

    def _current(self, servo: ServoView, t: float) -> float:
        """Present Current (A), or for the MX-28 its Present Load as a fraction of stall."""
        return self._amps[self._index_of[servo]]

    # ----------------------------------------------------------------- physical faults
    # Each takes the caller's key and what the fault does, or None to end what that key
    # began; faults of different keys overlap (pushes add up, the latest patch wins).

    def push(self, key: Hashable, force_n: Sequence[float] | None) -> None:
        """Push the body at its centre of mass with ``force_n`` (x, y, z in the world's
        frame, N) until ``push(key, None)``.

        MuJoCo applies ``xfrc_applied`` at the body's centre of mass and keeps it across
        steps (``mj_xfrcAccumulate``, engine_support.c)."""
        if force_n is None:
            self._pushes.pop(key, None)
        else:
            self._pushes[key] = np.asarray(force_n, dtype=float)
        total = np.zeros(3)
        for force in self._pushes.values():
            total += force
        self.data.xfrc_applied[self._base, :3] = total

    def slip(self, key: Hashable, patch: Patch | None) -> None:
        """Lay ``patch`` on the ground until ``slip(key, None)``: from the next step on, a
        wheel it covers grips with the patch's µ instead of the floor's.

        Per wheel, not per contact: MuJoCo sets a contact's friction from its geoms when it
        makes it, and offers no hook between, so the world sets each wheel's geom friction
        before it steps (:meth:`_grip`) from where its contact was at the step before. A
        wheel's own spread (:mod:`whexar.sim.spread`) scales the patch's µ as it scales
        the floor's; a rolling wheel grips with :data:`_ROLLING_SHARE` of it. Only the
        wheels meet a patch: a leg or the body dragged on the ground keeps the floor's."""
        self._patches.pop(key, None)
        if patch is not None:
            self._patches[key] = patch  # last: the latest patch lies on top

    def limp(self, key: Hashable, servo_ids: Sequence[int] | None, t: float) -> None:
        """Cut the power of servos ``servo_ids`` at bus time ``t`` until ``limp(key, None,
        t)``, when each boots as at power-up (torque off until the bus enables it).

        Unpowered, a servo hears and answers nothing and its motor makes no torque: the
        joint moves as the load moves it, against the gears' friction alone (the torque-off
        case of the servo law, :meth:`_control`)."""
        before = self.unpowered
        if servo_ids is None:
            self._limp.pop(key, None)
        else:
            self._limp[key] = tuple(servo_ids)
        self.unpowered = frozenset(sid for ids in self._limp.values() for sid in ids)
        for sid in sorted(self.unpowered - before):
            self.chain.servos[sid].power_off(t)
        for sid in sorted(before - self.unpowered):
            self.chain.servos[sid].power_on(t)

    def snag(self, key: Hashable, joint: int | None) -> None:
        """Hold joint ``joint`` (its index in :attr:`joints`) at its angle now, until
        ``snag(key, None)`` frees it: a leg caught on something.

        The hold is the joint's limit narrowed to that angle (MuJoCo builds limit
        constraints from ``jnt_limited`` and ``jnt_range`` every step), so the joint stays
        whatever its servo does; the servo, finding its error grow, drives into it up to
        its duty's limit, and its current rises as against any stall."""
        if joint is None:
            held = self._snags.pop(key, None)
            if held is not None and held not in self._snags.values():
                self._free(held)
            return
        self._snags[key] = joint
        jid = int(self.model.dof_jntid[self.joints[joint].dadr])
        if jid in self._free_limits:
            return  # held already: the first hold stands
        m = self.model
        self._free_limits[jid] = (int(m.jnt_limited[jid]), m.jnt_range[jid].copy())
        q = float(self.data.qpos[self.joints[joint].qadr])
        m.jnt_range[jid] = (q, q)
        m.jnt_limited[jid] = 1

    def _free(self, joint: int) -> None:
        """Give joint ``joint`` its own limits back."""
        jid = int(self.model.dof_jntid[self.joints[joint].dadr])
        limited, span = self._free_limits.pop(jid)
        self.model.jnt_limited[jid] = limited
        self.model.jnt_range[jid] = span

    def _ground_factor(self) -> np.ndarray:
        """The ground under each wheel as a factor on the floor's µ
        (:data:`~whexar.sim.terrain.GROUND_FRICTION`): the latest patch's that covers it,
        else 1."""
        xy = self._wheel_xy()
        factor = np.ones(len(self._wheel_geoms))
        for patch in self._patches.values():  # in the order they began: the latest wins
            factor[patch.covers(xy)] = patch.friction / GROUND_FRICTION[0]
        return factor

    def _wheel_xy(self) -> np.ndarray:
        """Where each wheel touches the ground (x, y), m: its contact's point at the last
        step, or the point under its centre when it touches nothing."""
        d = self.data
        xy: np.ndarray = d.geom_xpos[self._wheel_geom_index, :2].copy()
        n = d.ncon
        if n:
            slot = self._wheel_slot[d.contact.geom[:n]].max(axis=1)
            mine = slot >= 0
            xy[slot[mine]] = d.contact.pos[:n][mine, :2]
        return xy

    # ----------------------------------------------------------------- sensors

    def _sense(self) -> None:
        self._sensed_at = self.time
        m, d = self.model, self.data
        forces = [0.0] * 6
        wrench = self._wrench
        wheels = self._wheel_of
        for k in range(d.ncon):
            c = d.contact[k]
            leg = wheels.get(int(c.geom1), wheels.get(int(c.geom2)))
            if leg is None:
                continue
            mujoco.mj_contactForce(m, d, k, wrench)
            forces[leg] += abs(float(wrench[0]))  # the normal force, in the contact frame
        self.contact_forces = forces
        self.fsr_counts = [0 if i in self.dead_fsr else fsr_counts(f) for i, f in enumerate(forces)]
        geom = self._ray_geom
        ir = self.cfg.ir
        counts = []
        for site in self._ir_sites:
            pos = d.site_xpos[site]
            direction = d.site_xmat[site].reshape(3, 3)[:, 2]
            dist = mujoco.mj_ray(m, d, pos, direction, self._ray_groups, 1, -1, geom)
            far = ir.max_distance_mm / 1000
            if dist < 0 or dist > far:
                dist = far * 1.5  # nothing in range: the sensor's low floor
            counts.append(
                counts_for_distance(max(dist, ir.min_distance_mm / 1000), ir.k_cm, ir.exponent)
            )
        self.ir_counts = [0 if i in self.dead_ir else c for i, c in enumerate(counts)]
        if self.imu is not None or self.board is not None:
            # The chip's filter: the mean acceleration since the last reading (the change of
            # velocity over the period), not one step's contact spikes, which a sample
            # every 20 ms would alias into tilt.
            vel = np.zeros(6)
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, self._imu_site, vel, 0)
            span = self.time - self._imu_t
            mean = (vel[3:] - self._imu_v) / span if span > 0 else np.zeros(3)
            self._imu_v, self._imu_t = vel[3:].copy(), self.time
            rot = d.site_xmat[self._imu_site].reshape(3, 3)
            force = rot.T @ (mean - m.opt.gravity)  # specific force in the sensor's frame
            gyro = rot.T @ vel[:3]
            fx, fy, fz = (float(a) / STANDARD_G for a in force)
            wx, wy, wz = (math.degrees(float(w)) for w in gyro)
            # Mounted with its x axis to the body's left, y to the rear (module docstring).
            self.accel_g = (fy, -fx, fz)
            if self.imu is not None:
                # The chip the configuration was calibrated for: it reads its own zero-g
                # and zero-rate levels on top, which the reader takes off again.
                (ox, oy, oz), (gx, gy, gz) = self._imu_levels
                ax, ay, az = self.accel_g
                self.imu.accel_g = (ax + ox, ay + oy, az + oz)
                self.imu.gyro_dps = (wy + gx, -wx + gy, wz + gz)
        if self.sense_hook is not None:
            self.sense_hook(self)

    def _board_inputs(self, board_t: float) -> dict[str, int]:
        counts = dict(zip(FSR_KEYS, self.fsr_counts, strict=True))
        counts.update(zip(IR_KEYS, self.ir_counts, strict=True))
        if self.board is not None and self.board.accelerometer:
            # The board's analog accelerometer, mounted as the IMU (the same axes).
            acc = self.cfg.sensor_board.accelerometer
            raw = counts_for_acceleration(self.accel_g, acc.zero_g_counts, acc.counts_per_g)
            counts.update(zip(ACC_KEYS, raw, strict=True))
        return counts

    # ----------------------------------------------------------------- read-outs

    @property
    def base_position(self) -> tuple[float, float, float]:
        """The body centre in the world, m."""
        x, y, z = (float(v) for v in self.data.qpos[0:3])
        return x, y, z

    @property
    def base_quat(self) -> tuple[float, float, float, float]:
        """The body's orientation (w, x, y, z)."""
        w, x, y, z = (float(v) for v in self.data.qpos[3:7])
        return w, x, y, z

    def electric_power(self) -> float:
        """Σ V·|I| over the servos, W, I the winding current: the motors' power were each
        at full duty (the supply's is :attr:`supply_a` × the line's voltage)."""
        return float(np.sum(np.abs(self._torque / self._kt) * self._volts))

    def winding_current(self) -> float:
        """Σ |τ/kt| over the servos now, A: the winding currents Present Current reports."""
        return float(np.sum(np.abs(self._torque / self._kt)))

    def supply_summary(self) -> dict[str, float | None]:
        """The supply over the run: charge and energy drawn, its state of charge."""
        supply = self.supply
        soc = supply.state_of_charge
        empty = getattr(supply, "empty_at_s", None)
        return {
            "supply_charge_ah": supply.drawn_c / 3600.0,
            "supply_energy_j": supply.energy_j,
            "battery_state_of_charge": soc,
            "battery_empty_at_s": empty,
        }

    def state_hash(self) -> str:
        """A hash of the world's full state: equal runs give equal hashes, bit for bit."""
        h = hashlib.sha256()
        for array in (self.data.qpos, self.data.qvel, self.data.act):
            h.update(np.ascontiguousarray(array).tobytes())
        h.update(repr(self.time).encode())
        return h.hexdigest()


def _index(addresses: list[int]) -> slice | np.ndarray:
    """``addresses`` as a slice when they run on without a gap (a view, cheaper than an
    index array at every step), else as an index array."""
    first = addresses[0]
    if addresses == list(range(first, first + len(addresses))):
        return slice(first, first + len(addresses))
    return np.array(addresses)


ROBOT_GEOM_GROUP: Final = 3
"""The geom group the robot's own geoms are moved to, so that rays skip them."""

__all__ = ["SENSE_PERIOD_S", "Patch", "SimWorld", "fsr_counts", "gear_play"]
