"""Find the servos on a port: ``whexar bus scan``.

Uses dynamixel-sdk directly (``PacketHandler(2.0)`` on the waiting
``PortHandler`` of :mod:`whexar.bus.sdk`), so it
works on a U2D2, on a pty served by ``whexar emulate``, on anything that
speaks Protocol 2.0.

1. Broadcast Ping: every servo answers with its model number and firmware
   version, one status packet each, in ID order. The SDK listens for the
   whole window that 252 answers could take (about 0.8 s at 1 Mbps).
2. If some answer came back corrupt (two servos answering at once, noise),
   the IDs not yet found are pinged one by one.
3. Each servo found is confirmed by one Read of addresses 0–70: Model Number
   (0), Firmware Version (6) and Hardware Error Status (70). A servo that
   answers no Read in :data:`CONFIRM_ATTEMPTS` tries is left out.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass
from typing import Any, Final

from whexar.bus.control_table import HardwareError, model_name
from whexar.errors import DeviceGoneError, UsageError

__all__ = ["BAUDRATES", "CONFIRM_ATTEMPTS", "ScanResult", "scan", "scan_port"]

BAUDRATES: Final = (
    9600,
    19200,
    38400,
    57600,
    115200,
    230400,
    460800,
    500000,
    576000,
    921600,
    1000000,
    1152000,
    2000000,
    2500000,
    3000000,
    3500000,
    4000000,
)
"""The rates dynamixel-sdk 4.1.0's ``PortHandler.setBaudRate`` accepts (``getCFlagBaud``)."""
CONFIRM_ATTEMPTS: Final = 3
_READ_START: Final = 0
_READ_LENGTH: Final = 71
"""Model Number (0) … Hardware Error Status (70) in one Read (MX (2.0) control table)."""
_FIRMWARE: Final = 6
_HARDWARE_ERROR: Final = 70
_BROADCAST_ID: Final = 0xFE


@dataclass(frozen=True, slots=True)
class ScanResult:
    """One servo that answered."""

    id: int
    model_number: int
    model: str
    """``"MX-64"``, or ``"model 1234"`` for a model whexar does not know."""
    firmware: int
    hardware_error: int
    """Hardware Error Status (70); 0 when all is well."""
    hardware_error_text: str
    """``"overload"``, ``"none"``… (:meth:`HardwareError.describe`)."""

    def as_dict(self) -> dict[str, Any]:
        """The fields as a JSON-ready dictionary."""
        return asdict(self)


def scan(
    port_name: str, baudrate: int = 1_000_000, ids: Iterable[int] = range(0, 253)
) -> list[ScanResult]:
    """Every servo among ``ids`` that answers on ``port_name`` at ``baudrate``, by ID.

    Raises :class:`UsageError` for a rate the SDK cannot set and
    :class:`DeviceGoneError` when the port cannot be opened or vanishes.
    """
    if baudrate not in BAUDRATES:
        raise UsageError(f"baud rate {baudrate}; allowed: {', '.join(str(b) for b in BAUDRATES)}")
    wanted = sorted({int(i) for i in ids})
    bad = [i for i in wanted if not 0 <= i <= 252]
    if bad:
        raise UsageError(f"servo IDs {bad}; allowed: 0–252 (253–255 are reserved)")

    import dynamixel_sdk as dxl

    from whexar.bus.sdk import WaitingPortHandler

    port = WaitingPortHandler(port_name)
    try:
        port.setBaudRate(baudrate)
    except OSError as exc:  # pyserial's SerialException is an OSError
        raise DeviceGoneError(f"cannot open servo port {port_name}: {_reason(exc)}") from None
    try:
        return _scan(port, dxl.PacketHandler(2.0), wanted)
    except OSError as exc:
        raise DeviceGoneError(
            f"servo port {port_name} failed during the scan: {_reason(exc)}"
        ) from None
    finally:
        if port.is_open:
            port.closePort()


def scan_port(port: Any, ids: Iterable[int] = range(0, 253)) -> list[ScanResult]:
    """As :func:`scan`, on a port already open at its rate (a ``PortHandler``, an
    :class:`~whexar.bus.emulator.port.EmulatedPort`); port errors propagate as ``OSError``."""
    import dynamixel_sdk as dxl

    return _scan(port, dxl.PacketHandler(2.0), sorted({int(i) for i in ids}))


def _reason(exc: OSError) -> str:
    """The OS's own words: pyserial wraps the ``OSError`` of ``open()`` in its message."""
    cause = exc.__context__ if isinstance(exc.__context__, OSError) else exc
    if cause.strerror:
        return f"{cause.strerror} (errno {cause.errno})" if cause.errno else cause.strerror
    return str(exc)


def _scan(port: Any, handler: Any, wanted: list[int]) -> list[ScanResult]:
    import dynamixel_sdk as dxl

    found, result = handler.broadcastPing(port)
    answered = {sid for sid in found if sid in wanted}
    if result not in (dxl.COMM_SUCCESS, dxl.COMM_RX_TIMEOUT):
        # Something answered but not cleanly: ask the others one by one.
        for sid in wanted:
            if sid not in answered:
                _, ping_result, _ = handler.ping(port, sid)
                if ping_result == dxl.COMM_SUCCESS:
                    answered.add(sid)
    results = []
    for sid in sorted(answered):
        confirmed = _confirm(port, handler, sid)
        if confirmed is not None:
            results.append(confirmed)
    return results


def _confirm(port: Any, handler: Any, sid: int) -> ScanResult | None:
    import dynamixel_sdk as dxl

    for _ in range(CONFIRM_ATTEMPTS):
        data, result, _error = handler.readTxRx(port, sid, _READ_START, _READ_LENGTH)
        if result != dxl.COMM_SUCCESS or len(data) < _READ_LENGTH:
            continue
        number = data[0] | (data[1] << 8)
        status = data[_HARDWARE_ERROR]
        return ScanResult(
            id=sid,
            model_number=number,
            model=model_name(number),
            firmware=data[_FIRMWARE],
            hardware_error=status,
            hardware_error_text=HardwareError(status).describe(),
        )
    return None
