"""The bus scheduler: the only owner of the servo port.

Theory of operation
-------------------
The control loop is bus-bound, so one actor plans every byte on the servo
bus and nothing else touches it. A cycle is:

1. take every goal that arrived since the last cycle — the latest per joint
   wins, except that a reflex goal (``JointGoals.reflex``) wins over any
   other for the same joint in the same cycle — and bring it within the
   joint's limits: a position is clamped to the limits and rounded to a tick
   *inside* them, a wheel speed to the servo's Velocity Limit (each clamp an
   event); a goal that is no command at all (not finite, absurdly far out, a
   position for a wheel) is refused with an event. Nothing outside the
   limits reaches the wire;
2. run the reads the plan says are due (:mod:`whexar.bus.plan`), each one
   Sync Read or Fast Sync Read of a contiguous register span;
3. Sync Write the goals that changed (positions; wheel speeds separately),
   and the goals of servos no packet addressed for half the Bus Watchdog
   period, so that every servo keeps hearing the host. A write the port
   failed to send is counted and its goals go out again in the next cycle;
4. publish :class:`ServoStates` for the cycle, :class:`ServoHealth` for slow
   readings, and :class:`BusStats` once a second.

Steps 2 and 3 are one job for the port owner (:mod:`whexar.bus.sdk`): one
thread hop per cycle on a real port, exact wire time on the emulator.

Start-up reads before it writes: it pings every configured servo (waiting
up to ``bus.boot_timeout_s`` for servos still booting) and checks its
model, then reads each servo's Return Delay Time, Operating Mode, Shutdown,
Torque Enable, Velocity Limit, Bus Watchdog and goal. Only a servo whose
EEPROM settings differ from the configuration has its torque turned off,
and only the values that differ are written: a robot standing under torque
keeps standing through a restart. A servo already under torque keeps its
goal (brought within the limits); the others get their present position
(likewise) and torque on, verified, with retries. A Bus Watchdog error left
by a host that stopped without stopping the servos is reported and cleared;
then the watchdog is armed (``bus.watchdog_ms``): if this process dies, the
servos stop by themselves. Fast Sync Read is detected, never assumed.

Failures, after ROBOTIS's ros2_control hardware interface:

* a failed read is retried (``bus.retries``) from the servo that failed,
  and counted; a servo failing ``bus.degrade_after`` cycles in a row is
  *degraded*: left out of the cycle and pinged every ``probe_period_s``;
* a status packet with the Alert bit, or a non-zero Hardware Error Status
  read, is classified by the servo's Shutdown mask. A bit in the mask
  (overload, overheating, electrical shock by default) latched and turned
  torque off: the servo is rebooted. It is silent while it boots (about
  0.4 s): the cycle goes on without it, polling it, until it answers (then
  its settings, goal and torque are restored) or ``boot_timeout_s`` passes
  (then it is degraded). A bit outside the mask (input voltage, by default)
  does not latch: the servo keeps its torque, the bit is reported
  (:class:`HardwareWarning`, and :class:`SupplyLow` for the bus) and clears
  by itself when the supply is back — no reboot;
* polling a booting servo or probing a degraded one is one ping per cycle
  at most, its timeout bounded by the nominal cycle time, so that no cycle
  takes more than twice its nominal time;
* Fast Sync Read that fails where Sync Read succeeds three times in a row
  falls back to Sync Read; it is detected again after a servo recovers;
* losing a femur or tibia servo (the legs cannot carry the body), or the
  port itself, is :class:`BusLost` and asks the runtime for a safe stop;
  after a lost servo the cycles go on without it until the servos are parked,
  so that the coordinator can sit the robot down first.

On stop (and on a safe stop) the wheels are brought to zero speed, then the
servos end in ``bus.on_stop``: torque off by default, or holding their last
positions (with the watchdog disarmed, so a held robot stays held).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final, Literal

import anyio
from pydantic import Field

from whexar.actors.messages import (
    BusLost,
    BusStats,
    BusWarning,
    GoalClamped,
    GoalRefused,
    HardwareFault,
    HardwareWarning,
    JointGoal,
    JointGoals,
    JointState,
    ReadModeChanged,
    ServoDegraded,
    ServoFault,
    ServoHealth,
    ServoRebooted,
    ServoRecovered,
    ServoRestored,
    ServoStates,
    SupplyLow,
    SupplyRestored,
    WatchdogStopped,
    WriteFailed,
)
from whexar.bus import control_table as ct
from whexar.bus.emulator.faults import FaultPlanFile
from whexar.bus.plan import PlanRead, ReadPlan, resolve_plan
from whexar.bus.protocol import ALERT, sync_read_bytes, sync_write_bytes
from whexar.bus.replay import REPLAYED_BUS
from whexar.bus.sdk import (
    COMM_SUCCESS,
    LATENCY_FIX,
    DxlBus,
    InlinePortOwner,
    PortOwner,
    Reply,
    SyncReadResult,
    ThreadPortOwner,
    comm_name,
    latency_timer_ms,
    open_port,
    tap_port,
)
from whexar.config import ConfigFile, RobotConfig, load_config
from whexar.errors import DeviceError, DeviceGoneError
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.devices import DEVICES

CRITICAL_JOINTS: Final = frozenset({"femur", "tibia"})
"""Joints whose loss leaves a leg unable to carry the body: a safe stop (issue brief)."""
FAST_FALLBACK_AFTER: Final = 3
"""Consecutive Fast Sync Read failures, each healed by Sync Read, before falling back."""
EMULATOR: Final = "emulator"
"""The port name of a fresh in-process servo emulator; ``emulator:NAME`` opens the chain
registered as NAME (:data:`~whexar.bus.emulator.chain.SERVO_CHAIN`)."""
ABSURD_TURNS: Final = 1.0
"""A position goal more than this many turns beyond its joint's limits is refused, not
clamped: it is an upstream bug, not a command to saturate."""
ABSURD_SPEED_FACTOR: Final = 10.0
"""Likewise a wheel speed beyond this multiple of the servo's Velocity Limit."""
WARNING_RECHECK_S: Final = 0.1
"""While a servo's non-latching error stands, how often an Alert makes it be read again
(a latching error on top of it is seen within this)."""
BOOT_POLL_S: Final = 0.05
"""How often a rebooted servo is pinged while it boots (one ping per cycle at most)."""
START_RETRY_S: Final = 0.05
"""Pause between start-up ping rounds while servos are still booting."""
NOMINAL_SMOOTHING: Final = 0.1
"""Weight of the newest healthy cycle in the nominal cycle time (an exponential mean)."""
DEFAULT_NOMINAL_S: Final = 0.02
"""The nominal cycle time before the first healthy cycle was measured."""
MIN_CYCLE_S: Final = 0.005
"""Shortest cycle after a lost servo, while the robot sits down (a measured nominal cycle
of zero bus time, as a replay past its recording's answers has, would stop the clock)."""
MIN_PROBE_TIMEOUT_MS: Final = 1.0
"""Shortest wait for a probed servo's status: a servo answers in ~0.1 ms plus its Return
Delay Time at 1 Mbps, and a USB adapter adds its latency timer (1 ms when set right)."""

_REG_POSITION = ct.MODELS["MX-64"].register("present_position")
_TORQUE = ct.MODELS["MX-64"].register("torque_enable")
_HW_ERROR = ct.MODELS["MX-64"].register("hardware_error_status")
_GOAL_POSITION = ct.MODELS["MX-64"].register("goal_position")
_GOAL_VELOCITY = ct.MODELS["MX-64"].register("goal_velocity")
_RETURN_DELAY = ct.MODELS["MX-64"].register("return_delay_time")
_OPERATING_MODE = ct.MODELS["MX-64"].register("operating_mode")
_WATCHDOG = ct.MODELS["MX-64"].register("bus_watchdog")
_SETTINGS = ct.block(["return_delay_time", "operating_mode"])
"""Return Delay Time (9) and Operating Mode (11): the EEPROM the scheduler sets."""
_SURVEY = ct.block(
    [
        "return_delay_time",
        "operating_mode",
        "velocity_limit",
        "shutdown",
        "torque_enable",
        "hardware_error_status",
        "bus_watchdog",
        "goal_position",
        "present_position",
    ]
)
"""What start-up reads of every servo before it writes anything: one Sync Read of 9–135."""
_WHEEL_GOAL = ct.block(["goal_velocity"])
_TORQUE_SPAN = ct.block(["torque_enable"])
_RAD_PER_TICK: Final = ct.ticks_to_rad(ct.CENTER_TICKS + 1)
_CENTER_TICKS: Final = ct.CENTER_TICKS
_ABSURD_RAD: Final = ABSURD_TURNS * 2 * math.pi
"""A position goal this far beyond a joint's limits is refused (``ABSURD_TURNS``)."""
_RAD_S_PER_UNIT: Final = ct.velocity_to_rad_s(1)
_pack_i32 = struct.Struct("<i").pack
"""Goal Position/Velocity bytes (signed 32-bit, little-endian); goals are clamped first."""
_MODE_VELOCITY: Final = 1
_MODE_POSITION: Final = 3
"""Operating Mode (11): 1 velocity control (the wheel), 3 position control (e-manual)."""
_WATCHDOG_ERROR: Final = -1
"""Bus Watchdog (98) reads −1 after it stopped the servo (e-manual)."""
_WATCHDOG_UNIT_S: Final = 0.02
"""Bus Watchdog counts 20 ms units (e-manual)."""

State = Literal["ok", "booting", "degraded"]


def tick_limits(lo: float, hi: float) -> tuple[int, int]:
    """The first and last Goal Position ticks whose angle lies within [lo, hi] (rad).

    Rounding to the nearest tick could step past a limit (tibia 150° is tick
    3754.67: 3755 is 150.03°); these are the ticks inside, with no tolerance,
    within the register's one turn (0…4095).
    """
    per_tick = ct.ticks_to_rad(ct.CENTER_TICKS + 1)
    first = max(0, ct.CENTER_TICKS + math.ceil(lo / per_tick) - 1)
    while ct.ticks_to_rad(first) < lo:
        first += 1
    last = min(ct.TICKS_PER_REV - 1, ct.CENTER_TICKS + math.floor(hi / per_tick) + 1)
    while ct.ticks_to_rad(last) > hi:
        last -= 1
    return first, last


@dataclass(slots=True)
class _Servo:
    id: int
    leg: int
    joint: int
    model: ct.ServoModel
    endless: bool
    lo: float
    hi: float
    """The joint's limits (rad) within what Goal Position can express."""
    lo_tick: int
    hi_tick: int
    """The ticks inside ``lo``…``hi`` (:func:`tick_limits`)."""
    critical: bool
    speed_limit: int
    """Velocity Limit (44) in velocity units, read at start-up (the wheel's clamp)."""
    shutdown: int = 0x34
    """Shutdown (63): the error bits that latch and turn torque off (read at start-up)."""
    state: State = "ok"
    failures: int = 0
    next_probe: float = 0.0
    boot_deadline: float = 0.0
    goal: int | None = None
    """The goal to hold: ticks (position joints) or velocity units (the wheel)."""
    sent: int | None = None
    addressed_at: float = 0.0
    """When a packet last addressed it (what feeds its Bus Watchdog)."""
    warning: int = 0
    """Non-latching Hardware Error Status bits last seen (input voltage, by default)."""
    current_unit: float = 0.0
    """A per unit of Present Current (Present Load's unit on the MX-28), set in ``_setup``."""
    next_check: float = 0.0
    """While a warning stands (every status has the Alert bit), when to read 70 again."""
    from_degraded: bool = False
    """Booting after a probe found it degraded with a latched error: back means recovered."""

    @property
    def name(self) -> str:
        return f"servo {self.id} ({LEG_NAMES[self.leg]} {JOINT_NAMES[self.joint]})"

    @property
    def live(self) -> bool:
        """In the cycle: neither booting nor degraded."""
        return self.state == "ok"

    def clamp_tick(self, tick: int) -> int:
        return min(max(tick, self.lo_tick), self.hi_tick)


@dataclass(slots=True)
class _Read:
    """One plan read bound to servos: its span, its due time and its round-robin cursor."""

    spec: PlanRead
    block: ct.Block
    servos: list[_Servo]
    next_due: float = 0.0
    cursor: int = 0

    def take(self, now: float) -> list[_Servo]:
        """The servos this read asks in a cycle at ``now`` (none when not due)."""
        if self.spec.rate_hz is not None:
            if now < self.next_due:
                return []
            self.next_due = max(self.next_due + 1.0 / self.spec.rate_hz, now)
        live = [s for s in self.servos if s.state == "ok"]  # s.live, inlined: every cycle
        chunk = self.spec.chunk
        if chunk is None or chunk >= len(live):
            return live
        start = self.cursor % max(1, len(live))
        self.cursor = start + chunk
        return (live[start:] + live[:start])[:chunk]


@dataclass(slots=True)
class _Request:
    start: int
    length: int
    ids: tuple[int, ...]


@dataclass(slots=True)
class _Write:
    """One Sync Write of a cycle: a goal register (4 bytes, signed), the value per servo."""

    register: ct.Register
    values: dict[int, int]


@dataclass(slots=True)
class _Outcome:
    """What the port owner did in one cycle (built in the port's thread, read on the loop)."""

    reads: list[SyncReadResult] = field(default_factory=list)
    failed: dict[int, str] = field(default_factory=dict)
    retries: int = 0
    fast_failures: int = 0
    bytes: int = 0
    write_results: list[int] = field(default_factory=list)


def _cycle_job(
    requests: Sequence[_Request], fast: bool, retries: int, writes: Sequence[_Write]
) -> Callable[[DxlBus], _Outcome]:
    """The port-side half of a cycle: the due reads (with retries), then the goal writes."""

    def job(bus: DxlBus) -> _Outcome:
        out = _Outcome()
        # The writes are built first: after the last status of the reads they go out at once.
        packets = [
            bus.prepare_sync_write(
                w.register.address,
                w.register.size,  # goals: 4 bytes, signed — one precompiled struct
                {sid: _pack_i32(v) for sid, v in w.values.items()},
            )
            for w in writes
        ]
        unsent = True
        for k, req in enumerate(requests):
            merged = SyncReadResult(COMM_SUCCESS)
            remaining = list(req.ids)
            use_fast = fast
            attempts = 0
            while remaining:
                # The writes ride on the cycle's last read: out as soon as the bus is free.
                then = packets if unsent and k == len(requests) - 1 else ()
                res = bus.sync_read(remaining, req.start, req.length, fast=use_fast, then=then)
                if then:
                    out.write_results.extend(res.sent)
                    unsent = False
                out.bytes += sum(sync_read_bytes(len(remaining), req.length, fast=use_fast))
                merged.data.update(res.data)
                merged.errors.update(res.errors)
                if res.ok:
                    break
                if use_fast:
                    # A bad fast packet names no culprit: ask again the plain way.
                    out.fast_failures += 1
                    use_fast = False
                    out.retries += 1
                    continue
                failed = res.failed if res.failed is not None else remaining[0]
                at = remaining.index(failed)
                remaining = remaining[at:]
                if attempts < retries:
                    attempts += 1
                    out.retries += 1
                    continue
                out.failed[failed] = comm_name(res.result)
                remaining = remaining[1:]
                attempts = 0
            out.reads.append(merged)
        if unsent:
            out.write_results.extend(bus.send(packet) for packet in packets)
        for w in writes:
            out.bytes += sync_write_bytes(len(w.values), w.register.size)
        return out

    return job


def _enable_job(
    servos: Sequence[_Servo],
) -> Callable[[DxlBus], tuple[SyncReadResult, dict[int, int]]]:
    """Read where each limp joint is now and make that its goal, so that torque-on holds
    it still; torque on; read Torque Enable back. Returns the read-back and the position
    goals written (each within its joint's limits).

    The positions are read in the same job as torque-on: a limp joint sags under the
    robot's weight, and a position read before (the start-up's survey, tens of ms
    earlier) would pull it back with a jolt. A servo that does not answer keeps the
    goal it had."""
    joints = [s for s in servos if not s.endless]
    vel = {s.id: _pack_i32(s.goal or 0) for s in servos if s.endless}
    ids = [s.id for s in servos]

    def job(bus: DxlBus) -> tuple[SyncReadResult, dict[int, int]]:
        now = bus.sync_read([s.id for s in joints], _REG_POSITION.address, 4) if joints else None
        goals: dict[int, int] = {}
        for s in joints:
            data = now.data.get(s.id) if now is not None else None
            tick = int.from_bytes(data, "little", signed=True) if data else s.goal or 0
            goals[s.id] = s.clamp_tick(tick)
        bus.sync_write(_GOAL_POSITION.address, 4, {i: _pack_i32(g) for i, g in goals.items()})
        bus.sync_write(_GOAL_VELOCITY.address, 4, vel)
        bus.sync_write(_TORQUE.address, 1, dict.fromkeys(ids, b"\x01"))
        return bus.sync_read(ids, _TORQUE.address, 1), goals

    return job


def _ping_job(ids: Sequence[int]) -> Callable[[DxlBus], dict[int, Reply]]:
    return lambda bus: {i: bus.ping(i) for i in ids}


def _read_job(sid: int, reg: ct.Register) -> Callable[[DxlBus], Reply]:
    return lambda bus: bus.read(sid, reg)


def _read_all(bus: DxlBus, ids: Sequence[int], span: ct.Block) -> dict[int, dict[str, int]]:
    """``span`` of every servo in ``ids``; a servo that does not answer is left out."""
    out: dict[int, dict[str, int]] = {}
    remaining = list(ids)
    while remaining:
        res = bus.sync_read(remaining, span.start, span.length)
        out.update({sid: span.decode(data) for sid, data in res.data.items()})
        if res.ok or res.failed is None:
            break
        remaining = remaining[remaining.index(res.failed) + 1 :]
    return out


class BusScheduler(Actor):
    """Owns the servo port: reads per the plan, writes goals, recovers servos."""

    class Params(ActorParams):
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults (= config/whexar.toml)."""
        port: str | None = None
        """Overrides ``bus.port``: a device, a pty, ``emulator`` or ``emulator:NAME``, or
        ``replay:NAME`` for a recorded bus played back (:mod:`whexar.bus.replay`)."""
        plan: str | ReadPlan | None = None
        """Overrides ``bus.plan``: a preset name or a plan table."""
        emulator_fast_sync_read: bool = False
        """For ``port = "emulator"``: whether the emulated servos answer Fast Sync Read."""
        faults: FaultPlanFile | None = None
        """For ``port = "emulator"``: a fault plan (TOML) applied to the emulated servos."""
        stats_period_s: float = Field(1.0, gt=0)
        """How often :class:`BusStats` is published."""

    params: Params
    goals = Input(JointGoals, optional=True)
    state = Output(ServoStates)
    health = Output(ServoHealth, optional=True)
    stats = Output(BusStats, optional=True)

    # ----------------------------------------------------------------- set-up

    def _setup(self) -> None:
        p = self.params
        self.cfg: RobotConfig = load_config(p.config) if p.config else RobotConfig()
        self.plan: ReadPlan = resolve_plan(p.plan if p.plan is not None else self.cfg.bus.plan)
        self.servos: dict[int, _Servo] = {}
        for leg, leg_spec in enumerate(self.cfg.legs):
            for j, sid in enumerate(leg_spec.servo_ids):
                joint = self.cfg.joints.by_name(JOINT_NAMES[j])
                limits = joint.limits_rad
                model = ct.model(joint.model)
                # Goal Position spans one turn, 0…4095 around the centre (2048).
                lo = max(limits[0], ct.ticks_to_rad(0)) if limits else -math.inf
                hi = min(limits[1], ct.ticks_to_rad(ct.TICKS_PER_REV - 1)) if limits else math.inf
                lo_tick, hi_tick = tick_limits(lo, hi) if limits else (0, ct.TICKS_PER_REV - 1)
                self.servos[sid] = _Servo(
                    sid,
                    leg,
                    j,
                    model,
                    joint.endless,
                    lo,
                    hi,
                    lo_tick,
                    hi_tick,
                    JOINT_NAMES[j] in CRITICAL_JOINTS,
                    model.register("velocity_limit").initial or 0,
                )
        for s in self.servos.values():
            s.current_unit = ct.current_to_a(1, s.model)
        self.by_joint = {(s.leg, s.joint): s for s in self.servos.values()}
        ordered = sorted(self.servos.values(), key=lambda s: s.id)
        self.reads = []
        for spec in self.plan.reads:
            chosen = [
                s
                for s in ordered
                if JOINT_NAMES[s.joint] in spec.joints and LEG_NAMES[s.leg] in spec.legs
            ]
            models = {s.model.name: s.model for s in chosen}.values() or ct.MODELS.values()
            self.reads.append(_Read(spec, ct.block(spec.registers, models), chosen))
        self.home: dict[int, int] = {}
        """Each servo's first read in the plan: where a suspect is asked again."""
        for k, read in enumerate(self.reads):
            for s in read.servos:
                self.home.setdefault(s.id, k)
        self.suspects: set[int] = set()
        """Servos whose last read failed: asked every cycle (:meth:`_ask_suspects`)."""
        self.fast = self.plan.fast_sync_read == "on"
        self.fast_streak = 0
        self.cycle = 0
        self.counters = {
            "retries": 0,
            "timeouts": 0,
            "corrupt": 0,
            "clamped": 0,
            "bytes": 0,
            "write_failures": 0,
        }
        # Return Delay Time register value (2 µs units), written at start and on restore.
        self.rdt = ct.return_delay_units(self.cfg.bus.return_delay_time_us * 1e-6)
        self.watchdog_units = round(self.cfg.bus.watchdog_ms / 1000 / _WATCHDOG_UNIT_S)
        # Every servo hears a packet at least twice per watchdog period.
        self.keepalive_s = self.watchdog_units * _WATCHDOG_UNIT_S / 2 or math.inf
        self.nominal_s = DEFAULT_NOMINAL_S
        self.measured = False
        self.supply_low = False
        self.port_lost = False
        self.lost = False
        """Set with :class:`BusLost`. A lost servo: the cycles go on without it, so that the
        safe stop can sit the robot down; a lost port (:attr:`port_lost`) ends them."""
        self.parked = False
        """The servos were parked (:meth:`_park`): no more cycles."""

    def _open_owner(self) -> PortOwner:
        name = self.params.port or self.cfg.bus.port
        if name.startswith(REPLAYED_BUS.scheme + ":"):
            # A recorded bus played back (whexar replay): bytes and bus times as recorded.
            replay = DEVICES.get(REPLAYED_BUS, name.split(":", 1)[1], setting=f"port = {name!r}")
            played = replay.open(self.clock.now)
            played.setPortName(name)
            tap = self.tap()
            if tap is not None:
                tap_port(played, tap, lambda: self.clock.now() + played.elapsed_s)
            return InlinePortOwner(played, self.clock)
        if name == EMULATOR or name.startswith(EMULATOR + ":"):
            from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
            from whexar.bus.emulator.port import EmulatedPort

            if name == EMULATOR:
                chain = ServoChain.for_models(
                    self.cfg.servos(),
                    baudrate=self.cfg.bus.baudrate,
                    fast_sync_read=self.params.emulator_fast_sync_read,
                )
                if self.params.faults:
                    from whexar.bus.emulator.faults import FaultInjector, load_fault_plan

                    FaultInjector(load_fault_plan(self.params.faults)).attach(chain)
            else:
                key = name.split(":", 1)[1]
                chain = DEVICES.get(SERVO_CHAIN, key, setting=f"port = {name!r}")
            port = EmulatedPort(chain, now=self.clock.now)
            port.setPortName(name)  # errors name the configured port, as a device's do
            tap = self.tap()
            if tap is not None:  # bus time: the loop's, plus the wire time of this job so far
                tap_port(port, tap, lambda: self.clock.now() + port.elapsed_s)
            return InlinePortOwner(port, self.clock)
        self.clock.uses_real_io(f"servo port {name}")  # refused on virtual time, by name
        latency = latency_timer_ms(name)
        if latency is not None and latency > 1:
            device = name.rsplit("/", 1)[-1]
            self.emit(
                BusWarning(
                    t=self.now(),
                    source=self.name,
                    message=f"{name}: USB latency timer is {latency} ms, which caps the "
                    f"bus rate; set it to 1 ms: {LATENCY_FIX.format(device=device)}",
                )
            )
        real = open_port(name, self.cfg.bus.baudrate)
        tap = self.tap()
        if tap is not None:
            tap_port(real, tap, self.clock.now)
        return ThreadPortOwner(real)

    # ----------------------------------------------------------------- start-up

    async def _start_up(self, owner: PortOwner) -> None:
        servos = sorted(self.servos.values(), key=lambda s: s.id)
        await self._ping_all(owner, servos)
        ids = [s.id for s in servos]
        survey = await owner.call(lambda bus: _read_all(bus, ids, _SURVEY))
        silent = [s.name for s in servos if s.id not in survey]
        if silent:
            raise DeviceGoneError(f"no answer reading the settings of {', '.join(silent)}")
        for s in servos:
            s.speed_limit = survey[s.id]["velocity_limit"]
            s.shutdown = survey[s.id]["shutdown"]
        stopped = [sid for sid, regs in survey.items() if regs["bus_watchdog"] == _WATCHDOG_ERROR]
        if stopped:
            self.emit(WatchdogStopped(t=self.now(), source=self.name, servo_ids=tuple(stopped)))
            await owner.call(lambda bus: [bus.write(sid, _WATCHDOG, 0) for sid in stopped])
        # EEPROM only where it differs; torque off only where EEPROM must change.
        changes: dict[int, list[tuple[ct.Register, int]]] = {}
        for s in servos:
            mode = _MODE_VELOCITY if s.endless else _MODE_POSITION
            have = survey[s.id]
            wanted = ((_RETURN_DELAY, self.rdt), (_OPERATING_MODE, mode))
            diff = [(reg, v) for reg, v in wanted if have[reg.name] != v]
            if diff:
                changes[s.id] = diff
        if changes:
            problems = await owner.call(self._configure_job(changes))
            if problems:
                raise DeviceError("servo set-up failed: " + "; ".join(problems))
        await self._detect_fast(owner, "start-up")
        holding = {s.id for s in servos if s.id not in changes and survey[s.id]["torque_enable"]}
        for s in servos:
            if s.endless:
                s.goal = 0  # a wheel starts still, whatever it did before
            else:
                which = "goal_position" if s.id in holding else "present_position"
                s.goal = self._start_goal(s, survey[s.id][which])
        # Servos that hold on: a position goal goes out only if it had to change.
        moved = {
            s.id: _pack_i32(s.goal or 0)
            for s in servos
            if s.id in holding and not s.endless and s.goal != survey[s.id]["goal_position"]
        }
        still = {s.id: _pack_i32(0) for s in servos if s.id in holding and s.endless}

        def hold(bus: DxlBus) -> None:
            bus.sync_write(_GOAL_POSITION.address, 4, moved)
            bus.sync_write(_GOAL_VELOCITY.address, 4, still)

        await owner.call(hold)
        limp = []
        for s in servos:
            if s.id in holding:
                s.sent = s.goal
            else:
                limp.append(s)
        if limp:
            await self._enable_torque(owner, limp)
        await self._arm_watchdog(owner, servos)
        for s in servos:
            s.addressed_at = self.now()

    async def _ping_all(self, owner: PortOwner, servos: Sequence[_Servo]) -> None:
        """Ping every servo, in rounds while some are still booting (``bus.boot_timeout_s``)."""
        deadline = self.now() + self.cfg.bus.boot_timeout_s
        todo = list(servos)
        while True:
            ids = [s.id for s in todo]
            pings = await owner.call(_ping_job(ids))
            wrong = [
                f"{s.name} is a {ct.model_name(pings[s.id].value)} (model {pings[s.id].value}); "
                f"the configuration says {s.model.name} (model {s.model.model_number})"
                for s in todo
                if pings[s.id].ok and pings[s.id].value != s.model.model_number
            ]
            if wrong:
                raise DeviceError("servo model mismatch: " + "; ".join(wrong))
            todo = [s for s in todo if not pings[s.id].ok]
            if not todo:
                return
            if self.now() >= deadline:
                names = ", ".join(s.name for s in todo)
                raise DeviceGoneError(f"no answer at start-up from {names}")
            await self.clock.sleep(START_RETRY_S)

    def _configure_job(
        self, changes: Mapping[int, Sequence[tuple[ct.Register, int]]]
    ) -> Callable[[DxlBus], list[str]]:
        def configure(bus: DxlBus) -> list[str]:
            problems = []
            bus.sync_write(_TORQUE.address, 1, dict.fromkeys(changes, b"\x00"))  # EEPROM needs it
            for sid, diff in changes.items():
                for reg, value in diff:
                    reply = bus.write(sid, reg, value)
                    if not reply.ok or reply.error & ~ALERT:
                        name = self.servos[sid].name
                        problems.append(f"{name}: writing {reg.name} = {value} failed")
            return problems

        return configure

    def _start_goal(self, s: _Servo, tick: int) -> int:
        """A start-up goal (a present or held position) within the limits, an event if not."""
        inside = s.clamp_tick(tick)
        if inside != tick:
            self._clamped(s, ct.ticks_to_rad(tick), ct.ticks_to_rad(inside))
        return inside

    def _clamped(self, s: _Servo, requested: float, sent: float, unit: str = "rad") -> None:
        self.counters["clamped"] += 1
        self.emit(
            GoalClamped(
                t=self.now(),
                source=self.name,
                servo_id=s.id,
                requested_rad=requested,
                sent_rad=sent,
                unit=unit,
            )
        )

    async def _enable_torque(self, owner: PortOwner, servos: Sequence[_Servo]) -> None:
        """Hold each joint where it is (:func:`_enable_job`), then torque on, verified, with
        retries."""
        attempts = self.cfg.bus.torque_retries
        todo = list(servos)
        for _ in range(attempts):
            check, goals = await owner.call(_enable_job(todo))
            for s in todo:
                s.goal = goals.get(s.id, s.goal)
                s.sent = s.goal
            todo = [s for s in todo if check.data.get(s.id, b"\x00")[0] != 1]
            if not todo:
                return
        names = ", ".join(s.name for s in todo)
        raise DeviceError(f"torque could not be enabled on {names} after {attempts} attempts")

    async def _arm_watchdog(self, owner: PortOwner, servos: Iterable[_Servo]) -> None:
        """Set Bus Watchdog (98) to ``bus.watchdog_ms`` (0: off) on ``servos``."""
        units = bytes((self.watchdog_units,))
        ids = dict.fromkeys((s.id for s in servos), units)
        await owner.call(lambda bus: bus.sync_write(_WATCHDOG.address, 1, ids))

    async def _detect_fast(self, owner: PortOwner, why: str) -> None:
        """Try Fast Sync Read of the first read; keep it only if it works (``auto`` plans)."""
        if self.plan.fast_sync_read != "auto":
            return
        first = self.reads[0]
        ids = [s.id for s in first.servos if s.live]
        start, length = first.block.start, first.block.length

        def probe(bus: DxlBus) -> bool:
            return bus.sync_read(ids, start, length, fast=True).ok

        works = await owner.call(probe)
        if works != self.fast or why == "start-up":
            mode = "fast_sync_read" if works else "sync_read"
            verdict = "answered" if works else "did not answer"
            self.emit(
                ReadModeChanged(
                    t=self.now(),
                    source=self.name,
                    mode=mode,
                    reason=f"{why}: Fast Sync Read {verdict}",
                )
            )
        self.fast = works
        self.fast_streak = 0

    # ----------------------------------------------------------------- goals

    def _take_goals(self) -> None:
        inbox = self.goals
        if not inbox.connected:
            return
        messages = inbox.drain()
        # Reflex goals last: for a joint both touched this cycle, the reflex wins.
        for msg in [m for m in messages if not m.reflex] + [m for m in messages if m.reflex]:
            for g in msg.goals:
                self._take(g)

    def _refuse(self, g: JointGoal, reason: str) -> None:
        self.emit(
            GoalRefused(t=self.now(), source=self.name, leg=g.leg, joint=g.joint, reason=reason)
        )

    def _take(self, g: JointGoal) -> None:
        servo = self.by_joint.get((g.leg, g.joint))
        if servo is None:
            self._refuse(g, f"no joint {g.joint} on leg {g.leg} (legs 0–5, joints 0–6)")
            return
        if servo.endless:
            self._take_speed(servo, g)
            return
        want = g.position_rad
        if want is None:
            what = "a speed" if g.velocity_rad_s is not None else "no goal"
            self._refuse(g, f"{what} for {servo.name}, a positioned joint: give position_rad")
            return
        if not math.isfinite(want):
            self._refuse(g, f"position_rad = {want!r} for {servo.name}: not a finite number")
            return
        sent = min(max(want, servo.lo), servo.hi)
        if abs(want - sent) > _ABSURD_RAD:
            self._refuse(
                g,
                f"position_rad = {want!r} for {servo.name}: more than a turn beyond its "
                f"limits ({servo.lo:.3f}…{servo.hi:.3f} rad)",
            )
            return
        if sent != want:
            self._clamped(servo, want, sent)
        tick = _CENTER_TICKS + round(sent / _RAD_PER_TICK)  # ct.rad_to_ticks, inlined
        servo.goal = servo.lo_tick if tick < servo.lo_tick else min(tick, servo.hi_tick)

    def _take_speed(self, servo: _Servo, g: JointGoal) -> None:
        speed = g.velocity_rad_s
        if g.position_rad is not None or speed is None:
            what = "a position" if g.position_rad is not None else "no goal"
            self._refuse(g, f"{what} for {servo.name}, a wheel: give velocity_rad_s")
            return
        limit = ct.velocity_to_rad_s(servo.speed_limit)
        if not math.isfinite(speed) or abs(speed) > ABSURD_SPEED_FACTOR * limit:
            self._refuse(
                g,
                f"velocity_rad_s = {speed!r} for {servo.name}: not a speed "
                f"(its Velocity Limit is {limit:.3f} rad/s)",
            )
            return
        units = max(-servo.speed_limit, min(servo.speed_limit, ct.rad_s_to_velocity(speed)))
        if abs(speed) > limit:
            self._clamped(servo, speed, ct.velocity_to_rad_s(units), "rad/s")
        servo.goal = units

    def _writes(self, now: float) -> list[_Write]:
        """Goals that changed, and those of servos the watchdog would soon miss."""
        pos: dict[int, int] = {}
        vel: dict[int, int] = {}
        stale = now - self.keepalive_s
        for s in self.servos.values():
            goal = s.goal
            if s.state != "ok" or goal is None:  # not s.live (inlined: every cycle, 42 servos)
                continue
            if goal != s.sent or s.addressed_at <= stale:
                (vel if s.endless else pos)[s.id] = goal
        writes = []
        if pos:
            writes.append(_Write(_GOAL_POSITION, pos))
        if vel:
            writes.append(_Write(_GOAL_VELOCITY, vel))
        return writes

    # ----------------------------------------------------------------- the cycle

    async def _cycle(self, owner: PortOwner) -> None:
        t = self.now()
        self._take_goals()
        due: list[tuple[_Read, list[_Servo]]] = []
        for read in self.reads:
            servos = read.take(t)
            if servos:
                due.append((read, servos))
        if self.suspects:
            due = self._ask_suspects(due)
        requests = [
            _Request(r.block.start, r.block.length, tuple(s.id for s in servos))
            for r, servos in due
        ]
        writes = self._writes(t)
        outcome = await owner.call(_cycle_job(requests, self.fast, self.cfg.bus.retries, writes))
        self.cycle += 1
        self.counters["retries"] += outcome.retries
        self.counters["bytes"] += outcome.bytes
        for _, servos in due:
            for s in servos:
                s.addressed_at = t
        self._account_writes(t, writes, outcome.write_results)
        if outcome.fast_failures:
            self.fast_streak += 1
            if self.fast_streak >= FAST_FALLBACK_AFTER:
                self.fast = False
                self.emit(
                    ReadModeChanged(
                        t=self.now(),
                        source=self.name,
                        mode="sync_read",
                        reason=f"Fast Sync Read failed {self.fast_streak} cycles in a row "
                        "where Sync Read worked",
                    )
                )
        elif self.fast:
            self.fast_streak = 0
        values: dict[int, dict[str, int]] = {}
        errors: dict[int, int] = {}
        for (read, _), res in zip(due, outcome.reads, strict=True):
            decode = read.block.decode
            for sid, data in res.data.items():
                decoded = decode(data)
                if sid in values:
                    values[sid].update(decoded)
                else:
                    values[sid] = decoded
            errors.update(res.errors)
        await self._publish(t, values, errors)
        self._account(outcome, values)
        healthy = not outcome.failed and not outcome.retries
        busy = await self._recover(owner, values, errors)
        if healthy and not busy:
            # The nominal cycle: what a cycle costs when nothing goes wrong.
            took = self.now() - t
            w = NOMINAL_SMOOTHING if self.measured else 1.0
            self.nominal_s += w * (took - self.nominal_s)
            self.measured = True

    def _ask_suspects(
        self, due: list[tuple[_Read, list[_Servo]]]
    ) -> list[tuple[_Read, list[_Servo]]]:
        """``due`` with every servo whose last read failed asked again, in the first read
        of the plan that covers it, until it answers or is degraded.

        ``degrade_after`` then counts cycles for every servo: one that only the slow
        health reads ask (the default plan's trochanter, direction and wheel servos)
        would otherwise be degraded after that many of its reads, 2 s and more."""
        asked = {s.id for _, servos in due for s in servos}
        lists = {id(read): servos for read, servos in due}
        for sid in sorted(self.suspects):
            s = self.servos[sid]
            if not s.live or not s.failures:
                self.suspects.discard(sid)
            elif sid not in asked:
                lists.setdefault(id(self.reads[self.home[sid]]), []).append(s)
        return [(read, lists[id(read)]) for read in self.reads if id(read) in lists]

    def _account_writes(self, t: float, writes: Sequence[_Write], results: Sequence[int]) -> None:
        for w, result in zip(writes, results, strict=True):
            if result == COMM_SUCCESS:
                for sid, value in w.values.items():
                    s = self.servos[sid]
                    s.sent = value
                    s.addressed_at = t
                continue
            # Not sent: ``sent`` stays as it was, so these goals go out next cycle.
            self.counters["write_failures"] += 1
            self.emit(
                WriteFailed(
                    t=self.now(),
                    source=self.name,
                    register=w.register.name,
                    servos=len(w.values),
                    result=comm_name(result),
                )
            )

    async def _publish(
        self, t: float, values: Mapping[int, Mapping[str, int]], errors: Mapping[int, int]
    ) -> None:
        joints = []
        servos = self.servos
        center, rad_per_tick, rad_s_per_unit = _CENTER_TICKS, _RAD_PER_TICK, _RAD_S_PER_UNIT
        # The conversions of whexar.bus.control_table, inlined: 42 servos every cycle.
        for sid, regs in sorted(values.items()):
            get = regs.get
            pos = get("present_position")
            vel = get("present_velocity")
            cur = get("present_current")
            if cur is None:
                cur = get("present_load")
            if pos is None and vel is None and cur is None:
                continue
            s = servos[sid]
            joints.append(
                JointState(
                    s.leg,
                    s.joint,
                    sid,
                    None if pos is None else (pos - center) * rad_per_tick,
                    None if vel is None else vel * rad_s_per_unit,
                    None if cur is None else cur * s.current_unit,
                    bool(errors.get(sid, 0) & ALERT),
                )
            )
        await self.state.send(
            ServoStates(t=t, source=self.name, cycle=self.cycle, joints=tuple(joints))
        )
        if self.health.connected:
            for sid, regs in sorted(values.items()):
                volt = regs.get("present_input_voltage")
                temp = regs.get("present_temperature")
                hw = regs.get("hardware_error_status")
                if volt is None and temp is None and hw is None:
                    continue
                await self.health.send(
                    ServoHealth(
                        t=t,
                        source=self.name,
                        servo_id=sid,
                        voltage_v=None if volt is None else ct.voltage_to_v(volt),
                        temperature_c=temp,
                        hardware_error=hw,
                    )
                )

    def _account(self, outcome: _Outcome, values: Mapping[int, Mapping[str, int]]) -> None:
        for sid in values:
            self.servos[sid].failures = 0
        if self.suspects:
            self.suspects.difference_update(values)
        self.suspects.update(outcome.failed)
        for sid, kind in outcome.failed.items():
            s = self.servos[sid]
            s.failures += 1
            key = "timeouts" if kind == "timeout" else "corrupt" if kind == "corrupt" else None
            if key:
                self.counters[key] += 1
            self.emit(
                ServoFault(
                    t=self.now(),
                    source=self.name,
                    servo_id=sid,
                    kind=kind,
                    consecutive=s.failures,
                )
            )
            if s.failures >= self.cfg.bus.degrade_after and s.live:
                self._degrade(s, f"{s.failures} failed cycles in a row ({kind})")

    def _degrade(self, s: _Servo, reason: str) -> None:
        s.next_probe = self.now() + self.cfg.bus.probe_period_s
        if s.state == "degraded":  # a failed probe of a degraded servo: no new event
            return
        s.state = "degraded"
        self.emit(ServoDegraded(t=self.now(), source=self.name, servo_id=s.id, reason=reason))
        if s.critical:
            self._lose(f"{s.name} lost: {reason}")

    def _lose(self, reason: str) -> None:
        # Said once, and again only if the port goes too: a second lost servo while the
        # robot sits down changes nothing, a lost port ends the cycles.
        if not self.lost or self.port_lost:
            self.emit(BusLost(t=self.now(), source=self.name, reason=reason))
        self.lost = True
        self.request_safe_stop(reason)

    # ----------------------------------------------------------------- recovery

    async def _recover(
        self,
        owner: PortOwner,
        values: Mapping[int, Mapping[str, int]],
        errors: Mapping[int, int],
    ) -> bool:
        """Hardware errors, warnings, booting and degraded servos; True if the bus was used."""
        busy = False
        # Only servos with something to say: an Alert, error bits read, a standing warning.
        servos = self.servos
        suspects = {
            sid
            for sid, err in errors.items()
            if err & ALERT or (sid in values and servos[sid].warning)
        }
        suspects.update(sid for sid, regs in values.items() if regs.get("hardware_error_status"))
        for sid in sorted(suspects):
            s = self.servos[sid]
            if not s.live:
                continue
            alert = bool(errors.get(sid, 0) & ALERT)
            bits = values.get(sid, {}).get("hardware_error_status")
            now = self.now()
            if bits is None and alert and (not s.warning or now >= s.next_check):
                # An alert and no register read this cycle: ask the servo what it is
                # (again now and then while a warning stands: something may latch on top).
                reply = await owner.call(_read_job(sid, _HW_ERROR))
                busy = True
                bits = reply.value if reply.ok else None
                s.next_check = now + WARNING_RECHECK_S
            if bits is None:
                if not alert and sid in errors and s.warning:
                    bits = 0  # a clean status: the warning is over
                else:
                    continue
            self._warn(s, bits & ~s.shutdown)
            if bits & s.shutdown:
                await self._reboot(owner, s, bits)
                busy = True
        return await self._poll(owner) or busy

    def _warn(self, s: _Servo, bits: int) -> None:
        """Report a change of ``s``'s non-latching error bits."""
        if bits == s.warning:
            return
        changed = bits if bits else s.warning
        s.warning = bits
        self.emit(
            HardwareWarning(
                t=self.now(),
                source=self.name,
                servo_id=s.id,
                bits=changed,
                description=ct.HardwareError(changed).describe(),
                active=bool(bits),
            )
        )
        self._supply()

    def _supply(self) -> None:
        low = tuple(
            sorted(s.id for s in self.servos.values() if s.warning & ct.HardwareError.INPUT_VOLTAGE)
        )
        if low and not self.supply_low:
            self.supply_low = True
            self.emit(SupplyLow(t=self.now(), source=self.name, servo_ids=low))
        elif not low and self.supply_low:
            self.supply_low = False
            self.emit(SupplyRestored(t=self.now(), source=self.name))

    async def _reboot(self, owner: PortOwner, s: _Servo, bits: int) -> None:
        """Report and reboot ``s``; it boots while the cycle goes on (see :meth:`_poll`)."""
        self.emit(
            HardwareFault(
                t=self.now(),
                source=self.name,
                servo_id=s.id,
                bits=bits,
                description=ct.HardwareError(bits).describe(),
            )
        )
        reply = await owner.call(lambda bus: bus.reboot(s.id))
        self.emit(ServoRebooted(t=self.now(), source=self.name, servo_id=s.id, ok=reply.ok))
        s.state = "booting"
        s.warning = 0
        s.boot_deadline = self.now() + self.cfg.bus.boot_timeout_s
        s.next_probe = self.now() + BOOT_POLL_S

    def _probe_timeout_ms(self) -> float:
        """A probe's wait: within one nominal cycle, so a cycle takes at most two."""
        return max(MIN_PROBE_TIMEOUT_MS, 0.8 * self.nominal_s * 1000.0)

    async def _poll(self, owner: PortOwner) -> bool:
        """Ping the booting or degraded servo whose turn has come (one per cycle at most)."""
        now = self.now()
        # not s.live, inlined: every cycle, 42 servos
        waiting = [s for s in self.servos.values() if s.state != "ok" and now >= s.next_probe]
        if not waiting:
            return False
        s = min(waiting, key=lambda x: (x.next_probe, x.id))
        timeout = self._probe_timeout_ms()
        reply = await owner.call(lambda bus: bus.ping(s.id, timeout_ms=timeout))
        if s.state == "booting":
            if reply.ok:
                await self._after_boot(owner, s, reply.alert)
            elif self.now() >= s.boot_deadline:
                self._degrade_after_boot(
                    s, f"no answer {self.cfg.bus.boot_timeout_s:g} s after its reboot"
                )
            else:
                s.next_probe = self.now() + BOOT_POLL_S
            return True
        s.next_probe = self.now() + self.cfg.bus.probe_period_s
        if not reply.ok:
            return True
        if reply.alert:
            # A latched hardware error is rebooted first; the servo is back only if that
            # cleared it (the boot restores it), never while the error persists.
            bits = await owner.call(lambda bus: bus.read(s.id, _HW_ERROR))
            await self._reboot(owner, s, bits.value if bits.ok else 0)
            s.from_degraded = True
            return True
        if await self._restore(owner, s):
            self._recovered(s)
            await self._detect_fast(owner, f"{s.name} recovered")
        return True

    async def _after_boot(self, owner: PortOwner, s: _Servo, alert: bool) -> None:
        """``s`` answers after its reboot: restore it, unless its error came back."""
        if alert:
            bits = await owner.call(lambda bus: bus.read(s.id, _HW_ERROR))
            why = ct.HardwareError(bits.value).describe() if bits.ok else comm_name(bits.result)
            self._degrade_after_boot(s, f"hardware error persists after reboot ({why})")
            return
        if not await self._restore(owner, s):
            self._degrade_after_boot(s, "torque could not be re-enabled after reboot")
            return
        self.emit(ServoRestored(t=self.now(), source=self.name, servo_id=s.id))
        if s.from_degraded:
            self._recovered(s)
            await self._detect_fast(owner, f"{s.name} recovered")
        else:
            s.state = "ok"
            s.failures = 0

    def _degrade_after_boot(self, s: _Servo, reason: str) -> None:
        """A reboot did not bring ``s`` back: degraded (an event unless it already was)."""
        if s.from_degraded:  # it was degraded already: no new event
            s.state = "degraded"
        s.from_degraded = False
        self._degrade(s, reason)

    def _recovered(self, s: _Servo) -> None:
        s.state = "ok"
        s.failures = 0
        s.from_degraded = False
        self.emit(ServoRecovered(t=self.now(), source=self.name, servo_id=s.id))

    async def _restore(self, owner: PortOwner, s: _Servo) -> bool:
        """Write the servo's settings and goal again and enable its torque; True when it holds.

        EEPROM is read first and written only where it differs (a reboot keeps it);
        Bus Watchdog, goal and torque are RAM, lost in a reboot: written again.
        """
        mode = _MODE_VELOCITY if s.endless else _MODE_POSITION
        goal_reg = _GOAL_VELOCITY if s.endless else _GOAL_POSITION
        wanted = ((_RETURN_DELAY, self.rdt), (_OPERATING_MODE, mode))
        units = self.watchdog_units

        def restore(bus: DxlBus) -> bool:
            have = _read_all(bus, [s.id], _SETTINGS).get(s.id)
            if have is None:
                return False
            diff = [(reg, v) for reg, v in wanted if have[reg.name] != v]
            if diff:
                bus.write(s.id, _TORQUE, 0)
                for reg, value in diff:
                    bus.write(s.id, reg, value)
            if bus.read(s.id, _WATCHDOG).value == _WATCHDOG_ERROR:
                bus.write(s.id, _WATCHDOG, 0)
            if s.goal is not None:
                bus.write(s.id, goal_reg, s.goal)
            for _ in range(self.cfg.bus.torque_retries):
                if bus.write(s.id, _TORQUE, 1).ok and bus.read(s.id, _TORQUE).value == 1:
                    bus.write(s.id, _WATCHDOG, units)
                    return True
            return False

        ok = await owner.call(restore)
        if ok:
            s.sent = s.goal
            s.addressed_at = self.now()
        return ok

    # ----------------------------------------------------------------- statistics

    _stats_t = 0.0
    _stats_cycle = 0
    _stats_bytes = 0

    async def _report(self) -> None:
        if not self.stats.connected:
            return
        now = self.now()
        window = now - self._stats_t
        if window <= 0:
            return
        cycles = self.cycle - self._stats_cycle
        c = self.counters
        await self.stats.send(
            BusStats(
                t=now,
                source=self.name,
                cycles=self.cycle,
                rate_hz=cycles / window,
                bytes_per_cycle=(c["bytes"] - self._stats_bytes) / max(1, cycles),
                read_mode="fast_sync_read" if self.fast else "sync_read",
                retries=c["retries"],
                timeouts=c["timeouts"],
                corrupt=c["corrupt"],
                clamped=c["clamped"],
                degraded=tuple(sorted(s.id for s in self.servos.values() if not s.live)),
                write_failures=c["write_failures"],
            )
        )
        self._stats_t, self._stats_cycle, self._stats_bytes = now, self.cycle, c["bytes"]

    # ----------------------------------------------------------------- lifecycle

    async def run(self) -> None:
        self._setup()
        self.owner = self._open_owner()
        try:
            await self._start_up(self.owner)
            self.ready()
            self._stats_t, self._stats_cycle, self._stats_bytes = self.now(), 0, 0
            next_stats = self.now() + self.params.stats_period_s
            cap = self.plan.rate_hz
            next_cycle = self.now()
            # A lost servo: the cycles go on without it, for the safe stop the runtime now
            # makes (the coordinator sits the robot down with them; the bus then parks the
            # servos, which ends them). Stopped at once, the robot would be parked standing:
            # with bus.on_stop = torque_off, dropped on its belly.
            while not (self.port_lost or self.parked):
                started = self.clock.now()
                try:
                    await self._cycle(self.owner)
                except DeviceGoneError as exc:
                    self.port_lost = True
                    self._lose(f"servo port lost: {exc}")
                if self.lost:
                    # No cycle shorter than the nominal one while the robot sits down: a
                    # cycle can cost no bus time (a replay whose recording has no answer
                    # to the sit-down's packets), and the safe stop's time must go on.
                    await self.clock.sleep_until(started + max(self.nominal_s, MIN_CYCLE_S))
                if self.now() >= next_stats:
                    await self._report()
                    next_stats += self.params.stats_period_s
                if cap is not None:
                    next_cycle += 1.0 / cap
                    await self.clock.sleep_until(next_cycle)
            # Parked, or the port lost: nothing more to cycle; the runtime cancels us here.
            await anyio.sleep_forever()
        finally:
            with self.shielded():
                await self._park(self.cfg.bus.on_stop)
            self.owner.close()

    async def safe_stop(self, reason: str) -> None:
        """Servos to their shutdown state (``bus.on_stop``) before the runtime stops."""
        await self._park(self.cfg.bus.on_stop)

    async def _park(self, how: str) -> None:
        """Wheels to zero speed, then torque off (or hold, the watchdog disarmed), checked.

        The writes are read back (Goal Velocity of the wheels, Torque Enable) and sent once
        more where they did not take: a stop must stop, and a read behind the writes also
        makes sure they left the host before the port closes.
        """
        if self.port_lost:
            return
        live = [s for s in self.servos.values() if s.state != "degraded"]
        wheels = [s.id for s in live if s.endless]
        ids = [s.id for s in live]
        torque = 1 if how == "hold" else 0

        def park(bus: DxlBus) -> None:
            for _ in range(2):
                bus.sync_write(_GOAL_VELOCITY.address, 4, dict.fromkeys(wheels, _pack_i32(0)))
                if how == "hold":
                    bus.sync_write(_WATCHDOG.address, 1, dict.fromkeys(ids, b"\x00"))
                else:
                    bus.sync_write(_TORQUE.address, 1, dict.fromkeys(ids, b"\x00"))
                speeds = _read_all(bus, wheels, _WHEEL_GOAL)
                torques = _read_all(bus, ids, _TORQUE_SPAN)
                if all(v["goal_velocity"] == 0 for v in speeds.values()) and all(
                    v["torque_enable"] == torque for v in torques.values()
                ):
                    return

        self.parked = True
        try:
            await self.owner.call(park)
        except DeviceGoneError:
            self.port_lost = True
        for s in live:
            if s.endless:
                s.goal = s.sent = 0
