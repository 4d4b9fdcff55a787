"""The cycle's transactions in compiled code, and the pure-Python path where it is not built.

Theory of operation
-------------------
A profile of the bus on real time (``whexar bench bus``, docs/bus.md) put most of its
CPU in dynamixel-sdk's receiver: ``readRx``/``rxPacket`` take a status packet in two or
three reads, each a Python call, the CRC a table walk in Python, and the port thread
wakes and takes the GIL for every chunk a USB adapter hands over. ``_wire`` (C,
``whexar/bus/_wire.c``, built by the package's install) does what the bus does every
cycle, and only that:

* :func:`packet` — an instruction packet as the SDK's ``txPacket`` sends it, with its
  CRC: a Sync Read's request, a Sync Write of goals. Unstuffed, as the SDK's are: its
  ``txPacket`` drops what ``addStuffing`` returns, so a parameter that spells
  ``FF FF FD`` goes out as it is (no goal within a joint's limits does);
* ``parse`` — the SDK's reading of a Sync Read's status packets, over bytes already
  received (an emulated or a replayed port hands a reply over whole);
* ``transact`` — on a serial port's file descriptor: write the request, wait in
  ``poll()`` with the GIL released while the statuses arrive, read them as the SDK
  does, write the goals that ride on the read once the last status is whole, and
  hand back every byte read, with its time, for the link taps.

The receiver is the SDK's algorithm step for step — its header hunt, its checks and
what it drops, its reads of ``wait_length - rx_length`` bytes (negative ones
included), its CRC, its unstuffing, its passing over a status of another ID — so
that a stream of bytes, whole or corrupted, short, interleaved, gives the same
:class:`~whexar.bus.sdk.SyncReadResult` on both paths, and the port is left with
the same bytes unread. ``tests/bus/test_wire.py`` checks that against the SDK's
own code: every fault plan of the emulator, and streams mutated at random.

Everything else — ping, read, write, reboot, EEPROM, the scans — stays
dynamixel-sdk's. Where ``_wire`` cannot be imported (no compiler when the package
was installed), :data:`NATIVE` is ``None``, :func:`why_not` says why, and
:class:`~whexar.bus.sdk.DxlBus` takes the SDK's path for everything.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import ModuleType
from typing import Final

__all__ = ["NATIVE", "packet", "sync_read_request", "sync_write_request", "why_not"]

SYNC_READ: Final = 0x82
FAST_SYNC_READ: Final = 0x8A
SYNC_WRITE: Final = 0x83
BROADCAST: Final = 0xFE
"""Instruction codes and the broadcast ID (e-manual, Protocol 2.0)."""


def _load() -> tuple[ModuleType | None, str]:
    try:
        from whexar.bus import _wire
    except ImportError as exc:
        return None, f"the compiled bus path is not built ({exc}); using dynamixel-sdk's"
    return _wire, ""


NATIVE, _WHY = _load()
"""The compiled module, or ``None`` where it is not built."""


def why_not() -> str:
    """Why :data:`NATIVE` is ``None`` (empty when it is loaded)."""
    return _WHY


def packet(ident: int, instruction: int, params: bytes) -> bytes | None:
    """The instruction packet the SDK's ``txPacket`` would write; ``None`` where it is
    refused (longer than the SDK's 1 KiB) or the compiled path is not built."""
    if NATIVE is None:
        return None
    out: bytes | None = NATIVE.packet(ident, instruction, params)
    return out


def sync_read_request(start: int, length: int, ids: Sequence[int], *, fast: bool) -> bytes | None:
    """A (Fast) Sync Read's request for ``length`` bytes at ``start`` of ``ids``."""
    params = bytes((start & 0xFF, start >> 8, length & 0xFF, length >> 8, *ids))
    return packet(BROADCAST, FAST_SYNC_READ if fast else SYNC_READ, params)


def sync_write_request(start: int, length: int, values: Mapping[int, bytes]) -> bytes | None:
    """A Sync Write of ``length`` bytes at ``start``: ``values`` in their order."""
    head = bytes((start & 0xFF, start >> 8, length & 0xFF, length >> 8))
    body = b"".join([bytes((sid,)) + data for sid, data in values.items()])
    return packet(BROADCAST, SYNC_WRITE, head + body)
