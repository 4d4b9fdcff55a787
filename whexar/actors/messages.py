"""The robot's messages: the servo bus and the sensors, small, immutable, typed values.

Every message derives from :class:`~whexar.runtime.messages.Message` (``t``,
the time it is valid for, and ``source``, the actor that made it) and is
registered by :func:`~whexar.runtime.messages.message` under its class name,
which is how wiring configuration refers to it. Events (what went wrong or
changed on a device) derive from :class:`~whexar.runtime.messages.Event` and
travel on the runtime's ``events`` channel. Why frozen dataclasses and not
pydantic models is told in :mod:`whexar.runtime.messages`.
"""

from __future__ import annotations

from typing import NamedTuple

from whexar.runtime.messages import Event, Message, message

# --------------------------------------------------------------------------- servo bus
# Joints are addressed by (leg, joint) indices (whexar.robot): the bus
# scheduler alone knows which servo ID drives which joint.


@message
class JointGoal(Message):
    """A goal for joint ``joint`` of leg ``leg``: a position (rad) or, for the wheel, a speed."""

    leg: int
    joint: int
    position_rad: float | None = None
    velocity_rad_s: float | None = None


@message
class JointGoals(Message):
    """Goals for any set of joints; the latest goal per joint wins at the next bus cycle.

    ``reflex`` marks an override from a reflex actor: in a cycle where both
    arrive for the same joint, a reflex goal wins over any other, whatever
    their order (among reflex goals the latest wins). A joint no reflex
    touched keeps the rule "latest wins". Leg actors may therefore send their
    goals every cycle without undoing a reflex that fired in the same cycle.
    """

    goals: tuple[JointGoal, ...]
    reflex: bool = False


class JointState(NamedTuple):
    """What one servo reported in a bus cycle; ``None`` where the plan did not read it.

    ``alert`` is the status packet's Alert bit: Hardware Error Status is set.
    A named tuple, not a message: 42 of them ride in every :class:`ServoStates`
    (which carries the time), and a tuple is made five times faster than a
    frozen dataclass (0.36 µs against 1.96 µs, measured here).
    """

    leg: int
    joint: int
    servo_id: int
    position_rad: float | None = None
    velocity_rad_s: float | None = None
    current_a: float | None = None
    alert: bool = False


@message
class ServoStates(Message):
    """Every joint read in bus cycle ``cycle``, valid at ``t`` (the read's time)."""

    cycle: int
    joints: tuple[JointState, ...]


@message
class ServoHealth(Message):
    """A slow-rate reading of one servo: input voltage, temperature, hardware error bits."""

    servo_id: int
    voltage_v: float | None = None
    temperature_c: float | None = None
    hardware_error: int | None = None


@message
class BusStats(Message):
    """Counters of the servo bus since the scheduler started, and the recent cycle rate."""

    cycles: int
    rate_hz: float
    bytes_per_cycle: float
    read_mode: str
    retries: int
    timeouts: int
    corrupt: int
    clamped: int
    degraded: tuple[int, ...]
    write_failures: int = 0
    """Sync Writes the port failed to send (their goals went out again next cycle)."""


@message
class GoalClamped(Event):
    """A goal beyond a limit was clamped to ``sent_rad`` before it reached the wire.

    A position beyond the joint's limits (rad), or a wheel speed beyond the
    servo's Velocity Limit (``unit = "rad/s"``); a start-up goal too, when a
    servo stands outside its joint's limits.
    """

    servo_id: int
    requested_rad: float
    sent_rad: float
    unit: str = "rad"


@message
class GoalRefused(Event):
    """A goal that cannot be a command was dropped; the joint keeps its previous goal.

    ``reason`` says why: not a finite number, absurdly far beyond the limits,
    a position for a wheel or a speed for a positioned joint, a joint the
    robot does not have.
    """

    leg: int
    joint: int
    reason: str


@message
class HardwareWarning(Event):
    """Servo ``servo_id`` set (``active``) or cleared a Hardware Error Status bit that does not
    latch: one outside its Shutdown mask (input voltage, by default). Torque stays on; no
    reboot."""

    servo_id: int
    bits: int
    description: str
    active: bool


@message
class SupplyLow(Event):
    """Servos report an input-voltage error: the supply is outside their limits (a brownout)."""

    servo_ids: tuple[int, ...]


@message
class SupplyRestored(Event):
    """No servo reports an input-voltage error any more."""


@message
class WriteFailed(Event):
    """A Sync Write of ``register`` to ``servos`` servos did not go out (``result``); its goals
    are sent again in the next cycle."""

    register: str
    servos: int
    result: str


@message
class WatchdogStopped(Event):
    """At start-up, servos were found stopped by their Bus Watchdog: the host before this one
    stopped talking without a stop (a crash, a kill, a pulled cable). Cleared."""

    servo_ids: tuple[int, ...]


@message
class ReadModeChanged(Event):
    """The scheduler reads with ``mode`` ("fast_sync_read" or "sync_read") from now on."""

    mode: str
    reason: str


@message
class ServoFault(Event):
    """A transaction with servo ``servo_id`` failed (``kind``: timeout, corrupt, error…)."""

    servo_id: int
    kind: str
    consecutive: int


@message
class ServoDegraded(Event):
    """Servo ``servo_id`` keeps failing: it is left out of the cycle and probed instead."""

    servo_id: int
    reason: str


@message
class ServoRecovered(Event):
    """A degraded servo answers again and is back in the cycle, settings restored."""

    servo_id: int


@message
class HardwareFault(Event):
    """Servo ``servo_id`` reports Hardware Error Status ``bits`` (``description`` in words)."""

    servo_id: int
    bits: int
    description: str


@message
class ServoRebooted(Event):
    """Servo ``servo_id`` was rebooted to clear a hardware error (``ok``: it answered)."""

    servo_id: int
    ok: bool


@message
class ServoRestored(Event):
    """Servo ``servo_id``'s settings were written again and its torque re-enabled."""

    servo_id: int


@message
class BusWarning(Event):
    """Something about the bus set-up that costs performance, and how to fix it."""

    message: str


@message
class BusLost(Event):
    """The bus can no longer drive the robot (port gone, a critical servo lost)."""

    reason: str


# --------------------------------------------------------------------------- sensors
# The sensor board (ATmega2560, firmware/PROTOCOL.md) and the IMU. Every
# message carries the frame's or sample's sequence number; ``t`` is when it
# was received (the runtime clock), which is when it is valid to within one
# sample period.


@message
class SensorFrame(Message):
    """One decoded frame of the sensor board: raw counts and their conversions.

    A group the frame did not carry is ``None``. ``seq`` is ``None`` for a
    plain thesis frame. ``missed`` counts frames lost just before this one.
    Distances are as in :class:`ObstacleRanges`: metres, ``math.inf`` when
    nothing is within range, ``None`` for a sensor that gives no reading.
    Tilt angles are radians (eq. 5.6–5.7), ``None`` when the frame carries no
    accelerometer, the configuration says none is fitted
    (``sensor_board.accelerometer.fitted``) or its reading is not gravity
    (:class:`AccelImplausible`).
    """

    seq: int | None
    ir_counts: tuple[int, int] | None
    ir_distances_m: tuple[float | None, float | None] | None
    fsr_counts: tuple[int, int, int, int, int, int] | None
    contacts: tuple[bool, bool, bool, bool, bool, bool] | None
    acc_counts: tuple[int, int, int] | None
    roll_rad: float | None
    pitch_rad: float | None
    missed: int = 0


@message
class ObstacleRanges(Message):
    """Distances (m) seen by the IR rangefinders on the right and left front legs (eq. 5.5).

    Per sensor: a distance in metres; ``math.inf``: nothing within
    ``ir.max_distance_mm`` (the sensor answers, with a low voltage); ``None``:
    no reading — the input is at 0 counts, 0 V, which a working rangefinder
    never outputs (it gives about 0.4 V with nothing in range), so the sensor
    is unplugged or unpowered and the space in front of it is unknown, not
    free. Nearer than ``ir.min_distance_mm`` reads as that minimum (the
    sensor's output folds back below its nearest calibrated distance, 5.3.5).
    """

    seq: int | None
    counts: tuple[int, int]
    distances_m: tuple[float | None, float | None]


@message
class LegLoads(Message):
    """The force sensor of each leg (raw ADC counts, 5.3.3) and its contact flag (hysteresis)."""

    seq: int | None
    counts: tuple[int, int, int, int, int, int]
    contacts: tuple[bool, bool, bool, bool, bool, bool]


@message
class BodyTilt(Message):
    """Body roll and pitch (rad) from a static acceleration (eq. 5.6–5.7).

    ``sensor`` says which accelerometer: ``"board"`` (the sensor board's
    analog one) or ``"imu"`` (the LSM9DS1); ``accel_g`` is the reading in g
    that gave the angles. Only a reading whose magnitude is within the
    sensor's ``gravity_tolerance_g`` of 1 g gives a tilt
    (:mod:`whexar.sensors.gravity`); others are :class:`AccelImplausible`.
    """

    seq: int | None
    sensor: str
    roll_rad: float
    pitch_rad: float
    accel_g: tuple[float, float, float]


@message
class ImuSample(Message):
    """One reading of the IMU: acceleration (g) and angular rate (deg/s) in its own axes."""

    seq: int
    accel_g: tuple[float, float, float]
    gyro_dps: tuple[float, float, float]


@message
class SensorStats(Message):
    """Counters of a sensor link since its reader started."""

    link: str
    frames: int
    rejected: int
    missed: int
    unknown_keys: int
    garbage_bytes: int
    reconnects: int


@message
class SensorLinkUp(Event):
    """The sensor link ``link`` (a serial port, an I²C device) is open."""

    link: str


@message
class SensorLinkDown(Event):
    """The sensor link ``link`` went away (``reason``); the reader keeps trying to reopen it."""

    link: str
    reason: str


@message
class SensorLinkStale(Event):
    """No valid data on ``link`` for ``silent_s``; readings are old from now on."""

    link: str
    silent_s: float
    last_seq: int | None


@message
class SensorLinkFresh(Event):
    """Valid data on ``link`` again after it was stale for ``silent_s``."""

    link: str
    silent_s: float


@message
class SensorFrameGap(Event):
    """Frames were lost on ``link``: ``missed`` before ``seq`` (``restarted``: the board reset)."""

    link: str
    expected: int
    seq: int
    missed: int
    restarted: bool


@message
class SensorFrameRejected(Event):
    """A frame on ``link`` was discarded (``reason``); ``excerpt`` shows its start, escaped."""

    link: str
    reason: str
    size: int
    excerpt: str


@message
class AccelImplausible(Event):
    """The accelerometer ``sensor`` on ``link`` no longer reads gravity: no tilt from now on.

    Its reading ``accel_g`` (frame or sample ``seq``) has a magnitude of
    ``magnitude_g``, more than ``tolerance_g`` from 1 g: not fitted, unplugged,
    falling, shaken or miscalibrated (:mod:`whexar.sensors.gravity`). Said once
    when the readings turn implausible; :class:`AccelPlausible` ends it.
    """

    link: str
    sensor: str
    seq: int | None
    accel_g: tuple[float, float, float]
    magnitude_g: float
    tolerance_g: float


@message
class AccelPlausible(Event):
    """The accelerometer ``sensor`` on ``link`` reads gravity again after ``withheld`` readings."""

    link: str
    sensor: str
    seq: int | None
    magnitude_g: float
    withheld: int
