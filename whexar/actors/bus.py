"""The bus scheduler: the only owner of the servo port.

Theory of operation
-------------------
The control loop is bus-bound, so one actor plans every byte on the servo
bus and nothing else touches it. A cycle is:

1. take every goal that arrived since the last cycle — the latest per joint
   wins — and clamp it to the joint's limits (a clamped goal is an event;
   nothing outside the limits reaches the wire);
2. run the reads the plan says are due (:mod:`whexar.bus.plan`), each one
   Sync Read or Fast Sync Read of a contiguous register span;
3. Sync Write the goals that changed (positions; wheel speeds separately);
4. publish :class:`ServoStates` for the cycle, :class:`ServoHealth` for slow
   readings, and :class:`BusStats` once a second.

Steps 2 and 3 are one job for the port owner (:mod:`whexar.bus.sdk`): one
thread hop per cycle on a real port, exact wire time on the emulator.

Start-up pings every configured servo and checks its model, turns torque
off to write Return Delay Time and the operating mode, detects Fast Sync
Read (never assumed: MX support is unconfirmed), sets each goal to the
present position and enables torque with retries.

Failures, after ROBOTIS's ros2_control hardware interface:

* a failed read is retried (``bus.retries``) from the servo that failed,
  and counted; a servo failing ``bus.degrade_after`` cycles in a row is
  *degraded*: left out of the cycle and pinged every ``probe_period_s``
  until it answers, when its settings are restored;
* a status packet with the Alert bit, or a non-zero Hardware Error Status
  read, means a hardware error: the servo is rebooted, its settings and goal
  restored and its torque re-enabled, each step an event;
* Fast Sync Read that fails where Sync Read succeeds three times in a row
  falls back to Sync Read; it is detected again after a servo recovers;
* losing a femur or tibia servo (the legs cannot carry the body), or the
  port itself, is :class:`BusLost` and asks the runtime for a safe stop.

On stop (and on a safe stop) the servos end in ``bus.on_stop``: torque off
by default, or holding their last goals.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final

import anyio
from pydantic import Field

from whexar.actors.messages import (
    BusLost,
    BusStats,
    BusWarning,
    GoalClamped,
    HardwareFault,
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
)
from whexar.bus import control_table as ct
from whexar.bus.emulator.faults import FaultPlanFile
from whexar.bus.plan import PlanRead, ReadPlan, resolve_plan
from whexar.bus.protocol import ALERT, sync_read_bytes, sync_write_bytes
from whexar.bus.sdk import (
    COMM_SUCCESS,
    LATENCY_FIX,
    DxlBus,
    InlinePortOwner,
    PortOwner,
    SyncReadResult,
    ThreadPortOwner,
    comm_name,
    latency_timer_ms,
    open_port,
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

_REG_POSITION = ct.MODELS["MX-64"].register("present_position")
_TORQUE = ct.MODELS["MX-64"].register("torque_enable")
_HW_ERROR = ct.MODELS["MX-64"].register("hardware_error_status")
_GOAL_POSITION = ct.MODELS["MX-64"].register("goal_position")
_GOAL_VELOCITY = ct.MODELS["MX-64"].register("goal_velocity")
_RETURN_DELAY = ct.MODELS["MX-64"].register("return_delay_time")
_OPERATING_MODE = ct.MODELS["MX-64"].register("operating_mode")
_pack_i32 = struct.Struct("<i").pack
"""Goal Position/Velocity bytes (signed 32-bit, little-endian); goals are clamped first."""
_MODE_VELOCITY: Final = 1
_MODE_POSITION: Final = 3
"""Operating Mode (11): 1 velocity control (the wheel), 3 position control (e-manual)."""


@dataclass(slots=True)
class _Servo:
    id: int
    leg: int
    joint: int
    model: ct.ServoModel
    endless: bool
    lo: float
    hi: float
    """Clamp range (rad): the joint's limits within what Goal Position can express."""
    critical: bool
    failures: int = 0
    degraded: bool = False
    next_probe: float = 0.0
    goal: int | None = None
    """The goal to hold: ticks (position joints) or velocity units (the wheel)."""
    sent: int | None = None

    @property
    def name(self) -> str:
        return f"servo {self.id} ({LEG_NAMES[self.leg]} {JOINT_NAMES[self.joint]})"


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
        live = [s for s in self.servos if not s.degraded]
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
class _Outcome:
    """What the port owner did in one cycle (built in the port's thread, read on the loop)."""

    reads: list[SyncReadResult] = field(default_factory=list)
    failed: dict[int, str] = field(default_factory=dict)
    retries: int = 0
    fast_failures: int = 0
    bytes: int = 0
    write_results: list[int] = field(default_factory=list)


def _cycle_job(
    requests: Sequence[_Request],
    fast: bool,
    retries: int,
    writes: Sequence[tuple[int, int, dict[int, bytes]]],
) -> Callable[[DxlBus], _Outcome]:
    """The port-side half of a cycle: the due reads (with retries), then the goal writes."""

    def job(bus: DxlBus) -> _Outcome:
        out = _Outcome()
        for req in requests:
            merged = SyncReadResult(COMM_SUCCESS)
            remaining = list(req.ids)
            use_fast = fast
            attempts = 0
            while remaining:
                res = bus.sync_read(remaining, req.start, req.length, fast=use_fast)
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
        for start, length, values in writes:
            if values:
                out.write_results.append(bus.sync_write(start, length, values))
                out.bytes += sync_write_bytes(len(values), length)
        return out

    return job


def _enable_job(servos: Sequence[_Servo]) -> Callable[[DxlBus], SyncReadResult]:
    """Write each goal (so torque-on holds still), torque on, and read Torque Enable back."""
    pos = {s.id: _pack_i32(s.goal or 0) for s in servos if not s.endless}
    vel = {s.id: _pack_i32(s.goal or 0) for s in servos if s.endless}
    ids = [s.id for s in servos]

    def job(bus: DxlBus) -> SyncReadResult:
        bus.sync_write(_GOAL_POSITION.address, 4, pos)
        bus.sync_write(_GOAL_VELOCITY.address, 4, vel)
        bus.sync_write(_TORQUE.address, 1, dict.fromkeys(ids, b"\x01"))
        return bus.sync_read(ids, _TORQUE.address, 1)

    return job


class BusScheduler(Actor):
    """Owns the servo port: reads per the plan, writes goals, recovers servos."""

    class Params(ActorParams):
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults (= config/whexar.toml)."""
        port: str | None = None
        """Overrides ``bus.port``: a device, a pty, ``emulator`` or ``emulator:NAME``."""
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
                # Goal Position spans one turn, 0…4095 around the centre (2048).
                lo = max(limits[0], ct.ticks_to_rad(0)) if limits else -math.inf
                hi = min(limits[1], ct.ticks_to_rad(ct.TICKS_PER_REV - 1)) if limits else math.inf
                self.servos[sid] = _Servo(
                    sid,
                    leg,
                    j,
                    ct.model(joint.model),
                    joint.endless,
                    lo,
                    hi,
                    JOINT_NAMES[j] in CRITICAL_JOINTS,
                )
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
        self.fast = self.plan.fast_sync_read == "on"
        self.fast_streak = 0
        self.cycle = 0
        self.counters = {"retries": 0, "timeouts": 0, "corrupt": 0, "clamped": 0, "bytes": 0}
        # Return Delay Time register value (2 µs units), written at start and on restore.
        self.rdt = ct.return_delay_units(self.cfg.bus.return_delay_time_us * 1e-6)
        self.port_lost = False
        self.lost = False
        """Set with :class:`BusLost`: the cycle stops; only the safe stop touches the bus."""

    def _open_owner(self) -> PortOwner:
        name = self.params.port or self.cfg.bus.port
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
            return InlinePortOwner(port, self.clock)
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
        return ThreadPortOwner(open_port(name, self.cfg.bus.baudrate))

    async def _start_up(self, owner: PortOwner) -> None:
        servos = sorted(self.servos.values(), key=lambda s: s.id)
        ids = [s.id for s in servos]
        pings = await owner.call(lambda bus: {i: bus.ping(i) for i in ids})
        missing = [self.servos[i].name for i, r in pings.items() if not r.ok]
        if missing:
            raise DeviceGoneError(f"no answer at start-up from {', '.join(missing)}")
        wrong = [
            f"{s.name} is a {ct.model_name(pings[s.id].value)} (model {pings[s.id].value}); "
            f"the configuration says {s.model.name} (model {s.model.model_number})"
            for s in servos
            if pings[s.id].value != s.model.model_number
        ]
        if wrong:
            raise DeviceError("servo model mismatch: " + "; ".join(wrong))
        rdt = self.rdt

        def configure(bus: DxlBus) -> list[str]:
            problems = []
            bus.sync_write(_TORQUE.address, 1, dict.fromkeys(ids, b"\x00"))  # EEPROM needs it
            for s in servos:
                mode = _MODE_VELOCITY if s.endless else _MODE_POSITION
                for reg, value in ((_RETURN_DELAY, rdt), (_OPERATING_MODE, mode)):
                    reply = bus.write(s.id, reg, value)
                    if not reply.ok or reply.error & ~ALERT:
                        problems.append(f"{s.name}: writing {reg.name} = {value} failed")
            return problems

        problems = await owner.call(configure)
        if problems:
            raise DeviceError("servo set-up failed: " + "; ".join(problems))
        await self._detect_fast(owner, "start-up")
        positions = await owner.call(
            lambda bus: bus.sync_read(ids, _REG_POSITION.address, _REG_POSITION.size)
        )
        if not positions.ok:
            raise DeviceGoneError(
                f"reading present positions at start-up: {comm_name(positions.result)} "
                f"at servo {positions.failed}"
            )
        for s in servos:
            s.goal = 0 if s.endless else _REG_POSITION.decode(positions.data[s.id], 132)
            s.sent = None
        await self._enable_torque(owner, servos)

    async def _enable_torque(self, owner: PortOwner, servos: Sequence[_Servo]) -> None:
        """Write each goal (so torque-on holds still), then torque on, verified, with retries."""
        attempts = self.cfg.bus.torque_retries
        todo = list(servos)
        for _ in range(attempts):
            check = await owner.call(_enable_job(todo))
            for s in todo:
                s.sent = s.goal
            todo = [s for s in todo if check.data.get(s.id, b"\x00")[0] != 1]
            if not todo:
                return
        names = ", ".join(s.name for s in todo)
        raise DeviceError(f"torque could not be enabled on {names} after {attempts} attempts")

    async def _detect_fast(self, owner: PortOwner, why: str) -> None:
        """Try Fast Sync Read of the first read; keep it only if it works (``auto`` plans)."""
        if self.plan.fast_sync_read != "auto":
            return
        first = self.reads[0]
        ids = [s.id for s in first.servos if not s.degraded]
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

    # ----------------------------------------------------------------- the cycle

    def _take_goals(self) -> None:
        inbox = self.goals
        if not inbox.connected:
            return
        for msg in inbox.drain():
            for g in msg.goals:
                servo = self.by_joint.get((g.leg, g.joint))
                if servo is None:
                    continue
                if servo.endless:
                    if g.velocity_rad_s is not None and math.isfinite(g.velocity_rad_s):
                        servo.goal = ct.rad_s_to_velocity(g.velocity_rad_s)
                    continue
                want = g.position_rad
                if want is None or math.isnan(want):
                    continue
                sent = min(max(want, servo.lo), servo.hi)
                if sent != want:
                    self.counters["clamped"] += 1
                    self.emit(
                        GoalClamped(
                            t=self.now(),
                            source=self.name,
                            servo_id=servo.id,
                            requested_rad=want,
                            sent_rad=sent,
                        )
                    )
                servo.goal = ct.rad_to_ticks(sent)

    def _writes(self) -> list[tuple[int, int, dict[int, bytes]]]:
        pos: dict[int, bytes] = {}
        vel: dict[int, bytes] = {}
        for s in self.servos.values():
            if s.degraded or s.goal is None or s.goal == s.sent:
                continue
            if s.endless:
                vel[s.id] = _pack_i32(s.goal)
            else:
                pos[s.id] = _pack_i32(s.goal)
            s.sent = s.goal
        return [(_GOAL_POSITION.address, 4, pos), (_GOAL_VELOCITY.address, 4, vel)]

    async def _cycle(self, owner: PortOwner) -> None:
        t = self.now()
        self._take_goals()
        due: list[tuple[_Read, list[_Servo]]] = []
        for read in self.reads:
            servos = read.take(t)
            if servos:
                due.append((read, servos))
        requests = [
            _Request(r.block.start, r.block.length, tuple(s.id for s in servos))
            for r, servos in due
        ]
        outcome = await owner.call(
            _cycle_job(requests, self.fast, self.cfg.bus.retries, self._writes())
        )
        self.cycle += 1
        self.counters["retries"] += outcome.retries
        self.counters["bytes"] += outcome.bytes
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
            for sid, data in res.data.items():
                decoded = read.block.decode(data)
                if sid in values:
                    values[sid].update(decoded)
                else:
                    values[sid] = decoded
            errors.update(res.errors)
        await self._publish(t, values, errors)
        self._account(outcome, values)
        await self._recover(owner, values, errors)

    async def _publish(
        self, t: float, values: Mapping[int, Mapping[str, int]], errors: Mapping[int, int]
    ) -> None:
        joints = []
        for sid, regs in sorted(values.items()):
            s = self.servos[sid]
            pos = regs.get("present_position")
            vel = regs.get("present_velocity")
            cur = regs.get("present_current", regs.get("present_load"))
            if pos is None and vel is None and cur is None:
                continue
            joints.append(
                JointState(
                    s.leg,
                    s.joint,
                    sid,
                    None if pos is None else ct.ticks_to_rad(pos),
                    None if vel is None else ct.velocity_to_rad_s(vel),
                    None if cur is None else ct.current_to_a(cur, s.model),
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
            if s.failures >= self.cfg.bus.degrade_after and not s.degraded:
                self._degrade(s, f"{s.failures} failed cycles in a row ({kind})")

    def _degrade(self, s: _Servo, reason: str) -> None:
        s.next_probe = self.now() + self.cfg.bus.probe_period_s
        if s.degraded:  # a failed probe of a degraded servo: it stays degraded, no new event
            return
        s.degraded = True
        self.emit(ServoDegraded(t=self.now(), source=self.name, servo_id=s.id, reason=reason))
        if s.critical:
            self._lose(f"{s.name} lost: {reason}")

    def _lose(self, reason: str) -> None:
        self.lost = True
        self.emit(BusLost(t=self.now(), source=self.name, reason=reason))
        self.request_safe_stop(reason)

    async def _recover(
        self,
        owner: PortOwner,
        values: Mapping[int, Mapping[str, int]],
        errors: Mapping[int, int],
    ) -> None:
        # Hardware errors: the Alert bit of any status, or a non-zero register 70.
        suspects = sorted(
            {sid for sid, err in errors.items() if err & ALERT}
            | {sid for sid, regs in values.items() if regs.get("hardware_error_status")}
        )
        for sid in suspects:
            s = self.servos[sid]
            if not s.degraded:
                await self._reboot(owner, s)
        now = self.now()
        for s in self.servos.values():
            if s.degraded and now >= s.next_probe:
                s.next_probe = now + self.cfg.bus.probe_period_s
                await self._probe(owner, s)

    async def _reboot(self, owner: PortOwner, s: _Servo) -> bool:
        """Report, reboot and restore ``s``; True when its error cleared and it holds again."""
        bits = await owner.call(lambda bus: bus.read(s.id, _HW_ERROR))
        value = bits.value if bits.ok else 0
        self.emit(
            HardwareFault(
                t=self.now(),
                source=self.name,
                servo_id=s.id,
                bits=value,
                description=ct.HardwareError(value).describe(),
            )
        )
        reply = await owner.call(lambda bus: bus.reboot(s.id))
        self.emit(ServoRebooted(t=self.now(), source=self.name, servo_id=s.id, ok=reply.ok))
        after = await owner.call(lambda bus: bus.read(s.id, _HW_ERROR))
        if not after.ok or after.value:
            why = (
                comm_name(after.result)
                if not after.ok
                else ct.HardwareError(after.value).describe()
            )
            self._degrade(s, f"hardware error persists after reboot ({why})")
            return False
        if await self._restore(owner, s):
            self.emit(ServoRestored(t=self.now(), source=self.name, servo_id=s.id))
            return True
        self._degrade(s, "torque could not be re-enabled after reboot")
        return False

    async def _restore(self, owner: PortOwner, s: _Servo) -> bool:
        """Write the servo's settings and goal again and enable its torque; True when it holds."""
        rdt = self.rdt
        mode = _MODE_VELOCITY if s.endless else _MODE_POSITION
        goal_reg = _GOAL_VELOCITY if s.endless else _GOAL_POSITION

        def restore(bus: DxlBus) -> bool:
            bus.write(s.id, _TORQUE, 0)
            bus.write(s.id, _RETURN_DELAY, rdt)
            bus.write(s.id, _OPERATING_MODE, mode)
            if s.goal is not None:
                bus.write(s.id, goal_reg, s.goal)
            for _ in range(self.cfg.bus.torque_retries):
                if bus.write(s.id, _TORQUE, 1).ok and bus.read(s.id, _TORQUE).value == 1:
                    return True
            return False

        ok = await owner.call(restore)
        if ok:
            s.sent = s.goal
        return ok

    async def _probe(self, owner: PortOwner, s: _Servo) -> None:
        reply = await owner.call(lambda bus: bus.ping(s.id))
        if not reply.ok:
            return
        # A latched hardware error is rebooted first; the servo is back only if that cleared
        # it (the reboot restores it), never while the error persists.
        restored = await self._reboot(owner, s) if reply.alert else await self._restore(owner, s)
        if restored:
            s.degraded = False
            s.failures = 0
            self.emit(ServoRecovered(t=self.now(), source=self.name, servo_id=s.id))
            await self._detect_fast(owner, f"{s.name} recovered")

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
                degraded=tuple(sorted(s.id for s in self.servos.values() if s.degraded)),
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
            while not self.lost:
                try:
                    await self._cycle(self.owner)
                except DeviceGoneError as exc:
                    self.port_lost = True
                    self._lose(f"servo port lost: {exc}")
                if self.now() >= next_stats:
                    await self._report()
                    next_stats += self.params.stats_period_s
                if cap is not None:
                    next_cycle += 1.0 / cap
                    await self.clock.sleep_until(next_cycle)
            # Lost: no more cycles (a restore could re-enable torque); the
            # runtime's safe stop parks the servos, then cancels us here.
            await anyio.sleep_forever()
        finally:
            with self.shielded():
                await self._park(self.cfg.bus.on_stop)
            self.owner.close()

    async def safe_stop(self, reason: str) -> None:
        """Servos to their shutdown state (``bus.on_stop``) before the runtime stops."""
        await self._park(self.cfg.bus.on_stop)

    async def _park(self, how: str) -> None:
        if self.port_lost or how == "hold":
            return
        ids = dict.fromkeys((s.id for s in self.servos.values() if not s.degraded), b"\x00")
        try:
            await self.owner.call(lambda bus: bus.sync_write(_TORQUE.address, 1, ids))
        except DeviceGoneError:
            self.port_lost = True
