"""The port jobs: what the scheduler asks the port owner to do, as functions of the bus.

Each job runs where the port is owned (:class:`~whexar.bus.sdk.PortOwner`:
its own thread on a real port, inline on the emulator), does the blocking
transactions in a row and returns what they said. A job decides nothing
beyond the retries of its own transactions: what to ask and what the
answers mean is the cores' business.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from whexar.actors.bus.goals import Write
from whexar.actors.bus.servos import (
    BUS_WATCHDOG,
    GOAL_POSITION,
    GOAL_VELOCITY,
    PRESENT_POSITION,
    TORQUE_ENABLE,
    WATCHDOG_ERROR,
    Servo,
)
from whexar.actors.bus.startup import SETTINGS, Change, eeprom_diff
from whexar.bus import control_table as ct
from whexar.bus.protocol import ALERT, sync_read_bytes, sync_write_bytes
from whexar.bus.sdk import COMM_SUCCESS, DxlBus, Reply, SyncReadResult, comm_name

_pack_i32 = struct.Struct("<i").pack
"""Goal Position/Velocity bytes (signed 32-bit, little-endian); goals are clamped first."""
_WHEEL_GOAL = ct.block(["goal_velocity"])
_TORQUE_SPAN = ct.block(["torque_enable"])


@dataclass(slots=True)
class Request:
    """One read of a cycle: a register span of some servos."""

    start: int
    length: int
    ids: tuple[int, ...]


@dataclass(slots=True)
class Outcome:
    """What the port owner did in one cycle (built in the port's thread, read on the loop)."""

    reads: list[SyncReadResult] = field(default_factory=list)
    failed: dict[int, str] = field(default_factory=dict)
    retries: int = 0
    fast_failures: int = 0
    bytes: int = 0
    write_results: list[int] = field(default_factory=list)


def cycle_job(
    requests: Sequence[Request], fast: bool, retries: int, writes: Sequence[Write]
) -> Callable[[DxlBus], Outcome]:
    """The port-side half of a cycle: the due reads (with retries), then the goal writes.

    A failed read is retried (``retries`` times) from the servo that failed; a bad Fast
    Sync Read packet names no culprit, so it is asked again the plain way."""

    def job(bus: DxlBus) -> Outcome:
        out = Outcome()
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


def read_all(bus: DxlBus, ids: Sequence[int], span: ct.Block) -> dict[int, dict[str, int]]:
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


def survey_job(ids: Sequence[int], span: ct.Block) -> Callable[[DxlBus], dict[int, dict[str, int]]]:
    """:func:`read_all` as a job."""
    return lambda bus: read_all(bus, ids, span)


def ping_job(ids: Sequence[int]) -> Callable[[DxlBus], dict[int, Reply]]:
    """Ping each of ``ids``."""
    return lambda bus: {i: bus.ping(i) for i in ids}


def probe_job(sid: int, timeout_ms: float) -> Callable[[DxlBus], Reply]:
    """Ping servo ``sid``, waiting at most ``timeout_ms`` for its status."""
    return lambda bus: bus.ping(sid, timeout_ms=timeout_ms)


def read_job(sid: int, reg: ct.Register) -> Callable[[DxlBus], Reply]:
    """Read ``reg`` of servo ``sid``."""
    return lambda bus: bus.read(sid, reg)


def reboot_job(sid: int) -> Callable[[DxlBus], Reply]:
    """Reboot servo ``sid`` (instruction 0x08)."""
    return lambda bus: bus.reboot(sid)


def fast_probe_job(ids: Sequence[int], span: ct.Block) -> Callable[[DxlBus], bool]:
    """Whether a Fast Sync Read of ``span`` from ``ids`` succeeds."""
    return lambda bus: bus.sync_read(ids, span.start, span.length, fast=True).ok


def clear_watchdog_job(ids: Sequence[int]) -> Callable[[DxlBus], None]:
    """Clear the Bus Watchdog error of ``ids`` (writing 0 clears it, e-manual)."""

    def job(bus: DxlBus) -> None:
        for sid in ids:
            bus.write(sid, BUS_WATCHDOG, 0)

    return job


def _write_each(
    bus: DxlBus, changes: Mapping[int, Sequence[Change]], names: Mapping[int, str]
) -> list[str]:
    """Write each servo's ``changes`` one by one; the problems (named by ``names``)."""
    problems = []
    for sid, diff in changes.items():
        for reg, value in diff:
            reply = bus.write(sid, reg, value)
            if not reply.ok or reply.error & ~ALERT:
                problems.append(f"{names[sid]}: writing {reg.name} = {value} failed")
    return problems


def configure_job(
    changes: Mapping[int, Sequence[Change]], names: Mapping[int, str]
) -> Callable[[DxlBus], list[str]]:
    """Torque off, then each EEPROM change; the problems (named by ``names``)."""

    def configure(bus: DxlBus) -> list[str]:
        bus.sync_write(TORQUE_ENABLE.address, 1, dict.fromkeys(changes, b"\x00"))  # EEPROM needs it
        return _write_each(bus, changes, names)

    return configure


def gains_job(
    gains: Mapping[int, Sequence[Change]], names: Mapping[int, str]
) -> Callable[[DxlBus], list[str]]:
    """Each servo's position gains (RAM: its torque stays as it is); the problems (named
    by ``names``)."""
    return lambda bus: _write_each(bus, gains, names)


def hold_job(moved: Mapping[int, int], wheels: Sequence[int]) -> Callable[[DxlBus], None]:
    """The position goals that had to change, and zero speed for ``wheels``."""
    goals = {sid: _pack_i32(v) for sid, v in moved.items()}
    still = {sid: _pack_i32(0) for sid in wheels}

    def hold(bus: DxlBus) -> None:
        bus.sync_write(GOAL_POSITION.address, 4, goals)
        bus.sync_write(GOAL_VELOCITY.address, 4, still)

    return hold


def enable_job(
    servos: Sequence[tuple[Servo, int | None]],
) -> Callable[[DxlBus], tuple[SyncReadResult, dict[int, int]]]:
    """Read where each limp joint of ``servos`` (each with its goal) is now and make that
    its goal, so that torque-on holds it still; torque on; read Torque Enable back.
    Returns the read-back and the position goals written (each within its joint's limits).

    The positions are read in the same job as torque-on: a limp joint sags under the
    robot's weight, and a position read before (the start-up's survey, tens of ms
    earlier) would pull it back with a jolt. A servo that does not answer keeps the
    goal it had."""
    joints = [(s, goal) for s, goal in servos if not s.endless]
    vel = {s.id: _pack_i32(goal or 0) for s, goal in servos if s.endless}
    ids = [s.id for s, _ in servos]

    def job(bus: DxlBus) -> tuple[SyncReadResult, dict[int, int]]:
        now = (
            bus.sync_read([s.id for s, _ in joints], PRESENT_POSITION.address, 4)
            if joints
            else None
        )
        goals: dict[int, int] = {}
        for s, goal in joints:
            data = now.data.get(s.id) if now is not None else None
            tick = int.from_bytes(data, "little", signed=True) if data else goal or 0
            goals[s.id] = s.clamp_tick(tick)
        bus.sync_write(GOAL_POSITION.address, 4, {i: _pack_i32(g) for i, g in goals.items()})
        bus.sync_write(GOAL_VELOCITY.address, 4, vel)
        bus.sync_write(TORQUE_ENABLE.address, 1, dict.fromkeys(ids, b"\x01"))
        return bus.sync_read(ids, TORQUE_ENABLE.address, 1), goals

    return job


def watchdog_job(ids: Sequence[int], units: int) -> Callable[[DxlBus], int]:
    """Set Bus Watchdog (98) of ``ids`` to ``units`` (20 ms each; 0: off)."""
    values = dict.fromkeys(ids, bytes((units,)))
    return lambda bus: bus.sync_write(BUS_WATCHDOG.address, 1, values)


def restore_job(
    servo: Servo, goal: int | None, return_delay: int, watchdog_units: int, torque_retries: int
) -> Callable[[DxlBus], bool]:
    """Write the servo's settings and ``goal`` again and enable its torque; True when it
    holds.

    EEPROM is read first and written only where it differs (a reboot keeps it);
    Bus Watchdog, position gains, goal and torque are RAM, lost in a reboot: written
    again."""
    sid = servo.id

    def restore(bus: DxlBus) -> bool:
        have = read_all(bus, [sid], SETTINGS).get(sid)
        if have is None:
            return False
        diff = eeprom_diff(servo, have, return_delay)
        if diff:
            bus.write(sid, TORQUE_ENABLE, 0)
            for reg, value in diff:
                bus.write(sid, reg, value)
        if bus.read(sid, BUS_WATCHDOG).value == WATCHDOG_ERROR:
            bus.write(sid, BUS_WATCHDOG, 0)
        for reg, value in servo.gains:
            bus.write(sid, reg, value)
        if goal is not None:
            bus.write(sid, servo.goal_register, goal)
        for _ in range(torque_retries):
            if bus.write(sid, TORQUE_ENABLE, 1).ok and bus.read(sid, TORQUE_ENABLE).value == 1:
                bus.write(sid, BUS_WATCHDOG, watchdog_units)
                return True
        return False

    return restore


def park_job(wheels: Sequence[int], ids: Sequence[int], hold: bool) -> Callable[[DxlBus], None]:
    """Wheels to zero speed, then torque off (or, to ``hold``, the watchdog disarmed),
    checked: the writes are read back (Goal Velocity of the wheels, Torque Enable) and
    sent once more where they did not take. A stop must stop, and a read behind the
    writes also makes sure they left the host before the port closes."""
    torque = 1 if hold else 0

    def park(bus: DxlBus) -> None:
        for _ in range(2):
            bus.sync_write(GOAL_VELOCITY.address, 4, dict.fromkeys(wheels, _pack_i32(0)))
            if hold:
                bus.sync_write(BUS_WATCHDOG.address, 1, dict.fromkeys(ids, b"\x00"))
            else:
                bus.sync_write(TORQUE_ENABLE.address, 1, dict.fromkeys(ids, b"\x00"))
            speeds = read_all(bus, wheels, _WHEEL_GOAL)
            torques = read_all(bus, ids, _TORQUE_SPAN)
            if all(v["goal_velocity"] == 0 for v in speeds.values()) and all(
                v["torque_enable"] == torque for v in torques.values()
            ):
                return

    return park
