"""Fixtures of the runtime's tests."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from types import FrameType

import pytest

HANG_AFTER_S = 20.0
"""Wall seconds after which a guarded test is taken to hang (it takes well under one)."""


class Hung(Exception):  # noqa: N818 - what happened, not an error class of ours
    """Raised into a test that did not finish within :data:`HANG_AFTER_S`."""


@pytest.fixture
def hang_guard() -> Iterator[None]:
    """Fail, rather than hang, a test whose bug would spin the event loop forever.

    A Python-level SIGALRM handler raises :class:`Hung` wherever the main
    thread is — in the loop's own code too — so a regression (a virtual loop
    spinning in place, a publisher that never yields) fails in bounded time.
    """

    def hung(signum: int, frame: FrameType | None) -> None:
        raise Hung(f"the test did not finish within {HANG_AFTER_S:g} s: it hangs")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.setitimer(signal.ITIMER_REAL, HANG_AFTER_S)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
