"""The bus scheduler: the only owner of the servo port, a thin shell around pure cores.

Theory of operation
-------------------
The control loop is bus-bound, so one actor plans every byte on the servo
bus and nothing else touches it. What to write, what to read and what a
failure means are decided by plain classes that take the time and what was
observed, and return what to write and what to say (:mod:`.goals`,
:mod:`.reads`, :mod:`.health`, :mod:`.startup`, :mod:`.stats`). This shell
owns the port, the clock and the channels: it receives, calls the cores,
does the port jobs they ask for (:mod:`.jobs`) and publishes. A cycle is:

1. take every goal that arrived since the last cycle, in order: the latest
   per joint wins, within the joint's limits (:class:`GoalPolicy`). Which
   source overrides which — a reflex over the gait — is the leg's decision,
   never the bus's: ``JointGoals.reflex`` changes nothing here;
2. run the reads the plan says are due, and again the servos whose last
   read failed (:class:`CycleReads`), each one Sync Read or Fast Sync Read
   (:class:`ReadMode`) of a contiguous register span;
3. Sync Write the goals that changed, and those of servos the Bus Watchdog
   would soon miss; a write that did not go out is sent again next cycle;
4. publish :class:`ServoStates` for the cycle, :class:`ServoHealth` for slow
   readings, and :class:`BusStats` once a period;
5. tell the health machine (:class:`HealthMachine`) what the reads saw,
   then do what it asks — read an error register, reboot, restore — and ping
   the booting or degraded servo whose turn has come. That is one ping per
   cycle at most, its timeout bounded by the nominal cycle time, so that no
   cycle takes more than twice its nominal time.

Steps 2 and 3 are one job for the port owner (:mod:`whexar.bus.sdk`): one
thread hop per cycle on a real port, exact wire time on the emulator.

Start-up (:mod:`.startup`) reads before it writes, so that a robot standing
under torque keeps standing through a restart; then the Bus Watchdog is
armed (``bus.watchdog_ms``): if this process dies, the servos stop by
themselves. Fast Sync Read is detected, never assumed.

A lost femur or tibia servo, or the port itself, asks the runtime for a
safe stop (:class:`BusLost`); after a lost servo the cycles go on without it
until the servos are parked, so that the coordinator can sit the robot down
first. On stop (and on a safe stop) the wheels are brought to zero speed,
then the servos end in ``bus.on_stop``: torque off by default, or holding
their last positions (with the watchdog disarmed, so a held robot stays held).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Final

import anyio
from pydantic import Field

from whexar.actors.bus.goals import GoalPolicy
from whexar.actors.bus.health import Effect, HealthMachine, Job, SafeStopRequest, Step
from whexar.actors.bus.jobs import (
    Request,
    clear_watchdog_job,
    configure_job,
    cycle_job,
    enable_job,
    fast_probe_job,
    gains_job,
    hold_job,
    park_job,
    ping_job,
    probe_job,
    read_job,
    reboot_job,
    restore_job,
    survey_job,
    watchdog_job,
)
from whexar.actors.bus.reads import CycleReads, ReadMode, decode, health_readings, joint_states
from whexar.actors.bus.servos import HARDWARE_ERROR, WATCHDOG_UNIT_S, Servo, servo_table
from whexar.actors.bus.startup import SURVEY, model_mismatches, plan_start
from whexar.actors.bus.stats import BusCounters, NominalCycle
from whexar.actors.messages import (
    BusStats,
    BusWarning,
    JointGoals,
    ServoHealth,
    ServoStates,
    WatchdogStopped,
)
from whexar.bus import control_table as ct
from whexar.bus import wire
from whexar.bus.emulator.faults import FaultPlanFile
from whexar.bus.plan import ReadPlan, resolve_plan
from whexar.bus.protocol import ALERT
from whexar.bus.replay import REPLAYED_BUS
from whexar.bus.sdk import (
    LATENCY_FIX,
    InlinePortOwner,
    PortOwner,
    ThreadPortOwner,
    latency_timer_ms,
    open_port,
    tap_port,
)
from whexar.config import ConfigFile, RobotConfig, load_config
from whexar.errors import DeviceError, DeviceGoneError
from whexar.runtime.actor import Actor, ActorParams, Input, Output
from whexar.runtime.devices import DEVICES

EMULATOR: Final = "emulator"
"""The port name of a fresh in-process servo emulator; ``emulator:NAME`` opens the chain
registered as NAME (:data:`~whexar.bus.emulator.chain.SERVO_CHAIN`)."""
START_RETRY_S: Final = 0.05
"""Pause between start-up ping rounds while servos are still booting."""


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
        native: bool = True
        """The cycle's transactions on the compiled path (:mod:`whexar.bus.wire`) where it
        is built; ``false``: dynamixel-sdk's for everything (the same results)."""

    params: Params
    goals = Input(JointGoals, optional=True)
    state = Output(ServoStates)
    health = Output(ServoHealth, optional=True)
    stats = Output(BusStats, optional=True)

    # ----------------------------------------------------------------- set-up

    def _setup(self) -> None:
        p = self.params
        self.cfg: RobotConfig = load_config(p.config) if p.config else RobotConfig()
        bus = self.cfg.bus
        self.plan: ReadPlan = resolve_plan(p.plan if p.plan is not None else bus.plan)
        self.servos: dict[int, Servo] = servo_table(self.cfg)
        self.ordered = sorted(self.servos.values(), key=lambda s: s.id)
        # Return Delay Time register value (2 µs units), written at start and on restore.
        self.rdt = ct.return_delay_units(bus.return_delay_time_us * 1e-6)
        self.watchdog_units = round(bus.watchdog_ms / 1000 / WATCHDOG_UNIT_S)
        # Every servo hears a packet at least twice per watchdog period.
        keepalive_s = self.watchdog_units * WATCHDOG_UNIT_S / 2 or math.inf
        self.policy = GoalPolicy(self.servos, self.name, keepalive_s)
        self.machine = HealthMachine(
            self.servos,
            self.name,
            degrade_after=bus.degrade_after,
            probe_period_s=bus.probe_period_s,
            boot_timeout_s=bus.boot_timeout_s,
        )
        self.reading = CycleReads(self.plan, self.ordered)
        self.mode = ReadMode(self.plan.fast_sync_read, self.name)
        self.counters = BusCounters(self.name)
        self.nominal = NominalCycle()
        self.port_lost = False
        """The port is gone: no more cycles, nothing to park."""
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
            return InlinePortOwner(played, self.clock, native=self.params.native)
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
            return InlinePortOwner(port, self.clock, native=self.params.native)
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
        return ThreadPortOwner(real, native=self.params.native)

    def _effects(self, effects: Iterable[Effect]) -> None:
        """Publish what a core decided, in its order: events, and safe-stop requests."""
        for effect in effects:
            if isinstance(effect, SafeStopRequest):
                self.request_safe_stop(effect.reason)
            else:
                self.emit(effect)

    # ----------------------------------------------------------------- start-up

    async def _start_up(self, owner: PortOwner) -> None:
        servos = self.ordered
        await self._ping_all(owner, servos)
        ids = [s.id for s in servos]
        survey = await owner.call(survey_job(ids, SURVEY))
        silent = [s.name for s in servos if s.id not in survey]
        if silent:
            raise DeviceGoneError(f"no answer reading the settings of {', '.join(silent)}")
        plan = plan_start(servos, survey, self.rdt)
        for s in servos:
            s.speed_limit = plan.speed_limits[s.id]
            s.shutdown = plan.shutdowns[s.id]
        if plan.stopped:
            self.emit(WatchdogStopped(t=self.now(), source=self.name, servo_ids=plan.stopped))
            await owner.call(clear_watchdog_job(plan.stopped))
        # EEPROM (torque off first), then the position gains (RAM, under torque).
        for changes, job in ((plan.changes, configure_job), (plan.gains, gains_job)):
            if changes:
                names = {sid: self.servos[sid].name for sid in changes}
                problems = await owner.call(job(changes, names))
                if problems:
                    raise DeviceError("servo set-up failed: " + "; ".join(problems))
        await self._detect_fast(owner, "start-up", report=True)
        policy = self.policy
        self._effects(policy.start(self.now(), plan.start_ticks))
        # Servos that hold on: a position goal goes out only if it had to change.
        moved, wheels = plan.hold_writes({sid: slot.goal for sid, slot in policy.slots.items()})
        await owner.call(hold_job(moved, wheels))
        policy.holding(plan.holding_ids)
        if plan.limp:
            await self._enable_torque(owner, [self.servos[sid] for sid in plan.limp])
        await owner.call(watchdog_job(ids, self.watchdog_units))
        policy.addressed(ids, self.now())

    async def _ping_all(self, owner: PortOwner, servos: Sequence[Servo]) -> None:
        """Ping every servo, in rounds while some are still booting (``bus.boot_timeout_s``)."""
        deadline = self.now() + self.cfg.bus.boot_timeout_s
        todo = list(servos)
        while True:
            pings = await owner.call(ping_job([s.id for s in todo]))
            wrong = model_mismatches(todo, pings)
            if wrong:
                raise DeviceError("servo model mismatch: " + "; ".join(wrong))
            todo = [s for s in todo if not pings[s.id].ok]
            if not todo:
                return
            if self.now() >= deadline:
                names = ", ".join(s.name for s in todo)
                raise DeviceGoneError(f"no answer at start-up from {names}")
            await self.clock.sleep(START_RETRY_S)

    async def _enable_torque(self, owner: PortOwner, servos: Sequence[Servo]) -> None:
        """Hold each joint where it is (:func:`~.jobs.enable_job`), then torque on, verified,
        with retries."""
        attempts = self.cfg.bus.torque_retries
        slots = self.policy.slots
        todo = list(servos)
        for _ in range(attempts):
            check, goals = await owner.call(enable_job([(s, slots[s.id].goal) for s in todo]))
            self.policy.holding([s.id for s in todo], goals)
            todo = [s for s in todo if check.data.get(s.id, b"\x00")[0] != 1]
            if not todo:
                return
        names = ", ".join(s.name for s in todo)
        raise DeviceError(f"torque could not be enabled on {names} after {attempts} attempts")

    async def _detect_fast(self, owner: PortOwner, why: str, *, report: bool = False) -> None:
        """Try Fast Sync Read of the first read; keep it only if it works (``auto`` plans)."""
        if not self.mode.detects:
            return
        ids = self.reading.first_ids(self.machine.out)
        works = await owner.call(fast_probe_job(ids, self.reading.reads[0].block))
        self._effects(self.mode.detected(self.now(), works, why, report=report))

    # ----------------------------------------------------------------- the cycle

    async def _cycle(self, owner: PortOwner) -> None:
        t = self.now()
        policy, machine = self.policy, self.machine
        if self.goals.connected:
            self._effects(policy.take(t, self.goals.drain()))
        due = self.reading.due(t, machine.out, machine.to_ask())
        requests = [
            Request(r.block.start, r.block.length, tuple(s.id for s in servos)) for r, servos in due
        ]
        writes = policy.writes(t, machine.out)
        outcome = await owner.call(
            cycle_job(requests, self.mode.fast, self.cfg.bus.retries, writes)
        )
        self.counters.cycled(outcome.retries, outcome.bytes)
        policy.addressed((s.id for _, servos in due for s in servos), t)
        self._effects(policy.written(t, self.now(), writes, outcome.write_results))
        self._effects(self.mode.cycled(self.now(), outcome.fast_failures))
        values, errors = decode(due, outcome.reads)
        await self._publish(t, values, errors)
        self._effects(machine.account(self.now(), values, outcome.failed))
        healthy = not outcome.failed and not outcome.retries
        busy = await self._recover(owner, values, errors)
        if healthy and not busy:
            self.nominal.healthy(self.now() - t)

    async def _publish(
        self, t: float, values: Mapping[int, Mapping[str, int]], errors: Mapping[int, int]
    ) -> None:
        joints = joint_states(self.servos, values, errors)
        await self.state.send(
            ServoStates(t=t, source=self.name, cycle=self.counters.cycles, joints=joints)
        )
        if self.health.connected:
            for reading in health_readings(t, self.name, values):
                await self.health.send(reading)

    # ----------------------------------------------------------------- recovery

    async def _recover(
        self,
        owner: PortOwner,
        values: Mapping[int, Mapping[str, int]],
        errors: Mapping[int, int],
    ) -> bool:
        """Hardware errors, warnings, booting and degraded servos; True if the bus was used."""
        machine = self.machine
        busy = False
        for sid in machine.to_check(values, errors):
            alert = bool(errors.get(sid, 0) & ALERT)
            bits = values.get(sid, {}).get("hardware_error_status")
            if machine.wants_error_read(self.now(), sid, alert, bits):
                # An alert and no register read this cycle: ask the servo what it is.
                reply = await owner.call(read_job(sid, HARDWARE_ERROR))
                busy = True
                bits = reply.value if reply.ok else None
            step = machine.error_status(self.now(), sid, bits, alert, sid in errors)
            busy = await self._perform(owner, sid, step) or busy
        return await self._poll(owner) or busy

    async def _poll(self, owner: PortOwner) -> bool:
        """Ping the booting or degraded servo whose turn has come (one per cycle at most)."""
        sid = self.machine.due(self.now())
        if sid is None:
            return False
        reply = await owner.call(probe_job(sid, self.nominal.probe_timeout_ms))
        await self._perform(owner, sid, self.machine.pinged(self.now(), sid, reply))
        return True

    async def _perform(self, owner: PortOwner, sid: int, step: Step) -> bool:
        """Publish ``step``'s effects and do its job, then the steps that follow from the
        job's result, until one asks for no more; True if the bus was used."""
        machine = self.machine
        used = False
        while True:
            self._effects(step.effects)
            if step.job is None:
                return used
            used = True
            if step.job is Job.REBOOT:
                reply = await owner.call(reboot_job(sid))
                step = machine.rebooted(self.now(), sid, reply)
            elif step.job is Job.READ_ERROR:
                reply = await owner.call(read_job(sid, HARDWARE_ERROR))
                step = machine.error_read(self.now(), sid, reply)
            elif step.job is Job.RESTORE:
                ok = await self._restore(owner, sid)
                step = machine.restored(self.now(), sid, ok)
            else:  # Job.DETECT_FAST: a servo is back
                await self._detect_fast(owner, f"{self.servos[sid].name} recovered")
                return used

    async def _restore(self, owner: PortOwner, sid: int) -> bool:
        """Settings, goal and torque of servo ``sid`` again (:func:`~.jobs.restore_job`)."""
        job = restore_job(
            self.servos[sid],
            self.policy.slots[sid].goal,
            self.rdt,
            self.watchdog_units,
            self.cfg.bus.torque_retries,
        )
        ok = await owner.call(job)
        if ok:
            self.policy.restored(sid, self.now())
        return ok

    # ----------------------------------------------------------------- statistics

    async def _report(self) -> None:
        if not self.stats.connected:
            return
        machine, policy = self.machine, self.policy
        stats = self.counters.report(
            self.now(),
            read_mode=self.mode.name,
            timeouts=machine.timeouts,
            corrupt=machine.corrupt,
            clamped=policy.clamped,
            write_failures=policy.write_failures,
            degraded=machine.out,
        )
        if stats is not None:
            await self.stats.send(stats)

    # ----------------------------------------------------------------- lifecycle

    async def run(self) -> None:
        self._setup()
        self.owner = self._open_owner()
        if self.params.native and wire.NATIVE is None:  # said once, at start; then the SDK's
            self.emit(BusWarning(t=self.now(), source=self.name, message=wire.why_not()))
        try:
            await self._start_up(self.owner)
            self.ready()
            self.counters.start(self.now())
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
                    reason = f"servo port lost: {exc}"
                    self._effects(self.machine.lose(self.now(), reason, port=True))
                if self.machine.lost:
                    # No cycle shorter than the nominal one while the robot sits down: a
                    # cycle can cost no bus time (a replay whose recording has no answer
                    # to the sit-down's packets), and the safe stop's time must go on.
                    await self.clock.sleep_until(started + self.nominal.paced_s)
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
        """Wheels to zero speed, then torque off (or hold, the watchdog disarmed), checked
        (:func:`~.jobs.park_job`); the degraded servos are left alone."""
        if self.port_lost:
            return
        live = self.machine.reachable()
        wheels = [s.id for s in live if s.endless]
        self.parked = True
        try:
            await self.owner.call(park_job(wheels, [s.id for s in live], hold=how == "hold"))
        except DeviceGoneError:
            self.port_lost = True
        self.policy.stopped(wheels)
