"""The tilting board's limit (6.7.6) of a stance: slid, fell, turned, or lost a support."""

from __future__ import annotations

from types import SimpleNamespace
from typing import cast

import pytest

from whexar.actors.messages import LegLoads
from whexar.campaign import Window
from whexar.campaign.experiments.metrics import TILT_SUPPORT_FRACTION, tilt_limit_deg
from whexar.sim.run import Sample, SimResult
from whexar.sim.series import RunSeries
from whexar.sim.tilt import BoardTilt
from whexar.sim.world import SimWorld
from whexar.testing import MessageLog, RunResult

BOARD = BoardTilt(start_s=5.0, rate_deg_s=1.0, max_deg=55.0)
END = 40.0


def _stance(off: float | None, flicker: bool = False) -> SimResult:
    """A stance that never slides on the board; the RF foot leaves it from ``off`` s, or,
    with ``flicker``, reads no contact 0.2 s in every second."""
    samples = [
        Sample(t=k * 0.05, x=0.0, y=0.0, z=0.29, roll=0.0, pitch=0.0, yaw=0.0, power_w=60.0)
        for k in range(round(END / 0.05) + 1)
    ]
    loads = []
    for k in range(round(END / 0.02) + 1):
        t = k * 0.02
        lost = (off is not None and t >= off) or (flicker and t % 1.0 < 0.2)
        contacts = (not lost, True, True, True, True, True)
        loads.append(
            ("loads", LegLoads(t=t, source="sensors", seq=k, counts=(300,) * 6, contacts=contacts))
        )
    world = cast(SimWorld, SimpleNamespace(tilt=BOARD))
    return SimResult(
        samples=samples,
        run=RunResult(0, MessageLog([]), None, [], {}, END),
        world=world,
        wall_s=1.0,
        duration_s=END,
        mass_kg=8.8,
        events=[],
        series=RunSeries.of(loads),
    )


def test_a_stance_that_keeps_its_six_supports_holds_to_the_end() -> None:
    assert tilt_limit_deg(_stance(None), Window(3.0)) == pytest.approx(BOARD.angle_deg(END))


def test_a_foot_off_the_board_for_most_of_a_span_ends_the_stance() -> None:
    # Off from 25 s: the first 2 s span with it off for more than half starts at 24 s.
    got = tilt_limit_deg(_stance(25.0), Window(3.0))
    assert isinstance(got, float)
    assert got == pytest.approx(BOARD.angle_deg(25.0 - 2.0 * (1 - TILT_SUPPORT_FRACTION)), abs=0.1)


def test_a_flickering_foot_is_not_a_lost_support() -> None:
    assert tilt_limit_deg(_stance(None, flicker=True), Window(3.0)) == pytest.approx(
        BOARD.angle_deg(END)
    )
