"""Types of the compiled module (whexar/bus/_wire.c); whexar.bus.wire documents it."""

from typing import Any

COMM_SUCCESS: int
COMM_TX_FAIL: int
COMM_RX_TIMEOUT: int
COMM_RX_CORRUPT: int

def crc16(data: bytes, crc: int = 0, /) -> int: ...
def packet(ident: int, instruction: int, params: bytes, /) -> bytes | None: ...
def parse(
    received: bytes, ids: bytes, length: int, fast: bool, timed_out: bool, /
) -> tuple[bool, int, int, int | None, Any, dict[int, int] | None, bool]: ...
def transact(
    fd: int,
    request: bytes,
    ids: bytes,
    length: int,
    fast: bool,
    timeout_ms: float,
    then: tuple[bytes, ...],
    byte_s: float,
    busy_until: float,
    /,
) -> tuple[
    int,
    int | None,
    Any,
    dict[int, int],
    int,
    bytes,
    list[tuple[str, float, bytes]],
    list[int],
    float,
]: ...
