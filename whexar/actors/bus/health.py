"""The servo health machine: which servos are in the cycle, and what to do about the others.

Theory of operation
-------------------
Each servo is in one :class:`State`. What the bus observes of it — a cycle's
reads, a ping, an error register read, the outcome of a reboot or a restore —
is a :class:`Seen`, and :data:`TRANSITIONS` says, for each (state, seen),
the next state and the :class:`Action` s to take, in order. Nothing else
changes a state. The methods of :class:`HealthMachine` turn what the shell
observed into a :class:`Seen`, apply the table and return a :class:`Step`:
the effects to publish, in order (events, and a :class:`SafeStopRequest`),
and at most one port :class:`Job` for the shell to do next — whose result
it reports back through the method named after it (:meth:`rebooted`,
:meth:`error_read`, :meth:`restored`). The machine does no I/O, reads no
clock (each method takes ``now``) and awaits nothing.

Failures, after ROBOTIS's ros2_control hardware interface:

* a servo whose reads fail ``bus.degrade_after`` cycles in a row
  (:meth:`HealthMachine.account`) is *degraded*: left out of the cycle and
  pinged every ``bus.probe_period_s``; one that answers is restored (settings,
  goal, torque) and *recovered*;
* a status packet with the Alert bit, or a non-zero Hardware Error Status
  read, is classified by the servo's Shutdown mask
  (:meth:`HealthMachine.error_status`). A bit in the mask (overload,
  overheating, electrical shock by default) latched and turned torque off:
  the servo is rebooted. It is silent while it boots (about 0.4 s,
  ROBOTIS-GIT/emanual issue #1698; the emulator models it): it is *booting*,
  out of the cycle and polled until it answers (then restored) or
  ``bus.boot_timeout_s`` passes (then degraded). A degraded servo whose probe
  finds a latched error is rebooted the same way (*recovering*): back, it is
  recovered, never while the error persists. A bit outside the mask (input
  voltage, by default) does not latch: the servo keeps its torque, the bit is
  reported (:class:`HardwareWarning`, and :class:`SupplyLow` for the bus) and
  clears by itself when the supply is back — no reboot, no state;
* losing a femur or tibia servo (the legs cannot carry the body), or the
  port itself (:meth:`HealthMachine.lose`), is :class:`BusLost` and a safe
  stop; said once, and again only for the port.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import Final, TypeAlias

from whexar.actors.bus.servos import Servo
from whexar.actors.messages import (
    BusLost,
    HardwareFault,
    HardwareWarning,
    ServoDegraded,
    ServoFault,
    ServoRebooted,
    ServoRecovered,
    ServoRestored,
    SupplyLow,
    SupplyRestored,
)
from whexar.bus import control_table as ct
from whexar.bus.protocol import ALERT
from whexar.bus.sdk import Reply, comm_name
from whexar.runtime.messages import Event

WARNING_RECHECK_S: Final = 0.1
"""While a servo's non-latching error stands, how often an Alert makes it be read again
(a latching error on top of it is seen within this)."""
BOOT_POLL_S: Final = 0.05
"""How often a rebooted servo is pinged while it boots (one ping per cycle at most)."""


class State(Enum):
    """Where a servo stands; only :attr:`OK` servos are in the cycle."""

    OK = "ok"
    """In the cycle: read per the plan, written its goals."""
    BOOTING = "booting"
    """Rebooted after a latched error; polled until it answers, then restored."""
    RECOVERING = "recovering"
    """Rebooted from :attr:`DEGRADED` (its probe found a latched error); back, recovered."""
    DEGRADED = "degraded"
    """Left out; probed every ``bus.probe_period_s``."""


class Seen(Enum):
    """What the bus observed of a servo."""

    FAILING = "failing"
    """Its reads failed ``bus.degrade_after`` cycles in a row."""
    LATCHED = "latched"
    """Its Hardware Error Status has a bit of its Shutdown mask (torque is off)."""
    REBOOTED = "rebooted"
    """The Reboot instruction went out (answered or not)."""
    ANSWERED = "answered"
    """A ping answered, without the Alert bit."""
    ALERT = "alert"
    """A ping answered with the Alert bit (Hardware Error Status is set)."""
    SILENT = "silent"
    """A ping went unanswered (a booting servo: within ``bus.boot_timeout_s``)."""
    TIMED_OUT = "timed_out"
    """A ping of a booting servo went unanswered ``bus.boot_timeout_s`` after its reboot."""
    ERROR_READ = "error_read"
    """Hardware Error Status was read after an Alert (or the read failed)."""
    RESTORED = "restored"
    """Settings, goal and torque were written again, torque verified."""
    NOT_RESTORED = "not_restored"
    """Torque could not be re-enabled."""


class Action(Enum):
    """What a transition does, in its order; a port job (:class:`Job`) comes last."""

    REBOOT = "reboot"
    """Report :class:`HardwareFault` and reboot the servo (port job)."""
    BOOT = "boot"
    """Report :class:`ServoRebooted`; poll it from ``BOOT_POLL_S`` until its boot timeout."""
    POLL = "poll"
    """Ping it again in ``BOOT_POLL_S``."""
    PROBE = "probe"
    """Ping it again in ``bus.probe_period_s``."""
    READ_ERROR = "read_error"
    """Read its Hardware Error Status (port job)."""
    RESTORE = "restore"
    """Write its settings and goal again and enable its torque (port job)."""
    DEGRADE = "degrade"
    """Report :class:`ServoDegraded`; a critical servo loses the bus (:meth:`lose`)."""
    RESTORED = "restored"
    """Report :class:`ServoRestored`."""
    RECOVERED = "recovered"
    """Report :class:`ServoRecovered`; detect Fast Sync Read again (port job)."""


class Job(Enum):
    """The port work a :class:`Step` asks of the shell."""

    REBOOT = "reboot"
    """Reboot the servo; report with :meth:`HealthMachine.rebooted`."""
    READ_ERROR = "read_error"
    """Read Hardware Error Status; report with :meth:`HealthMachine.error_read`."""
    RESTORE = "restore"
    """Restore settings, goal and torque; report with :meth:`HealthMachine.restored`."""
    DETECT_FAST = "detect_fast"
    """Try Fast Sync Read again (the bus has one more servo); nothing to report."""


_JOBS: Final = {
    Action.REBOOT: Job.REBOOT,
    Action.READ_ERROR: Job.READ_ERROR,
    Action.RESTORE: Job.RESTORE,
    Action.RECOVERED: Job.DETECT_FAST,
}

_S, _A = State, Action
TRANSITIONS: Final[Mapping[tuple[State, Seen], tuple[State, tuple[Action, ...]]]] = {
    (_S.OK, Seen.FAILING): (_S.DEGRADED, (_A.PROBE, _A.DEGRADE)),
    (_S.OK, Seen.LATCHED): (_S.OK, (_A.REBOOT,)),
    (_S.OK, Seen.REBOOTED): (_S.BOOTING, (_A.BOOT,)),
    (_S.BOOTING, Seen.ANSWERED): (_S.BOOTING, (_A.RESTORE,)),
    (_S.BOOTING, Seen.ALERT): (_S.BOOTING, (_A.READ_ERROR,)),
    (_S.BOOTING, Seen.SILENT): (_S.BOOTING, (_A.POLL,)),
    (_S.BOOTING, Seen.TIMED_OUT): (_S.DEGRADED, (_A.PROBE, _A.DEGRADE)),
    (_S.BOOTING, Seen.ERROR_READ): (_S.DEGRADED, (_A.PROBE, _A.DEGRADE)),
    (_S.BOOTING, Seen.RESTORED): (_S.OK, (_A.RESTORED,)),
    (_S.BOOTING, Seen.NOT_RESTORED): (_S.DEGRADED, (_A.PROBE, _A.DEGRADE)),
    # A degraded servo rebooted: it was reported degraded already, so a failed boot is
    # said no more; back, it is recovered.
    (_S.RECOVERING, Seen.ANSWERED): (_S.RECOVERING, (_A.RESTORE,)),
    (_S.RECOVERING, Seen.ALERT): (_S.RECOVERING, (_A.READ_ERROR,)),
    (_S.RECOVERING, Seen.SILENT): (_S.RECOVERING, (_A.POLL,)),
    (_S.RECOVERING, Seen.TIMED_OUT): (_S.DEGRADED, (_A.PROBE,)),
    (_S.RECOVERING, Seen.ERROR_READ): (_S.DEGRADED, (_A.PROBE,)),
    (_S.RECOVERING, Seen.RESTORED): (_S.OK, (_A.RESTORED, _A.RECOVERED)),
    (_S.RECOVERING, Seen.NOT_RESTORED): (_S.DEGRADED, (_A.PROBE,)),
    (_S.DEGRADED, Seen.SILENT): (_S.DEGRADED, (_A.PROBE,)),
    (_S.DEGRADED, Seen.ANSWERED): (_S.DEGRADED, (_A.PROBE, _A.RESTORE)),
    (_S.DEGRADED, Seen.ALERT): (_S.DEGRADED, (_A.PROBE, _A.READ_ERROR)),
    # A latched error is rebooted first: the servo is back only if that cleared it.
    (_S.DEGRADED, Seen.ERROR_READ): (_S.DEGRADED, (_A.REBOOT,)),
    (_S.DEGRADED, Seen.REBOOTED): (_S.RECOVERING, (_A.BOOT,)),
    (_S.DEGRADED, Seen.RESTORED): (_S.OK, (_A.RECOVERED,)),
    (_S.DEGRADED, Seen.NOT_RESTORED): (_S.DEGRADED, ()),
}
"""The whole machine: (state, what was seen) → (next state, actions in order)."""


class TransitionError(Exception):
    """An observation the table has no transition for: a bug of the shell."""


@dataclass(frozen=True, slots=True)
class SafeStopRequest:
    """An effect: ask the runtime for a safe stop (the bus lost what the robot needs)."""

    reason: str


Effect: TypeAlias = Event | SafeStopRequest
"""What a step publishes: an event, or a safe-stop request, in order."""


@dataclass(slots=True)
class Step:
    """The result of an observation: ``effects`` to publish in order, then ``job`` to do."""

    effects: list[Effect] = field(default_factory=list)
    job: Job | None = None


@dataclass(slots=True)
class Health:
    """One servo's health."""

    servo: Servo
    state: State = State.OK
    failures: int = 0
    """Consecutive cycles whose read of it failed."""
    next_probe: float = 0.0
    """When to ping it next, out of the cycle."""
    boot_deadline: float = 0.0
    """Booting or recovering: when it is given up (``bus.boot_timeout_s`` after the reboot)."""
    warning: int = 0
    """Non-latching Hardware Error Status bits last seen (input voltage, by default)."""
    next_check: float = 0.0
    """While a warning stands (every status has the Alert bit), when to read 70 again."""


class HealthMachine:
    """The health of every servo; see the module docstring.

    ``source`` names the events' maker (the actor); ``degrade_after``,
    ``probe_period_s`` and ``boot_timeout_s`` are the ``bus`` settings of the
    same names.
    """

    def __init__(
        self,
        servos: Mapping[int, Servo],
        source: str,
        *,
        degrade_after: int,
        probe_period_s: float,
        boot_timeout_s: float,
    ) -> None:
        self.source = source
        self.degrade_after = degrade_after
        self.probe_period_s = probe_period_s
        self.boot_timeout_s = boot_timeout_s
        self.records = {sid: Health(s) for sid, s in servos.items()}
        """Every servo's health, in the table's order."""
        self.out: set[int] = set()
        """The servos not :attr:`State.OK`: out of the cycle."""
        self.suspects: set[int] = set()
        """Servos whose last read failed: asked every cycle (:meth:`to_ask`)."""
        self.supply_low = False
        self.lost = False
        """Set with :class:`BusLost`: a servo the robot cannot do without, or the port."""
        self.timeouts = 0
        self.corrupt = 0
        """Failed reads so far, by kind (for :class:`BusStats`)."""

    def state(self, sid: int) -> State:
        """Servo ``sid``'s state."""
        return self.records[sid].state

    # ----------------------------------------------------------------- the table

    def _fire(
        self, now: float, h: Health, seen: Seen, *, reason: str = "", bits: int = 0, ok: bool = True
    ) -> Step:
        """Apply :data:`TRANSITIONS` to ``h``; ``reason``, ``bits`` and ``ok`` are what its
        actions report (why it is degraded, the error bits, whether the reboot answered)."""
        try:
            state, actions = TRANSITIONS[h.state, seen]
        except KeyError:
            raise TransitionError(f"{h.servo.name}: {seen.name} while {h.state.name}") from None
        h.state = state
        if state is State.OK:
            h.failures = 0
            self.out.discard(h.servo.id)
        else:
            self.out.add(h.servo.id)
        step = Step()
        effects, sid, source = step.effects, h.servo.id, self.source
        for action in actions:
            if action is Action.REBOOT:
                description = ct.HardwareError(bits).describe()
                effects.append(
                    HardwareFault(
                        t=now, source=source, servo_id=sid, bits=bits, description=description
                    )
                )
            elif action is Action.BOOT:
                effects.append(ServoRebooted(t=now, source=source, servo_id=sid, ok=ok))
                h.warning = 0
                h.boot_deadline = now + self.boot_timeout_s
                h.next_probe = now + BOOT_POLL_S
            elif action is Action.POLL:
                h.next_probe = now + BOOT_POLL_S
            elif action is Action.PROBE:
                h.next_probe = now + self.probe_period_s
            elif action is Action.DEGRADE:
                effects.append(ServoDegraded(t=now, source=source, servo_id=sid, reason=reason))
                if h.servo.critical:
                    effects.extend(self.lose(now, f"{h.servo.name} lost: {reason}"))
            elif action is Action.RESTORED:
                effects.append(ServoRestored(t=now, source=source, servo_id=sid))
            elif action is Action.RECOVERED:
                effects.append(ServoRecovered(t=now, source=source, servo_id=sid))
            job = _JOBS.get(action)
            if job is not None:
                step.job = job
        return step

    def lose(self, now: float, reason: str, *, port: bool = False) -> list[Effect]:
        """The bus lost what the robot needs (a critical servo, or the ``port``): a safe stop.

        :class:`BusLost` is said once, and again only for the port: a second lost servo
        while the robot sits down changes nothing, a lost port ends the cycles."""
        effects: list[Effect] = []
        if not self.lost or port:
            effects.append(BusLost(t=now, source=self.source, reason=reason))
        self.lost = True
        effects.append(SafeStopRequest(reason))
        return effects

    # ----------------------------------------------------------------- a cycle's reads

    def to_ask(self) -> list[int]:
        """The servos in the cycle whose last read failed, by ID: a cycle asks them again,
        so that ``degrade_after`` counts cycles even for a servo the plan reads rarely."""
        if not self.suspects:
            return []
        asked = []
        for sid in sorted(self.suspects):
            h = self.records[sid]
            if h.state is not State.OK or not h.failures:
                self.suspects.discard(sid)
            else:
                asked.append(sid)
        return asked

    def account(
        self, now: float, answered: Collection[int], failed: Mapping[int, str]
    ) -> list[Effect]:
        """A cycle's reads: the servos that ``answered``, and those whose read ``failed``
        (by kind: ``timeout``, ``corrupt``…), each a :class:`ServoFault`."""
        records = self.records
        for sid in answered:
            records[sid].failures = 0
        if self.suspects:
            self.suspects.difference_update(answered)
        self.suspects.update(failed)
        effects: list[Effect] = []
        for sid, kind in failed.items():
            h = records[sid]
            h.failures += 1
            if kind == "timeout":
                self.timeouts += 1
            elif kind == "corrupt":
                self.corrupt += 1
            effects.append(
                ServoFault(
                    t=now, source=self.source, servo_id=sid, kind=kind, consecutive=h.failures
                )
            )
            if h.failures >= self.degrade_after and h.state is State.OK:
                reason = f"{h.failures} failed cycles in a row ({kind})"
                effects.extend(self._fire(now, h, Seen.FAILING, reason=reason).effects)
        return effects

    def to_check(
        self, values: Mapping[int, Mapping[str, int]], errors: Mapping[int, int]
    ) -> list[int]:
        """The servos in the cycle with something to say, by ID: an Alert, error bits read,
        or a standing warning."""
        records = self.records
        suspects = {
            sid
            for sid, err in errors.items()
            if err & ALERT or (sid in values and records[sid].warning)
        }
        suspects.update(sid for sid, regs in values.items() if regs.get("hardware_error_status"))
        return [sid for sid in sorted(suspects) if records[sid].state is State.OK]

    def wants_error_read(self, now: float, sid: int, alert: bool, bits: int | None) -> bool:
        """Whether to read servo ``sid``'s Hardware Error Status now: an Alert and no bits
        read this cycle (and, while a warning stands, ``WARNING_RECHECK_S`` since the last
        read: something may latch on top of it)."""
        h = self.records[sid]
        if bits is None and alert and (not h.warning or now >= h.next_check):
            h.next_check = now + WARNING_RECHECK_S
            return True
        return False

    def error_status(
        self, now: float, sid: int, bits: int | None, alert: bool, answered: bool
    ) -> Step:
        """Servo ``sid``'s Hardware Error Status ``bits`` (``None``: not read), its status's
        ``alert`` and whether a status ``answered`` this cycle: its warning, and a reboot
        for a latched error."""
        h = self.records[sid]
        if bits is None:
            if not alert and answered and h.warning:
                bits = 0  # a clean status: the warning is over
            else:
                return Step()
        shutdown = h.servo.shutdown
        effects = self._warn(now, h, bits & ~shutdown)
        if not bits & shutdown:
            return Step(effects)
        step = self._fire(now, h, Seen.LATCHED, bits=bits)
        return Step(effects + step.effects, step.job)

    def _warn(self, now: float, h: Health, bits: int) -> list[Effect]:
        """A change of ``h``'s non-latching error bits, and of the bus's supply."""
        if bits == h.warning:
            return []
        changed = bits if bits else h.warning
        h.warning = bits
        effects: list[Effect] = [
            HardwareWarning(
                t=now,
                source=self.source,
                servo_id=h.servo.id,
                bits=changed,
                description=ct.HardwareError(changed).describe(),
                active=bool(bits),
            )
        ]
        low = tuple(
            sorted(
                sid for sid, r in self.records.items() if r.warning & ct.HardwareError.INPUT_VOLTAGE
            )
        )
        if low and not self.supply_low:
            self.supply_low = True
            effects.append(SupplyLow(t=now, source=self.source, servo_ids=low))
        elif not low and self.supply_low:
            self.supply_low = False
            effects.append(SupplyRestored(t=now, source=self.source))
        return effects

    # ----------------------------------------------------------------- out of the cycle

    def due(self, now: float) -> int | None:
        """The booting or degraded servo whose ping is due at ``now`` (the earliest; one
        per cycle at most), or ``None``."""
        records = self.records
        waiting = [records[sid] for sid in self.out if now >= records[sid].next_probe]
        if not waiting:
            return None
        return min(waiting, key=lambda h: (h.next_probe, h.servo.id)).servo.id

    def pinged(self, now: float, sid: int, reply: Reply) -> Step:
        """Servo ``sid`` (out of the cycle) answered a ping with ``reply``, or did not."""
        h = self.records[sid]
        if reply.ok:
            return self._fire(now, h, Seen.ALERT if reply.alert else Seen.ANSWERED)
        if h.state is not State.DEGRADED and now >= h.boot_deadline:
            reason = f"no answer {self.boot_timeout_s:g} s after its reboot"
            return self._fire(now, h, Seen.TIMED_OUT, reason=reason)
        return self._fire(now, h, Seen.SILENT)

    def error_read(self, now: float, sid: int, reply: Reply) -> Step:
        """Servo ``sid``'s Hardware Error Status, read after an Alert (:attr:`Job.READ_ERROR`)."""
        h = self.records[sid]
        why = ct.HardwareError(reply.value).describe() if reply.ok else comm_name(reply.result)
        reason = f"hardware error persists after reboot ({why})"
        bits = reply.value if reply.ok else 0
        return self._fire(now, h, Seen.ERROR_READ, reason=reason, bits=bits)

    def rebooted(self, now: float, sid: int, reply: Reply) -> Step:
        """The Reboot of servo ``sid`` went out; ``reply`` is its status (:attr:`Job.REBOOT`)."""
        return self._fire(now, self.records[sid], Seen.REBOOTED, ok=reply.ok)

    def restored(self, now: float, sid: int, ok: bool) -> Step:
        """Whether servo ``sid``'s restore held its torque (:attr:`Job.RESTORE`)."""
        h = self.records[sid]
        if ok:
            return self._fire(now, h, Seen.RESTORED)
        reason = "torque could not be re-enabled after reboot"
        return self._fire(now, h, Seen.NOT_RESTORED, reason=reason)

    def reachable(self) -> list[Servo]:
        """The servos not degraded, in the table's order: what a stop addresses."""
        return [h.servo for h in self.records.values() if h.state is not State.DEGRADED]
