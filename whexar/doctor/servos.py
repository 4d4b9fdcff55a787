"""Checks of the servo bus: the baud rate answers, the configured servos (and nothing
else) answer with their model, firmware and ID, their EEPROM agrees with the
configuration, and their supply voltage and temperatures are in range.

Each check uses the port the baud-rate check opened (:attr:`Findings.port`), through
dynamixel-sdk's own packet handler: a U2D2, ``whexar emulate``'s pty, or an
:class:`~whexar.bus.emulator.port.EmulatedPort` in tests.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from typing import Any, Final

from whexar.actors.bus.servos import Servo, servo_table
from whexar.bus import control_table as ct
from whexar.bus.scan import ScanResult, scan_port
from whexar.doctor.environment import Environment
from whexar.doctor.host import reason
from whexar.doctor.report import CheckResult, Findings, fail, ok, warn
from whexar.errors import DeviceGoneError

BAUD_CODES: Final[Mapping[int, int]] = {
    9600: 0,
    57600: 1,
    115200: 2,
    1_000_000: 3,
    2_000_000: 4,
    3_000_000: 5,
    4_000_000: 6,
}
"""Baud Rate (8) value of each rate (e-manual, MX (2.0) control table; factory: 1, 57600)."""
TESTED_FIRMWARE: Final = 42
"""The MX (2.0) firmware whexar is built and tested against (the emulator's, v42: the
e-manual's first with Clear and a refused broadcast Factory Reset)."""
DRIVE_MODE: Final = 0
"""Drive Mode (10) whexar assumes: bit 0 clear, normal direction (the DH table's
``theta_sign`` gives each joint's sense); bit 2 clear, velocity-based profile (e-manual)."""
EEPROM_LENGTH: Final = 64
"""Addresses 0–63, the EEPROM area, in one Read (e-manual: RAM starts at Torque Enable, 64)."""
POWER: Final = ct.block(["present_input_voltage", "present_temperature"])
"""Present Input Voltage (144) and Present Temperature (146), one Read."""
SUPPLY_TOLERANCE: Final = 0.1
"""A supply this far (relative) from ``[robot] supply_voltage_v`` is worth a warning."""
TEMPERATURE_MARGIN_C: Final = 10
"""A servo this close to its Temperature Limit (31) is worth a warning."""
WIZARD: Final = "with torque off, in DYNAMIXEL Wizard 2.0 (whexar writes no other EEPROM)"


def _model_of(cfg_models: Mapping[int, str], sid: int) -> str:
    return cfg_models.get(sid, "?")


def _ping_at(port: Any, rate: int) -> list[int]:
    """IDs that answer a broadcast ping at ``rate`` (the port is left at that rate)."""
    import dynamixel_sdk as dxl

    if not port.setBaudRate(rate):
        return []
    found, _ = dxl.PacketHandler(2.0).broadcastPing(port)
    return sorted(found)


def check_baud_rate(env: Environment, found: Findings) -> CheckResult:
    """Some servo answers at the configured rate; if none, which rate they answer at."""
    name = "baud rate"
    baud = env.config.bus.baudrate
    try:
        port = env.open_servo_port(env.servo_port, baud)
    except DeviceGoneError as exc:
        return fail(name, str(exc), "check the adapter with: ls -l /dev/serial/by-id/")
    except OSError as exc:
        return fail(name, f"cannot open {env.servo_port}: {reason(exc)}", None)
    found.port = port
    found.closers.append(lambda: _close(port))
    try:
        scan = scan_port(port)
        if scan:
            found.scan = scan
            return ok(name, f"{len(scan)} servos answer at {baud} bps")
        # Nobody answered: find the rate they are at, to say what to change.
        for rate in (r for r in BAUD_CODES if r != baud):
            answered = _ping_at(port, rate)
            if answered:
                port.setBaudRate(baud)
                return fail(
                    name,
                    f"no servo answers at {baud} bps; {len(answered)} answer at {rate} bps",
                    f"set [bus] baudrate = {rate}, or set every servo's Baud Rate (8) to "
                    f"{BAUD_CODES[baud]} ({baud} bps) {WIZARD}",
                )
        port.setBaudRate(baud)
    except OSError as exc:
        return fail(name, f"{env.servo_port} failed: {reason(exc)}", None)
    return fail(
        name,
        f"no servo answers on {env.servo_port} at any rate",
        "check the servos' supply (the power switch, the battery) and the bus cable "
        "from the U2D2 to the first servo",
    )


def _close(port: Any) -> None:
    with contextlib.suppress(Exception):
        port.closePort()


def check_servos(env: Environment, found: Findings) -> CheckResult:
    """Every configured servo answers with its model and a tested firmware, without a
    hardware error; nothing else is on the bus."""
    name = "servos"
    want = env.config.servos()
    seen = {s.id: s for s in found.scan}
    missing = [sid for sid in want if sid not in seen]
    extra = [s for s in found.scan if s.id not in want]
    wrong = [s for s in found.scan if s.id in want and s.model != want[s.id]]
    errors = [s for s in found.scan if s.id in want and s.hardware_error]
    old = [s for s in found.scan if s.id in want and s.firmware < TESTED_FIRMWARE]
    lines = [
        *(f"servo {sid} ({want[sid]}) does not answer" for sid in missing),
        *(f"servo {s.id} is an {s.model}; the configuration says {want[s.id]}" for s in wrong),
        *(f"servo {s.id} ({s.model}) answers but is not in the configuration" for s in extra),
        *(f"servo {s.id}: hardware error {s.hardware_error_text}" for s in errors),
    ]
    if missing or wrong or extra or errors:
        return fail(
            name,
            _summary(len(want), missing, wrong, extra, errors),
            _fixes(want, missing, wrong, extra, errors),
            tuple(lines),
        )
    if old:
        return warn(
            name,
            f"{len(old)} servo{'s' if len(old) != 1 else ''} with firmware older than "
            f"v{TESTED_FIRMWARE}, the one whexar is tested against",
            "update the firmware in DYNAMIXEL Wizard 2.0 (Tools → Firmware Update)",
            tuple(f"servo {s.id} ({s.model}): firmware v{s.firmware}" for s in old),
        )
    firmware = sorted({s.firmware for s in found.scan})
    return ok(
        name,
        f"all {len(want)} servos answer with their model, firmware "
        f"{', '.join(f'v{f}' for f in firmware)}; nothing else on the bus",
    )


def _summary(
    total: int,
    missing: list[int],
    wrong: list[ScanResult],
    extra: list[ScanResult],
    errors: list[ScanResult],
) -> str:
    parts = []
    if missing:
        parts.append(f"{len(missing)} of {total} missing")
    if wrong:
        parts.append(f"{len(wrong)} of another model")
    if extra:
        parts.append(f"{len(extra)} not in the configuration")
    if errors:
        parts.append(f"{len(errors)} with a hardware error")
    return "servos: " + ", ".join(parts)


def _fixes(
    want: Mapping[int, str],
    missing: list[int],
    wrong: list[ScanResult],
    extra: list[ScanResult],
    errors: list[ScanResult],
) -> str:
    fixes = []
    if len(missing) == 1 and len(extra) == 1 and extra[0].model == want[missing[0]]:
        fixes.append(
            f"servo {extra[0].id} is likely servo {missing[0]} with the wrong ID: set its "
            f"ID (7) to {missing[0]} {WIZARD}"
        )
    else:
        if missing:
            fixes.append(
                "check the cable and the supply of each missing servo (a missing run of "
                "IDs points at the cable before the first)"
            )
        if extra:
            fixes.append("give each unknown servo its configured ID, or take it off the bus")
    if wrong:
        fixes.append("fit the configured model, or correct [joints] in the configuration")
    if errors:
        fixes.append("find the cause (load, heat, supply), then power-cycle the servos")
    return "; ".join(fixes)


def _configured(env: Environment, found: Findings) -> list[Servo]:
    """The configured servos that answered with the configured model."""
    table = servo_table(env.config)
    seen = {s.id: s for s in found.scan}
    return [
        s
        for sid, s in table.items()
        if sid in seen and seen[sid].model_number == s.model.model_number
    ]


def _read(port: Any, sid: int, start: int, length: int) -> bytes | None:
    import dynamixel_sdk as dxl

    data, result, _ = dxl.PacketHandler(2.0).readTxRx(port, sid, start, length)
    return bytes(data) if result == dxl.COMM_SUCCESS and len(data) == length else None


def _register(servo: Servo, eeprom: bytes, name: str) -> int:
    return servo.model.register(name).decode(eeprom)


def check_eeprom(env: Environment, found: Findings) -> CheckResult:
    """Each servo's EEPROM against the configuration: position limits (the servo refuses
    a goal outside them), voltage limits around the supply, Drive Mode, and the Return
    Delay Time and Operating Mode that start-up writes."""
    name = "eeprom"
    cfg = env.config
    servos = _configured(env, found)
    if not servos:
        return fail(name, "no configured servo answered to read its EEPROM", None)
    delay = ct.return_delay_units(cfg.bus.return_delay_time_us * 1e-6)
    supply = cfg.robot.supply_voltage_v
    bad: list[str] = []
    later: list[str] = []
    try:
        for s in servos:
            eeprom = _read(found.port, s.id, 0, EEPROM_LENGTH)
            if eeprom is None:
                bad.append(f"{s.name} (servo {s.id}): its EEPROM could not be read")
                continue
            found.eeprom[s.id] = eeprom

            def get(register: str, s: Servo = s, eeprom: bytes = eeprom) -> int:
                return _register(s, eeprom, register)

            if get("drive_mode") != DRIVE_MODE:
                bad.append(
                    f"servo {s.id}: Drive Mode (10) is {get('drive_mode')}, whexar needs "
                    f"{DRIVE_MODE} (normal direction, velocity-based profile)"
                )
            if not s.endless:
                lo, hi = get("min_position_limit"), get("max_position_limit")
                if lo > s.lo_tick or hi < s.hi_tick:
                    bad.append(
                        f"servo {s.id}: position limits {lo}–{hi} (48, 52) refuse goals the "
                        f"configuration allows ({s.lo_tick}–{s.hi_tick}); set them so"
                    )
            vmin = ct.voltage_to_v(get("min_voltage_limit"))
            vmax = ct.voltage_to_v(get("max_voltage_limit"))
            if not vmin <= supply <= vmax:
                bad.append(
                    f"servo {s.id}: voltage limits {vmin:.1f}–{vmax:.1f} V (32, 34) exclude "
                    f"the {supply:.1f} V supply"
                )
            if get("return_delay_time") != delay:
                later.append(
                    f"servo {s.id}: Return Delay Time (9) {get('return_delay_time')}, "
                    f"configured {delay}"
                )
            if get("operating_mode") != s.mode:
                later.append(
                    f"servo {s.id}: Operating Mode (11) {get('operating_mode')}, needs {s.mode}"
                )
    except OSError as exc:
        return fail(name, f"{env.servo_port} failed: {reason(exc)}", None)
    if bad:
        return fail(
            name,
            f"{len(bad)} EEPROM setting{'s' if len(bad) != 1 else ''} disagree with the "
            "configuration",
            f"write the values named {WIZARD}",
            tuple(bad + later),
        )
    if later:
        return warn(
            name,
            f"{len(later)} setting{'s' if len(later) != 1 else ''} differ; start-up writes "
            "them, with the servo's torque off for a moment",
            None,
            tuple(later),
        )
    return ok(name, f"EEPROM of {len(servos)} servos agrees with the configuration")


def check_power(env: Environment, found: Findings) -> CheckResult:
    """Each servo's supply voltage within its limits and near ``[robot] supply_voltage_v``,
    its temperature below its Temperature Limit (31)."""
    name = "voltage and temperature"
    servos = _configured(env, found)
    if not servos:
        return fail(name, "no configured servo answered", None)
    supply = env.config.robot.supply_voltage_v
    bad: list[str] = []
    close: list[str] = []
    volts: list[float] = []
    temps: list[int] = []
    try:
        for s in servos:
            data = _read(found.port, s.id, POWER.start, POWER.length)
            if data is None:
                bad.append(f"servo {s.id}: no answer to a read of voltage and temperature")
                continue
            values = POWER.decode(data)
            v = ct.voltage_to_v(values["present_input_voltage"])
            t = values["present_temperature"]
            volts.append(v)
            temps.append(t)
            eeprom = found.eeprom.get(s.id)
            reg = s.model.registers
            limit = reg["temperature_limit"].decode(eeprom) if eeprom else 80
            vmin = ct.voltage_to_v(reg["min_voltage_limit"].decode(eeprom)) if eeprom else 9.5
            vmax = ct.voltage_to_v(reg["max_voltage_limit"].decode(eeprom)) if eeprom else 16.0
            if not vmin <= v <= vmax:
                bad.append(f"servo {s.id}: {v:.1f} V, outside its limits {vmin:.1f}–{vmax:.1f} V")
            elif abs(v - supply) > SUPPLY_TOLERANCE * supply:
                close.append(f"servo {s.id}: {v:.1f} V, the supply is {supply:.1f} V")
            if t >= limit:
                bad.append(f"servo {s.id}: {t} °C, at its limit {limit} °C")
            elif t >= limit - TEMPERATURE_MARGIN_C:
                close.append(f"servo {s.id}: {t} °C, near its limit {limit} °C")
    except OSError as exc:
        return fail(name, f"{env.servo_port} failed: {reason(exc)}", None)
    span = f"{min(volts):.1f}–{max(volts):.1f} V, {min(temps)}–{max(temps)} °C" if volts else ""
    if bad:
        return fail(
            name,
            f"{len(bad)} servo reading{'s' if len(bad) != 1 else ''} out of range",
            "charge or replace the battery (check the supply under load); let hot servos cool",
            tuple(bad + close),
        )
    if close:
        return warn(
            name,
            f"{span}: {len(close)} near a limit",
            "charge the battery; let hot servos cool before a long run",
            tuple(close),
        )
    return ok(name, f"{span} on {len(servos)} servos")
