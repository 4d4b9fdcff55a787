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

from whexar.kinematics.trajectory import SwingOutcome
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

    ``reflex`` marks an override, sent by a reflex to a leg's ``reflex`` input:
    the leg alone decides each of its joints' goals (it holds the override, then
    blends back, :mod:`whexar.actors.locomotion.leg_controller`) and sends the bus
    the result. The bus gives the flag no meaning. ``priority`` ranks overrides: for
    one joint, the highest wins, whatever the order they came in.
    """

    goals: tuple[JointGoal, ...]
    reflex: bool = False
    priority: int = 0


class JointState(NamedTuple):
    """What one servo reported in a bus cycle; ``None`` where the plan did not read it.

    ``alert`` is the status packet's Alert bit: Hardware Error Status is set.
    A named tuple, not a message: 42 of them ride in every :class:`ServoStates`
    (which carries the time), and a tuple is made several times faster than a
    frozen dataclass (docs/architecture.md, "Figures behind the design").
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


# --------------------------------------------------------------------------- the world
# Physical faults of the simulated world (whexar.sim.faults): what happens to the robot,
# not to a device's link. Said by the simulation when one begins and when it ends, so a
# recording and a test see when the world pushed, slipped, went limp or snagged.


@message
class WorldFault(Event):
    """A physical fault of the simulated world began (``active``) or ended.

    ``kind``: ``push`` (a force on the body), ``slippery`` (the ground's friction
    changed under an area or a foot), ``limp`` (a servo lost power: no torque, no
    reply), ``snag`` (a joint blocked); ``target`` names where (the body, an area, a
    leg, a servo); ``detail`` the amounts, in words."""

    kind: str
    target: str
    detail: str
    active: bool


@message
class WorldDiverged(Event):
    """The simulated world's physics diverged at ``t`` (MuJoCo could not integrate it:
    ``detail``, its warning); the world holds still from then on and the run stops."""

    detail: str


# --------------------------------------------------------------------------- command sources
# The gamepad's link (whexar.actors.commands): ``link`` is its device, a path
# (/dev/input/event0) or an in-process pad (pipe:NAME).


@message
class GamepadLinkUp(Event):
    """The gamepad on ``link`` is open; ``name`` is what it calls itself (EVIOCGNAME), empty
    when it cannot say (a pipe)."""

    link: str
    name: str


@message
class GamepadLinkDown(Event):
    """The gamepad on ``link`` is not there or went away (``reason``); the robot was told to
    stop if it moved, and the source looks for the pad again every ``reopen_period_s``."""

    link: str
    reason: str


@message
class GamepadLinkSilent(Event):
    """The gamepad on ``link`` said nothing for ``silent_s`` while its dead-man was held and it
    asked for motion: the robot was told to stop."""

    link: str
    silent_s: float


@message
class GamepadLinkHeard(Event):
    """The gamepad on ``link`` reports again after ``silent_s`` of silence."""

    link: str
    silent_s: float


@message
class GamepadEventsDropped(Event):
    """The kernel dropped events of the gamepad on ``link`` (SYN_DROPPED; ``discarded`` more
    were thrown away after it). ``resynced``: its state was read back from the device;
    else it was forgotten and the dead-man must be pressed again."""

    link: str
    discarded: int
    resynced: bool


@message
class GamepadLayoutUnknown(Event):
    """The gamepad on ``link`` (``name``) lacks ``missing`` of the configured mapping (the
    dead-man button or a stick's axis): ``using`` is ``"default"`` when the default mapping
    fits it and drives it instead, ``"configured"`` when neither does (it cannot drive)."""

    link: str
    name: str
    missing: tuple[str, ...]
    using: str


# --------------------------------------------------------------------------- recording
# The recorder's own events (source "recorder"): about the process, not the robot, so a
# replay and ``whexar log diff`` leave them out (whexar.record.budget).


@message
class RecordingDeleted(Event):
    """An older recording ``path`` of ``size_bytes`` was deleted to keep the recordings
    folder within its budget (``[recording]``): ``reason`` says which limit."""

    path: str
    size_bytes: int
    reason: str


@message
class RecordingStopped(Event):
    """The recording ``path`` stopped before the run's end, for ``reason`` (over its
    budget, too little free space, a full disk, the recording process gone); the robot
    runs on, and the file reads up to here."""

    path: str
    reason: str


# --------------------------------------------------------------------------- locomotion
# The coordinator and the six leg actors (whexar.actors.locomotion).
# Points are in the body frame (x forward, y left, z up; metres) unless a name says
# otherwise; legs are indices 0…5 in LEG_NAMES order.

Vec3 = tuple[float, float, float]


@message
class MotionCommand(Message):
    """What the robot should do next; a field left ``None`` keeps its present value.

    One typed path for every front end: command scripts, stdin, the keyboard,
    scenarios and tests all send these to the coordinator.

    * ``vx_m_s``, ``vy_m_s``, ``yaw_rate_rad_s``: body velocity (forward, left, turn
      rate counter-clockwise); ``turn_radius_m`` instead of a yaw rate drives along a
      circle about (0, R) (R > 0: a left turn), the yaw rate following the speed;
    * ``gait``: tripod, tetrapod, ripple, wave, or ``auto`` (the gait selector's choice);
      ``mode``: walk, ride, hybrid;
    * ``stance``: a preset of ``[stances]``; ``step_height_m``, ``step_length_m``;
    * ``body_height_m`` (coxa joints above the ground), ``roll_rad``, ``pitch_rad``:
      the body pose over the feet;
    * ``upside_down``: the robot lies on its back (True) or on its feet; a change
      turns every leg 180° about its trochanter (6.8.1);
    * ``stop``: velocity to zero and every foot down in the stance.
    """

    vx_m_s: float | None = None
    vy_m_s: float | None = None
    yaw_rate_rad_s: float | None = None
    turn_radius_m: float | None = None
    gait: str | None = None
    mode: str | None = None
    stance: str | None = None
    step_height_m: float | None = None
    step_length_m: float | None = None
    body_height_m: float | None = None
    roll_rad: float | None = None
    pitch_rad: float | None = None
    upside_down: bool | None = None
    stop: bool = False


@message
class BodyMotion(Message):
    """The coordinator's set-points for this control cycle, read by every leg.

    ``twist`` (vx, vy, ω) is the body's velocity over the ground in the body frame,
    already limited and ramped: a stance foot moves by −(v + ω ẑ × p). ``pose`` is
    (x, y, z, roll, pitch, yaw) of the body relative to its neutral frame
    (:class:`~whexar.kinematics.body.BodyPose`); ``trochanter_rad`` the angle every
    trochanter holds (the body pitch of eq. 4.18, or −π when the legs are flipped);
    ``upside_down`` says the legs work flipped (6.8.1).

    The wheels: with ``steer`` each leg turns its wheel to ``wheel_heading_rad``
    (upright frame, 0 = straight ahead; the leg subtracts its coxa angle, 5.1) and
    drives it at ``wheel_speed_m_s`` (ground speed of the contact, signed), both in
    leg order; a leg whose foot is in the air stops its wheel whatever they say.
    Without ``steer`` the direction joints stand at 0 and the wheels are held, except
    the legs in ``steer_legs``: they steer and drive their wheels while the others walk
    (a leg riding its wheel for a lost coxa, :mod:`whexar.actors.locomotion.losses`).
    """

    cycle: int
    twist: Vec3
    pose: tuple[float, float, float, float, float, float]
    trochanter_rad: float
    upside_down: bool
    steer: bool = False
    wheel_heading_rad: tuple[float, ...] = (0.0,) * 6
    wheel_speed_m_s: tuple[float, ...] = (0.0,) * 6
    steer_legs: tuple[int, ...] = ()


@message
class StepCommand(Message):
    """The coordinator's order to one leg, valid from ``start_t`` for ``duration_s``.

    ``kind``:

    * ``"swing"``: lift the foot from where it is and put it down at ``target``,
      ``height_m`` above the ground at the highest, along ``trajectory`` (parabola,
      half_sine, or a CPG orbit: hopf, van_der_pol, rayleigh, stick_slip), which a
      ``duty_factor`` gait cycle re-times; the wheel stops first. Touching the
      ground early ends the swing there (adaptive swing);
    * ``"stance"``: keep the foot on the ground and let the body carry it
      (:class:`BodyMotion`'s twist) until ``start_t + duration_s``;
    * ``"move"``: move the foot to ``target`` in ``duration_s`` on a minimum-jerk
      path, lifted by ``height_m`` on the way (0: slide, for body height changes);
    * ``"hold"``: keep the foot where it is;
    * ``"ride"``: keep the foot where it is under the body, its wheel rolling it over the
      ground (:class:`BodyMotion`'s ``steer_legs``): a leg whose coxa is lost.

    ``search_depth_m`` (a swing): a foot that found no ground where expected searches
    down this far for it (the searching reflex's, 4.2.2), the stance going on from
    where it finds it; 0: it stays where the ground was expected. ``reach_depth_m`` (a
    swing): its stance foot, if it loses the ground it stood on, reaches down this far
    for it while the walk goes on (:mod:`whexar.actors.locomotion.steps`); 0: it does not.
    ``share_load`` (a swing or a stance): its stance shares the load with the other feet
    by their force sensors (``contact.balance_gain_m_s``): the coordinator asks it where
    the ground tilts ``contact.balance_tilt_deg`` or more.

    The wheels take their orders from :class:`BodyMotion`, every cycle.
    """

    leg: int
    kind: str
    start_t: float
    duration_s: float
    target: Vec3
    height_m: float = 0.0
    trajectory: str = "parabola"
    duty_factor: float = 0.5
    search_depth_m: float = 0.0
    reach_depth_m: float = 0.0
    share_load: bool = False


@message
class LegState(Message):
    """What a leg did in control cycle ``cycle``: its phase, foot and contact.

    ``phase`` is the kind of the step it executes (swing, stance, move, hold,
    reflex); ``progress`` how far through it (0…1). ``foot`` is the commanded foot
    point and ``measured_foot`` the point the servos' present angles give (FK),
    both in the body frame, ``None`` before the first reading. ``contact`` comes
    from the force sensor when the leg has one, else from the femur current
    (thesis 6.7.3); ``contact_source`` says which ("fsr", "current", "none").
    ``contact_confidence`` is the probability that ``contact`` is right given the
    force sensor, the current and the step's phase together
    (:mod:`whexar.kinematics.contact`); ``contact_source`` "none" with confidence 0
    when no sensor can be used. ``load`` is the eq. 5.19 indicator F = I / (L·sin α)
    of the femur and tibia segments (A/m), ``None`` where a reading is missing or the
    next joint is nearly straight. ``ik_ok`` is False while the leg holds its last good
    pose because the IK failed.
    """

    leg: int
    cycle: int
    phase: str
    progress: float
    foot: Vec3
    measured_foot: Vec3 | None
    contact: bool
    contact_source: str
    load: tuple[float | None, float | None]
    ik_ok: bool = True
    contact_confidence: float = 1.0
    foot_error_m: float | None = None
    """How far the foot is from where the goals sent put it (FK of the present angles
    against FK of the goals): the servos' tracking error at the foot — a leg pushed, held
    or snagged away from its goal (the stepping reflex's signal, 6.7.1)."""
    touchdown_pending: bool = False
    """A swing's touchdown is still awaited: its outcome (:class:`SwingEnded`) not judged
    yet, its search for the ground included. The coordinator lifts no such foot."""


@message
class LocomotionState(Message):
    """The coordinator's state, once per control cycle: what it does and why.

    ``activity``: standing_up, standing, walking, riding, hybrid, transition,
    flipping, sitting_down, seated. ``twist`` is the body velocity it commands,
    ``gait_phase`` the phase of the gait cycle (0…1), ``swing_legs`` the legs in
    swing, ``margin_m`` the static stability margin of the commanded support feet.
    """

    activity: str
    mode: str
    gait: str
    stance: str
    twist: Vec3
    gait_phase: float
    swing_legs: tuple[int, ...]
    margin_m: float
    upside_down: bool
    cycle_s: float = 0.0
    """The gait cycle's period T, s (0 while no gait runs)."""
    gait_auto: bool = False
    """The gait is the selector's choice (the operator asked for ``auto``)."""


@message
class SwingEnded(Message):
    """Leg ``leg``'s swing ended, with its foot ``ground_offset_m`` above (+) or below (−)
    where the ground was expected; a later stance continues from that height.

    ``outcome`` (:data:`~whexar.kinematics.trajectory.SwingOutcome`): ``completed`` (down
    where expected, or the swing ran its course on a leg that senses no contact),
    ``early_contact`` (ground met from the apex on: the leg stopped there), ``blocked``
    (something met on the way up: the elevator reflex's case; the swing goes on),
    ``no_contact`` (no ground where expected: the searching reflex's case). A control
    signal, not an event: each leg publishes it on its ``swings`` port."""

    leg: int
    outcome: SwingOutcome
    ground_offset_m: float
    confidence: float = 1.0
    """The leg's contact confidence when the outcome was judged
    (:class:`LegState`'s ``contact_confidence``)."""


@message
class BatteryLow(Event):
    """The line's voltage (the median of the servos' readings) stayed below
    ``threshold_v``: ``stage`` is ``warning`` (low: plan to stop) or ``empty`` (the robot
    sits down and shuts down, 5.3.1)."""

    stage: str
    voltage_v: float
    threshold_v: float


@message
class BatteryRestored(Event):
    """The line's voltage is back above the warning level (the supply was changed)."""

    voltage_v: float


@message
class ReflexRequest(Message):
    """Reflex ``reflex`` asks the coordinator for something (its ``requests`` input); a
    field left ``None`` leaves that request of the reflex as it was.

    * ``step_height_m``: swing at least this high; 0 withdraws;
    * ``step_raise_m``: swing this much higher than asked otherwise (the elevator reflex,
      6.7.2); 0 withdraws;
    * ``halt``: hold the body still, feet down, until the reflex says ``False`` (the
      obstacle reflex's stop, 4.2.2);
    * ``yaw_rate_rad_s``: add this to the commanded turn rate while the body translates
      (heading hold); 0 withdraws;
    * ``sit_down``: sit down and stay seated (the battery reflex, 5.3.1): the operator's
      commands are refused from then on;
    * ``search_depth_m``: swings search down this far for ground they do not find where
      expected (the searching reflex, 4.2.2); 0 withdraws;
    * ``reach_depth_m``: a stance foot that loses its ground reaches down this far for it,
      the walk going on (the searching reflex where four or five feet hold the body,
      6.7.3); 0 withdraws;
    * ``trochanter_rad``: hold the trochanters at this angle (eq. 4.18's body pitch: the
      legs parallel to gravity, the trochanter reflex, 6.7.6), in place of the
      coordinator's own rule; 0 withdraws;
    * ``block_ahead``: no translation forward while it lasts (the operator's forward speed
      held at 0; turning, sidestepping and backing away go on): the obstacle reflex's stop
      before what it will not climb (4.2.2: avoided by navigation); ``False`` withdraws;
    * ``restep_leg``: step that leg, once, to its neutral point moved by
      ``restep_offset_m`` (x, y in the body frame): the body halts, the leg swings
      there (searching as the swings do), the walk goes on (the stepping and searching
      reflexes, 6.7.1, 6.7.3). One at a time: a request while one is pending replaces it.

    The operator's command stays what the robot wants; the requests bend it while they
    last. ``reason`` says why, in a few words (the coordinator's events repeat it)."""

    reflex: str
    step_height_m: float | None = None
    step_raise_m: float | None = None
    halt: bool | None = None
    yaw_rate_rad_s: float | None = None
    sit_down: bool = False
    reason: str = ""
    search_depth_m: float | None = None
    reach_depth_m: float | None = None
    restep_leg: int | None = None
    restep_offset_m: tuple[float, float] = (0.0, 0.0)
    trochanter_rad: float | None = None
    block_ahead: bool | None = None


@message
class ReflexActivity(Message):
    """Reflex ``reflex`` became active (``active``) or went quiet, and why.

    Each reflex publishes its changes on the ``reflex-activity`` channel, and every reflex
    reads it: while a reflex is active, the reflexes it names in ``inhibits`` are held
    back (:mod:`whexar.actors.reactive`). ``inhibited`` is True while this reflex is
    itself held back."""

    reflex: str
    active: bool
    reason: str = ""
    inhibits: tuple[str, ...] = ()
    inhibited: bool = False


@message
class TerrainEstimate(Message):
    """The terrain estimator's metrics (4.2.3) over its sliding window (6.7.5).

    Over the last ``window_s`` (one gait cycle while walking): ``step_height_m``, the
    highest ground a swing met above where it expected (a foot stopped early on it, or a
    swing blocked on its way up): the step the terrain asks for, 0 on the flat;
    ``pitch_rad`` and ``roll_rad``, the body's mean tilt (IMU); ``obstacles``, the
    obstacles the rangefinders saw come near (ones to step over or climb); ``bumps``, the
    IMU's jolts (on wheels: rough ground); ``lost_supports``, the feet that found no ground
    where expected or lost it in stance. ``tilt_known`` is False while the window holds
    no tilt reading (no IMU: the tilt is 0 for want of one, not level)."""

    window_s: float
    step_height_m: float
    pitch_rad: float
    roll_rad: float
    obstacles: int
    bumps: int
    lost_supports: int
    tilt_known: bool = False


@message
class GaitChoice(Message):
    """The gait selector's choice (Table 5.9): ``gait``, the walking gait for the terrain,
    ``wheels`` whether riding would do; ``reason`` what decided it. The coordinator takes
    ``gait`` while the operator asks for the ``auto`` gait (its ``gait_choice`` input)."""

    gait: str
    wheels: bool
    reason: str


@message
class GaitSelected(Event):
    """The gait selector moved from ``before`` to ``after`` (``reason``: the metric and its
    threshold, or the calm that allowed a return)."""

    before: str
    after: str
    reason: str


@message
class Restepped(Event):
    """The coordinator stepped leg ``leg`` again at reflex ``reflex``'s request, to
    ``target`` (body frame), or could not (``done`` False, ``reason``)."""

    leg: int
    reflex: str
    target: Vec3
    done: bool
    reason: str = ""


@message
class NoFoothold(Event):
    """Leg ``leg`` found no ground within ``searched_m`` below where it expected it, after
    ``attempts`` steps around (the searching reflex): the body is held still."""

    leg: int
    searched_m: float
    attempts: int


@message
class ContactDegraded(Event):
    """Leg ``leg``'s contact sensor ``sensor`` (fsr, current) is set aside (``reason``):
    its contact estimate falls back on what is left (:mod:`whexar.kinematics.contact`)."""

    leg: int
    sensor: str
    reason: str


@message
class ContactRestored(Event):
    """Leg ``leg``'s contact sensor ``sensor`` is used again (``reason``)."""

    leg: int
    sensor: str
    reason: str


@message
class JointLost(Event):
    """The bus stopped reading joint ``joint`` of leg ``leg``: the coordinator does
    ``action`` about it (:mod:`whexar.actors.locomotion.losses`)."""

    leg: int
    joint: int
    action: str


@message
class JointBack(Event):
    """Joint ``joint`` of leg ``leg`` is read again: what its loss changed is undone."""

    leg: int
    joint: int


@message
class IkFailed(Event):
    """Leg ``leg`` could not reach ``target`` (body frame): it holds its last good pose."""

    leg: int
    target: Vec3
    reason: str


@message
class CommandClamped(Event):
    """A command asked for more than the robot can do: ``field`` was limited from
    ``requested`` to ``applied`` (``reason`` says by what)."""

    field: str
    requested: float
    applied: float
    reason: str


@message
class CommandRefused(Event):
    """A command that cannot be carried out was dropped (``reason``); nothing of it applies."""

    command: str
    reason: str


@message
class SwingDelayed(Event):
    """Lifting ``legs`` now would leave a stability margin of ``margin_m`` below
    ``minimum_m``: the gait waits with every foot down."""

    legs: tuple[int, ...]
    margin_m: float
    minimum_m: float


@message
class LocomotionChanged(Event):
    """The coordinator changed what it does: ``what`` (activity, gait, mode, stance,
    upside_down) from ``before`` to ``after``."""

    what: str
    before: str
    after: str
