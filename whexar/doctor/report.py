"""A check's result, and what the checks found that later ones build on."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from whexar.bus.scan import ScanResult


class Status(StrEnum):
    """How a check came out; only :attr:`FAIL` keeps the robot from being ready."""

    OK = "ok"
    WARN = "warn"
    """Works, but not as well as it should (the fix is worth doing)."""
    FAIL = "fail"
    SKIPPED = "skipped"
    """Not run: a check it needs failed, or it does not apply (``summary`` says which)."""


@dataclass(frozen=True, slots=True)
class CheckResult:
    """One check: what it found, and when something is wrong, the command that fixes it."""

    name: str
    status: Status
    summary: str
    """One line: what is fine, or what is wrong."""
    fix: str | None = None
    """The command (or the step) that fixes it; ``None`` when nothing needs fixing."""
    details: tuple[str, ...] = ()
    """One line per item when several are wrong (a servo each)."""

    def as_dict(self) -> dict[str, Any]:
        """The fields as a JSON-ready dictionary."""
        return {
            "name": self.name,
            "status": str(self.status),
            "summary": self.summary,
            "fix": self.fix,
            "details": list(self.details),
        }


def ok(name: str, summary: str) -> CheckResult:
    """A passed check."""
    return CheckResult(name, Status.OK, summary)


def warn(name: str, summary: str, fix: str | None, details: tuple[str, ...] = ()) -> CheckResult:
    """A check that passed with a reservation."""
    return CheckResult(name, Status.WARN, summary, fix, details)


def fail(name: str, summary: str, fix: str | None, details: tuple[str, ...] = ()) -> CheckResult:
    """A failed check."""
    return CheckResult(name, Status.FAIL, summary, fix, details)


def skipped(name: str, summary: str) -> CheckResult:
    """A check that did not run, and why."""
    return CheckResult(name, Status.SKIPPED, summary)


@dataclass(slots=True)
class Findings:
    """What earlier checks learnt, for the later ones: the open servo port, the scan."""

    port: Any = None
    """The servo port, open at the configured rate (from the baud-rate check on)."""
    scan: list[ScanResult] = field(default_factory=list)
    eeprom: dict[int, bytes] = field(default_factory=dict)
    """Addresses 0–63 (the EEPROM area) of each configured servo that answered."""
    closers: list[Callable[[], None]] = field(default_factory=list)
    """What to close once every check has run."""


@dataclass(frozen=True, slots=True)
class Check:
    """A named check, the checks it needs, and the function that runs it."""

    name: str
    run: Callable[[Any, Findings], CheckResult]
    """``run(environment, findings)``."""
    needs: tuple[str, ...] = ()
    """Checks that must not have failed or been skipped for this one to run."""
