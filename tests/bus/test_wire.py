"""The compiled transaction path gives dynamixel-sdk's results, byte for byte.

Both paths read the same bytes from the same kind of port: the SDK's own receiver
(``DxlBus(native=False)``) and ``_wire`` (``DxlBus(native=True)``). They must agree on
the result code, the failing servo, every servo's data and ERR byte, the packets
written, and the bytes left unread — for whole replies and for replies corrupted,
cut short, interleaved, padded with garbage, or made of packets of other servos.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import random
import shutil
import sysconfig
import threading
import time
import tty
from pathlib import Path
from typing import Any, cast

import dynamixel_sdk as dxl
import pytest

from whexar.actors.messages import BusWarning
from whexar.bus import wire
from whexar.bus.emulator.chain import FaultState
from whexar.bus.emulator.pty import PtyEmulator
from whexar.bus.protocol import crc16, crc16_py, encode_fast_status, encode_status
from whexar.bus.sdk import DxlBus, SyncReadResult, _Capture, open_port, tap_port
from whexar.errors import DeviceGoneError
from whexar.runtime.clock import monotonic
from whexar.runtime.harness import run_actors
from whexar.runtime.messages import ActorFailed
from whexar.testing.bus import bus_graph, servo_chain

needs_native = pytest.mark.skipif(wire.NATIVE is None, reason=wire.why_not())


class BytesPort:
    """A port that hands over a reply whole, like the emulated one: the SDK's calls,
    reads sliced as Python slices (negative counts included), a timeout once nothing is
    left to read. Every call is logged."""

    is_using = False
    timeout_cap_ms: float | None = None

    def __init__(self, reply: bytes) -> None:
        self.reply = reply
        self.rx = b""
        self.at = 0
        self.log: list[tuple[str, Any]] = []

    def clearPort(self) -> None:
        self.rx, self.at = b"", 0

    def writePort(self, packet: Any) -> int:
        data = bytes(packet)
        self.log.append(("tx", data))
        if data[7] in (0x82, 0x8A):
            self.rx, self.at = self.reply, 0
        return len(data)

    def setPacketTimeout(self, n: int) -> None:
        self.log.append(("timeout armed", n))

    def peek(self) -> bytes:
        return self.rx[self.at :]

    def readPort(self, length: int) -> bytes:
        unread = self.rx[self.at :]
        data = unread[:length]
        self.at += len(data)
        if data:
            self.log.append(("rx", data))
        return data

    def isPacketTimeout(self) -> bool:
        over = self.at >= len(self.rx)
        self.log.append(("timeout?", over))
        return over

    def getBaudRate(self) -> int:
        return 1_000_000


def _merged(log: list[tuple[str, Any]]) -> list[tuple[str, Any]]:
    """The log with consecutive reads joined: what a link tap reports."""
    out: list[tuple[str, Any]] = []
    for kind, value in log:
        if kind == "rx" and out and out[-1][0] == "rx":
            out[-1] = ("rx", out[-1][1] + value)
        else:
            out.append((kind, value))
    return out


def _status(sid: int, data: bytes, error: int = 0) -> bytes:
    return encode_status(sid, error, data)


def _fast_status(ids: list[int], data: list[bytes], errors: list[int]) -> bytes:
    return encode_fast_status([(sid, e, d) for sid, d, e in zip(ids, data, errors, strict=True)])


def _mutate(rng: random.Random, packets: list[bytes]) -> bytes:
    packets = list(packets)
    for _ in range(rng.choice([0, 1, 1, 2, 3])):
        kind = rng.randrange(9)
        k = rng.randrange(len(packets))
        if kind == 0:  # a bit flipped
            p = bytearray(packets[k])
            i = rng.randrange(len(p))
            p[i] ^= 1 << rng.randrange(8)
            packets[k] = bytes(p)
        elif kind == 1:  # lost
            del packets[k]
        elif kind == 2:  # two swapped: interleaved answers
            j = rng.randrange(len(packets))
            packets[k], packets[j] = packets[j], packets[k]
        elif kind == 3:  # cut short
            packets[k] = packets[k][: rng.randrange(len(packets[k]))]
        elif kind == 4:  # garbage before it
            junk = bytes(
                rng.choice([0xFF, 0xFD, 0x00, 0x55, rng.randrange(256)])
                for _ in range(rng.randrange(1, 12))
            )
            packets.insert(k, junk)
        elif kind == 5:  # answered twice
            packets.insert(k, packets[k])
        elif kind == 6:  # a servo nobody asked
            packets.insert(
                k, _status(rng.randrange(0, 253), bytes(rng.randrange(256) for _ in range(4)))
            )
        elif kind == 7:  # a LEN of nonsense
            p = bytearray(packets[k])
            if len(p) > 6:
                p[5] = rng.choice([0, 1, 2, 3, 4, 5, 0xFF])
                p[6] = rng.choice([0, 0, 0, 4, 0xFF])
            packets[k] = bytes(p)
        else:  # a header half-stuffed
            packets[k] = b"\xff\xff\xfd" + packets[k]
        if not packets:
            return b""
    return b"".join(packets)


def _data(rng: random.Random, length: int) -> bytes:
    # FF FF FD in the data now and then: the statuses are stuffed.
    if length >= 3 and rng.random() < 0.2:
        return b"\xff\xff\xfd" + bytes(rng.randrange(256) for _ in range(length - 3))
    return bytes(rng.choice([0xFF, 0xFD, rng.randrange(256)]) for _ in range(length))


def _both(
    reply: bytes, ids: list[int], length: int, *, fast: bool, then: tuple[bytes, ...]
) -> tuple[Any, Any]:
    out = []
    for native in (False, True):
        port = BytesPort(reply)
        bus = DxlBus(port, native=native)
        assert bus.native is native
        res: SyncReadResult = bus.sync_read(ids, 126, length, fast=fast, then=then)
        out.append(
            (
                (res.result, res.data, res.errors, res.failed, res.sent),
                _merged(port.log),
                port.peek(),
            )
        )
    return out[0], out[1]


@needs_native
@pytest.mark.parametrize("fast", [False, True])
def test_any_reply_reads_as_the_sdk_reads_it(fast: bool) -> None:
    rng = random.Random(7 if fast else 5)
    then = (b"\xff\xff\xfd\x00\xfe\x09\x00\x83\x74\x00\x04\x00\x01\x02\x03\x04\x00\x00",)
    outcomes: set[int] = set()
    for case in range(1500):
        n = rng.choice([1, 2, 6, 42])
        length = rng.choice([1, 2, 4, 10])
        ids = sorted(rng.sample(range(1, 60), n))
        data = [_data(rng, length) for _ in ids]
        errors = [rng.choice([0, 0, 0, 0x80, 0x01]) for _ in ids]
        if fast:
            packets = [_fast_status(ids, data, errors)]
            if rng.random() < 0.3:
                packets.append(_status(ids[0], data[0]))
        else:
            packets = [_status(s, d, e) for s, d, e in zip(ids, data, errors, strict=True)]
        reply = _mutate(rng, packets)
        sdk, native = _both(reply, ids, length, fast=fast, then=then if case % 2 else ())
        assert native == sdk, (case, reply.hex(), ids, length)
        outcomes.add(sdk[0][0])
    assert outcomes >= {dxl.COMM_SUCCESS, dxl.COMM_RX_TIMEOUT, dxl.COMM_RX_CORRUPT}


@needs_native
def test_result_codes_are_the_sdks() -> None:
    assert wire.NATIVE is not None
    assert wire.NATIVE.COMM_SUCCESS == dxl.COMM_SUCCESS
    assert wire.NATIVE.COMM_TX_FAIL == dxl.COMM_TX_FAIL
    assert wire.NATIVE.COMM_RX_TIMEOUT == dxl.COMM_RX_TIMEOUT
    assert wire.NATIVE.COMM_RX_CORRUPT == dxl.COMM_RX_CORRUPT


@needs_native
def test_crc_is_the_sdks() -> None:
    assert wire.NATIVE is not None
    rng = random.Random(1)
    ph = dxl.PacketHandler(2.0)
    for _ in range(200):
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 300)))
        expected = ph.updateCRC(0, list(data), len(data))
        assert wire.NATIVE.crc16(data) == crc16(data) == crc16_py(data) == expected
        assert crc16(data[3:], crc16(data[:3])) == expected  # continued, as the codec does


@needs_native
def test_packets_are_the_sdks() -> None:
    """Sync Writes and Sync Reads as the SDK builds them, stuffing included."""
    rng = random.Random(2)
    ph = dxl.PacketHandler(2.0)
    for _ in range(400):
        n = rng.randrange(1, 43)
        length = rng.choice([1, 2, 4, 12])
        ids = rng.sample(range(0, 253), n)
        values = {sid: _data(rng, length) for sid in ids}
        start = rng.choice([64, 104, 116, 0xFFFF, 0xFDFF])
        capture = _Capture()
        param = [b for sid, d in values.items() for b in (sid, *d)]
        ph.syncWriteTxOnly(capture, start, length, param, len(param))
        assert wire.sync_write_request(start, length, values) == capture.packet
        for fast in (False, True):
            capture = _ReadCapture()
            ph.syncReadTx(capture, start, length, ids, len(ids), fast)
            assert wire.sync_read_request(start, length, ids, fast=fast) == capture.packet


class _ReadCapture(_Capture):
    def setPacketTimeout(self, n: int) -> None:
        pass


@needs_native
def test_a_packet_the_sdk_refuses_is_left_to_the_sdk() -> None:
    values = {sid: bytes(8) for sid in range(200)}  # 14 + 200 * 9 bytes: over 1 KiB
    assert wire.sync_write_request(116, 8, values) is None
    for native in (True, False):  # the SDK's addStuffing overruns its 1 KiB list
        with pytest.raises(IndexError):
            DxlBus(cast(Any, _Capture()), native=native).prepare_sync_write(116, 8, values)


FAULT_PLANS = sorted((Path(__file__).parents[2] / "config" / "faults").glob("*.toml"))
ROUGH_BUS = """
seed = 3
[[faults]]
kind = "corrupt"
rate = 2e-3
at_s = 0.5
duration_s = 2.0
[[faults]]
kind = "drop"
rate = 0.01
at_s = 1.0
duration_s = 2.0
"""


def _run_bus(plan: Path, native: bool, seconds: float) -> tuple[list[Any], list[Any]]:
    links: list[Any] = []
    graph = bus_graph("emulator", {"faults": str(plan), "native": native}, wiggle={})
    result = run_actors(graph, duration=seconds, link_observer=lambda *event: links.append(event))
    # A failure's traceback names the path's own functions: everything else must agree.
    messages = [
        dataclasses.replace(m, traceback="") if isinstance(m, ActorFailed) else m
        for m in result.messages()
    ]
    return messages, links


@needs_native
@pytest.mark.slow
@pytest.mark.parametrize("plan", [*FAULT_PLANS, "rough"], ids=lambda p: getattr(p, "stem", p))
def test_every_fault_plan_runs_the_same_on_both_paths(plan: Path | str, tmp_path: Path) -> None:
    """The whole scheduler on the emulator, each fault plan: every message published and
    every byte on the link, the same with the compiled path as with the SDK's."""
    if plan == "rough":  # corrupted and lost statuses every few cycles
        plan = tmp_path / "rough.toml"
        plan.write_text(ROUGH_BUS)
    assert isinstance(plan, Path)
    seconds = 6.5 if plan.stem == "brownout" else 3.5
    sdk_messages, sdk_links = _run_bus(plan, False, seconds)
    native_messages, native_links = _run_bus(plan, True, seconds)
    assert len(sdk_links) > 100
    assert native_links == sdk_links
    assert native_messages == sdk_messages


def _drain(port: Any, quiet_s: float = 0.1, limit_s: float = 2.0) -> None:
    """Read (through the tap) whatever the emulator still sends, until ``quiet_s`` pass
    without a byte."""
    end = last = monotonic()
    end += limit_s
    while monotonic() < end:
        waiting = port.getBytesAvailable()
        if waiting:
            port.readPort(waiting)
            last = monotonic()
        elif monotonic() - last > quiet_s:
            return
        else:
            time.sleep(0.002)


def _pty_reads(native: bool, faults: FaultState | None = None, cycles: int = 30) -> list[Any]:
    """Sync Reads of 42 servos over a pty to the emulator in real time, each with goals
    riding on it; what each returned, and every byte the link tap saw."""
    chain = servo_chain()
    if faults is not None:
        chain.faults = faults
    tapped: list[tuple[str, bytes]] = []
    with PtyEmulator(chain) as emulator:
        port = open_port(emulator.path, 1_000_000)
        tap_port(port, lambda kind, _t, data: tapped.append((kind, data)), monotonic)
        bus = DxlBus(port, native=native)
        ids = list(range(1, 43))
        out: list[Any] = []
        try:
            for k in range(cycles):
                goals = bus.prepare_sync_write(116, 4, {3: (2000 + k).to_bytes(4, "little")})
                res = bus.sync_read(ids, 126, 10, then=[goals])
                out.append((res.result, res.failed, sorted(res.data), res.sent))
                if not res.ok:
                    # The rest of a failed read is still on its way: where it falls in the
                    # next read is a race, which each path may win (a real bus too). Read
                    # it off until the line is quiet, so that both paths see all of it
                    # however busy the machine (a fixed pause lost it to a busy CPU).
                    _drain(port)
        finally:
            port.closePort()
    return [out, tapped]


@needs_native
@pytest.mark.slow
@pytest.mark.serial  # answered within the SDK's packet timeout, on real time
@pytest.mark.parametrize("fault", ["none", "silent", "corrupt"])
def test_a_real_port_reads_as_the_sdk_reads_it(fault: str) -> None:
    """Over a pty, on real time: the same results on both paths, and every byte through
    the tap (the goals riding on each read included), the same bytes each way."""

    def faults() -> FaultState | None:
        if fault == "silent":
            return FaultState(silent_until={17: float("inf")})
        if fault == "corrupt":
            return FaultState(corrupt_rate=2e-3, rng=random.Random(5))
        return None

    def seen(tap: list[tuple[str, bytes]]) -> tuple[list[bytes], bytes, int]:
        # Where the goals fall among the statuses is a matter of microseconds: compare
        # what went each way.
        sent = [data for kind, data in tap if kind == "tx"]
        received = b"".join(data for kind, data in tap if kind == "rx")
        return sent, received, sum(kind == "timeout" for kind, _ in tap)

    # On real time, a process stall longer than the packet timeout (a busy CI machine)
    # times one path out where the other was answered. Such a stall hits one attempt; a
    # real difference between the paths shows on every attempt, so three are allowed.
    def expected(out: list[Any]) -> bool:
        if fault == "silent":
            return {r[:2] for r in out} == {(dxl.COMM_RX_TIMEOUT, 17)}
        if fault == "corrupt":
            return {r[0] for r in out} >= {dxl.COMM_SUCCESS, dxl.COMM_RX_CORRUPT}
        return True

    for _attempt in range(3):
        sdk_out, sdk_tap = _pty_reads(False, faults())
        native_out, native_tap = _pty_reads(True, faults())
        if native_out == sdk_out and seen(native_tap) == seen(sdk_tap) and expected(sdk_out):
            break
    assert native_out == sdk_out
    assert expected(sdk_out)
    assert seen(native_tap) == seen(sdk_tap)


def _can_build() -> bool:
    include = Path(sysconfig.get_paths()["include"]) / "Python.h"
    return include.exists() and shutil.which(sysconfig.get_config_var("CC") or "cc") is not None


def test_the_compiled_path_is_built_where_it_can_be() -> None:
    if not _can_build():
        pytest.skip("no C compiler or no Python headers: the pure-Python path it is")
    assert wire.NATIVE is not None, wire.why_not()


def test_without_it_the_bus_says_so_once_and_takes_the_sdks_path(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    graph = bus_graph("emulator", {}, wiggle={})
    built = run_actors(graph, duration=0.5)
    monkeypatch.setattr(wire, "NATIVE", None)
    monkeypatch.setattr(wire, "_WHY", "the compiled bus path is not built (test)")
    assert DxlBus(BytesPort(b"")).native is False
    fallen = run_actors(graph, duration=0.5)
    warnings = [m for m in fallen.messages("events") if isinstance(m, BusWarning)]
    assert [w.message for w in warnings] == ["the compiled bus path is not built (test)"]
    assert fallen.messages("state") == built.messages("state")


@needs_native
@pytest.mark.slow
@pytest.mark.serial  # answered within the SDK's packet timeout, on real time
@pytest.mark.parametrize("native", [False, True])
def test_a_port_that_vanishes_mid_read_is_a_gone_device(native: bool) -> None:
    """The pty's other side closes while the servos answer (a USB adapter pulled out):
    both paths raise :class:`DeviceGoneError` naming the port, nothing hangs."""
    master, slave = os.openpty()
    tty.setraw(slave)
    name = os.ttyname(slave)
    port = open_port(name, 1_000_000)
    os.close(slave)  # the port has its own descriptor

    def pull_out() -> None:
        os.read(master, 64)  # the request
        os.write(master, encode_status(1, 0, b"\x00\x08\x00\x00"))  # one servo answers
        time.sleep(0.005)
        os.close(master)

    puller = threading.Thread(target=pull_out)
    puller.start()
    try:
        with pytest.raises(DeviceGoneError, match=name):
            DxlBus(port, native=native).sync_read(list(range(1, 43)), 132, 4)
    finally:
        puller.join()
        with contextlib.suppress(Exception):
            port.closePort()


@needs_native
@pytest.mark.slow
@pytest.mark.serial  # answered within the SDK's packet timeout, on real time
@pytest.mark.parametrize("native", [False, True])
def test_bytes_after_the_last_status_stay_unread_on_a_real_port(native: bool) -> None:
    """A reply with bytes behind it (another transaction's, noise): the read takes what the
    SDK takes, the rest stays in the port for the next one, and the tap sees only what
    was read."""
    master, slave = os.openpty()
    tty.setraw(slave)
    port = open_port(os.ttyname(slave), 1_000_000)
    os.close(slave)
    tapped: list[tuple[str, bytes]] = []
    tap_port(port, lambda kind, _t, data: tapped.append((kind, data)), monotonic)
    reply = b"".join(encode_status(sid, 0, bytes((sid, 0, 0, 0))) for sid in (1, 2, 3))
    noise = b"\x00\xff\xff\xfd\x00\x09"

    def answer() -> None:
        os.read(master, 64)
        os.write(master, reply + noise)

    answering = threading.Thread(target=answer)
    answering.start()
    try:
        res = DxlBus(port, native=native).sync_read([1, 2, 3], 132, 4)
        answering.join()
        assert res.ok
        assert res.data == {1: b"\x01\0\0\0", 2: b"\x02\0\0\0", 3: b"\x03\0\0\0"}
        assert port.peek() == noise
        port.closePort()  # the tap reports what it holds
        assert b"".join(data for kind, data in tapped if kind == "rx") == reply
    finally:
        with contextlib.suppress(OSError):
            os.close(master)
