"""Checks of the host: the servo port and its permissions, the USB adapter's latency
timer, free disk for recordings, Python and package versions."""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path
from typing import Final

from whexar.doctor.environment import Environment
from whexar.doctor.report import CheckResult, Findings, fail, ok, skipped, warn

UDEV_RULE: Final = "99-whexar-dynamixel.rules"
"""The rule shipped in ``config/``: latency timer 1 ms on every FTDI adapter."""
LATENCY_MS: Final = 1
"""FTDI latency timer wanted: the driver holds received bytes up to this long (FTDI
AN232B-04, "Data Throughput, Latency and Handshaking"; default 16 ms)."""
INSTALL_RULE: Final = (
    f"sudo cp config/{UDEV_RULE} /etc/udev/rules.d/ && "
    "sudo udevadm control --reload-rules && sudo udevadm trigger"
)


def check_servo_port(env: Environment, found: Findings) -> CheckResult:
    """The servo port exists and this process may read and write it (group ``dialout``)."""
    name = "servo port"
    path = Path(env.servo_port)
    absent = device(
        env,
        path,
        name,
        "the U2D2 is not plugged in, or is another device",
        "plug the U2D2 in and find its port with: ls /dev/serial/by-id/; then pass "
        "--port DEVICE or set [bus] port in the configuration",
    )
    return absent or ok(name, f"{path} exists and is readable and writable")


def device(env: Environment, path: Path, name: str, why: str, fix: str) -> CheckResult | None:
    """Check ``name`` failed: the device ``path`` does not exist (``why``, ``fix``) or this
    process may not use it (:func:`permission`); ``None`` when it is there to open."""
    if not path.exists():
        return fail(name, f"{path} does not exist: {why}", fix)
    return permission(env, path, name)


def permission(env: Environment, path: Path, name: str) -> CheckResult | None:
    """``None`` when this process may read and write the device ``path``; else check
    ``name``'s failure, naming its group and how to join it."""
    if env.access(path, os.R_OK | os.W_OK):
        return None
    group = env.group_name(env.device_gid(path))
    active = {env.group_name(g) for g in env.process_groups()}
    if group in env.user_groups() and group not in active:
        return fail(
            name,
            f"{path} belongs to group {group!r}: you joined it, but this session started before",
            "log out and in again (or run: newgrp " + group + ")",
        )
    return fail(
        name,
        f"{path} is not readable and writable by you: it belongs to group {group!r}",
        f"sudo usermod -aG {group} $USER, then log out and in again",
    )


def check_latency_timer(env: Environment, found: Findings) -> CheckResult:
    """The FTDI adapter's latency timer is 1 ms (sysfs), and the udev rule that sets it is
    installed."""
    name = "latency timer"
    device = Path(env.servo_port).resolve().name
    attribute = env.sysfs / "bus" / "usb-serial" / "devices" / device / "latency_timer"
    try:
        text = attribute.read_text().strip()
    except FileNotFoundError:
        return skipped(name, f"{env.servo_port} is not a USB-serial adapter: no latency timer")
    except OSError as exc:
        return fail(name, f"cannot read {attribute}: {exc.strerror}", None)
    try:
        ms = int(text)
    except ValueError:
        return fail(name, f"{attribute} holds {text!r}, not a number of ms", None)
    installed = any((d / UDEV_RULE).exists() for d in env.udev_rules_dirs)
    if ms == LATENCY_MS:
        if installed:
            return ok(name, f"{ms} ms on {device}; the udev rule keeps it so")
        return warn(
            name,
            f"{ms} ms on {device}, but the udev rule is not installed: the next plug-in "
            "brings back 16 ms",
            INSTALL_RULE,
        )
    once = f"echo {LATENCY_MS} | sudo tee /sys/bus/usb-serial/devices/{device}/latency_timer"
    if installed:
        return fail(
            name,
            f"{ms} ms on {device} (want {LATENCY_MS} ms): the udev rule is installed, "
            "but the adapter was plugged in before it was",
            f"unplug and replug the adapter, or run: {once}",
        )
    return fail(
        name,
        f"{ms} ms on {device} (want {LATENCY_MS} ms): every servo read waits up to "
        f"{ms} ms more; the udev rule {UDEV_RULE} is not installed",
        f"{INSTALL_RULE}, then replug the adapter (or once per boot: {once})",
    )


def check_free_disk(env: Environment, found: Findings) -> CheckResult:
    """The recordings' disk has more than ``[recording] min_free_mb`` free."""
    name = "free disk"
    folder = env.recordings()
    want_mb = env.config.recording.min_free_mb
    try:
        free_mb = env.free_bytes(folder) / 1e6
    except OSError as exc:
        return fail(name, f"cannot see the free space of {folder}: {exc.strerror}", None)
    if free_mb <= want_mb:
        return fail(
            name,
            f"{free_mb:.0f} MB free for {folder}; recordings stop below {want_mb:.0f} MB "
            "([recording] min_free_mb)",
            f"free some space: whexar log info {folder} lists the recordings; delete the "
            "oldest, or lower [recording] max_total_mb",
        )
    return ok(name, f"{free_mb:.0f} MB free for {folder} (recordings stop at {want_mb:.0f} MB)")


_REQUIREMENT: Final = re.compile(r"^\s*([A-Za-z0-9_.\-]+)\s*(?:>=\s*([0-9][0-9.]*))?\s*(;.*)?$")
MIN_PYTHON: Final = (3, 11)
"""``requires-python`` of pyproject.toml."""


def _version_tuple(text: str) -> tuple[int, ...]:
    parts = []
    for piece in text.split("."):
        digits = re.match(r"\d+", piece)
        if digits is None:
            break
        parts.append(int(digits.group()))
    return tuple(parts)


def check_versions(env: Environment, found: Findings) -> CheckResult:
    """Python is recent enough and every package whexar requires is installed, recent enough."""
    name = "versions"
    python = ".".join(str(v) for v in env.python_version)
    if tuple(env.python_version[:2]) < MIN_PYTHON:
        return fail(
            name,
            f"Python {python}; whexar needs {'.'.join(map(str, MIN_PYTHON))} or newer",
            "install a newer Python (Raspberry Pi OS bookworm has 3.11) and reinstall whexar",
        )
    problems = []
    for line in env.requirements():
        match = _REQUIREMENT.match(line)
        if match is None or (match.group(3) and "extra" in match.group(3)):
            continue  # an extra's requirement: the robot does not need it
        package, minimum = match.group(1), match.group(2)
        have = env.version(package)
        if have is None:
            problems.append(f"{package} is not installed")
        elif minimum and _version_tuple(have) < _version_tuple(minimum):
            problems.append(f"{package} {have} is older than {minimum}")
    whexar = env.version("whexar") or "not installed"
    if problems:
        return fail(
            name,
            f"{len(problems)} package{'s' if len(problems) != 1 else ''} missing or too old",
            "pip install -e . (in the whexar folder, with its virtual environment active)",
            tuple(problems),
        )
    why = env.native_bus()
    if why:  # it works without: the SDK's path, at some three times the CPU (docs/bus.md)
        return warn(
            name,
            f"Python {python}, whexar {whexar}; the compiled bus path is not built",
            "sudo apt-get install gcc python3-dev, then reinstall whexar "
            "(pip install --force-reinstall --no-deps .)",
            (why,),
        )
    return ok(
        name,
        f"Python {python}, whexar {whexar}, every required package installed, "
        "the bus path compiled",
    )


def reason(exc: OSError) -> str:
    """The OS's own words for ``exc`` (pyserial wraps the ``OSError`` of ``open()``)."""
    cause = exc.__context__ if isinstance(exc.__context__, OSError) else exc
    if cause.strerror:
        return f"{cause.strerror} ({errno.errorcode.get(cause.errno or 0, cause.errno)})"
    return str(exc)
