"""The checks, in order, and the runner.

A check runs only when every check it needs passed (``ok`` or ``warn``); otherwise it
is ``skipped``, naming the one that did not. Every port a check opened is closed once
all have run.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from typing import Final

from whexar.doctor import board, devices, host, servos
from whexar.doctor.environment import Environment
from whexar.doctor.report import Check, CheckResult, Findings, Status, skipped

CHECKS: Final[tuple[Check, ...]] = (
    Check("servo port", host.check_servo_port),
    Check("latency timer", host.check_latency_timer, ("servo port",)),
    Check("baud rate", servos.check_baud_rate, ("servo port",)),
    Check("servos", servos.check_servos, ("baud rate",)),
    Check("eeprom", servos.check_eeprom, ("baud rate",)),
    Check("voltage and temperature", servos.check_power, ("baud rate",)),
    Check("sensor board", board.check_sensor_board),
    Check("imu", devices.check_imu),
    Check("free disk", host.check_free_disk),
    Check("versions", host.check_versions),
)
"""Every check, in the order ``whexar doctor`` runs them."""


def run_checks(env: Environment, checks: Sequence[Check] = CHECKS) -> list[CheckResult]:
    """Run ``checks`` in order on ``env``; one result each."""
    found = Findings()
    results: dict[str, CheckResult] = {}
    try:
        for check in checks:
            blocker = next(
                (
                    results[n]
                    for n in check.needs
                    if n in results and results[n].status in (Status.FAIL, Status.SKIPPED)
                ),
                None,
            )
            if blocker is not None:
                results[check.name] = skipped(
                    check.name, f"needs the {blocker.name} check, which {_verb(blocker)}"
                )
            else:
                results[check.name] = check.run(env, found)
    finally:
        for close in found.closers:
            with contextlib.suppress(Exception):
                close()
    return list(results.values())


def _verb(result: CheckResult) -> str:
    return "failed" if result.status is Status.FAIL else "was skipped"


def ready(results: Sequence[CheckResult]) -> bool:
    """The robot is ready: no check failed."""
    return all(r.status is not Status.FAIL for r in results)
