"""The reflex campaign: its metrics on a hand-made run, its judging of rows, its report,
and the campaign file itself (every run built before any runs)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any, cast

import pytest

from whexar.actors.messages import NoFoothold, ReflexActivity, Restepped, SwingEnded
from whexar.campaign import Row, Window, load_campaign, registry
from whexar.campaign.reflexes import false_triggers, success, sweep, write_report
from whexar.config import RobotConfig
from whexar.runtime.wiring import EVENTS_CHANNEL
from whexar.sim.run import Sample, SimResult
from whexar.sim.series import RunSeries
from whexar.sim.world import SimWorld
from whexar.testing import LogEntry, MessageLog, RunResult
from whexar.testing.reflexes import locomotion_state

END = 60.0


def _activity(t: float, reflex: str, active: bool) -> ReflexActivity:
    return ReflexActivity(t=t, source=reflex, reflex=reflex, active=active)


def _fake() -> SimResult:
    """A minute of walking (standing the first 3 s); the elevator active twice, searching
    once, two swings with no ground, a re-step and a safe stop."""
    entries: list[LogEntry] = []
    samples = []
    t = 0.0
    while t <= END:
        activity = "walking" if t >= 3.0 else "standing"
        entries.append(LogEntry("locomotion", locomotion_state(t, activity)))
        samples.append(Sample(t, 0.1 * max(0.0, t - 3.0), 0.0, 0.28, 0.0, 0.0, 0.0, 50.0))
        t = round(t + 0.05, 6)
    entries += [
        LogEntry("reflex-activity", _activity(1.0, "reflex-elevator", True)),  # before 5 s
        LogEntry("reflex-activity", _activity(2.0, "reflex-elevator", False)),
        LogEntry("reflex-activity", _activity(10.0, "reflex-elevator", True)),
        LogEntry("reflex-activity", _activity(12.0, "reflex-elevator", False)),
        LogEntry("reflex-activity", _activity(20.0, "reflex-searching", True)),
    ]
    for k, outcome in enumerate(("no_contact", "completed", "no_contact")):
        swing = SwingEnded(
            t=20.0 + k,
            source="leg",
            leg=1,
            outcome=outcome,  # type: ignore[arg-type]
            ground_offset_m=0.0,
        )
        entries.append(LogEntry("swings", swing))
    events = [
        Restepped(
            t=22.0, source="c", leg=1, reflex="reflex-searching", target=(0, 0, 0), done=True
        ),
        Restepped(
            t=23.0,
            source="c",
            leg=1,
            reflex="reflex-searching",
            target=(0, 0, 0),
            done=False,
            reason="x",
        ),
        NoFoothold(t=24.0, source="reflex-searching", leg=1, searched_m=0.06, attempts=2),
    ]
    entries += [LogEntry(EVENTS_CHANNEL, e) for e in events]
    entries.sort(key=lambda e: e.message.t)
    log = MessageLog(entries)
    world = cast(SimWorld, SimpleNamespace(cfg=RobotConfig(), chain=SimpleNamespace(hooks=[])))
    return SimResult(
        samples=samples,
        run=RunResult(0, log, None, [], {}, END),
        world=world,
        wall_s=1.0,
        duration_s=END,
        mass_kg=5.0,
        events=log.events(),
        series=RunSeries.of((e.channel, e.message) for e in entries),
    )


def test_the_metrics_count_what_began_in_the_window() -> None:
    result, table, window = _fake(), registry(), Window(from_s=5.0)
    values = {
        name: table[name].fn(result, window)
        for name in (
            "elevator_activations",
            "searching_activations",
            "stepping_activations",
            "no_contact_swings",
            "restepped",
            "no_foothold",
            "walking_min",
            "x_end_m",
        )
    }
    assert values == {
        "elevator_activations": 1,  # the spell at 1 s began before the window
        "searching_activations": 1,  # still active at the end: counted
        "stepping_activations": 0,
        "no_contact_swings": 2,
        "restepped": 1,  # the refused one is no step
        "no_foothold": 1,
        "walking_min": pytest.approx(55.0 / 60.0),
        "x_end_m": pytest.approx(5.7),
    }


def _row(label: str, variation: dict[str, Any] | None = None, **metrics: Any) -> Row:
    return Row(
        id=f"{abs(hash((label, str(variation), str(metrics)))) % 10000:04d}",
        label=label,
        variation=variation or {},
        metrics={"falls": 0, **metrics},
        state_hash=None,
        outcome="ok",
    )


ROWS = [
    _row("elevator sill", x_end_m=1.9),
    _row("elevator sill", x_end_m=1.3),  # stopped at the sill
    _row("searching trench", x_end_m=1.8, no_contact_swings=0),
    _row("searching trench", x_end_m=1.8, no_contact_swings=2),  # a foot left hanging
    _row("searching deep", no_foothold=1),
    _row("stepping snag", restepped=1, x_end_m=1.0),
    _row("heading lost coxa", heading_change_deg=-3.0),
    _row("obstacle box", obstacle_activations=1, x_end_m=2.1),
    _row("obstacle box", obstacle_activations=1, x_end_m=1.2),  # measured, not over
    _row("obstacle wall", obstacle_activations=1, x_end_m=0.4),
    _row("obstacle wall", obstacle_activations=0, x_end_m=0.4),  # stopped by no reflex
    _row(
        "nominal",
        {"terrain": "flat"},
        walking_min=3.0,
        elevator_activations=0,
        searching_activations=1,
        stepping_activations=0,
        heading_hold_activations=0,
    ),
    _row(
        "nominal",
        {"terrain": "slope30"},
        walking_min=2.0,
        elevator_activations=3,
        searching_activations=0,
        stepping_activations=0,
        heading_hold_activations=0,
    ),
    _row("sweep sill", {"config.fsr.contact_on_counts": 200}, x_end_m=1.7),
    _row(
        "sweep slope23",
        {"config.fsr.contact_on_counts": 200},
        elevator_activations=2,
        walking_min=1.0,
    ),
]


def test_rows_are_judged_by_their_scenarios_criterion() -> None:
    found = success(ROWS)
    assert {k: (v[0], v[2], v[3]) for k, v in found.items()} == {
        "elevator sill": ("elevator", 1, 2),
        "searching trench": ("searching", 1, 2),
        "searching deep": ("searching", 1, 1),
        "stepping snag": ("stepping", 1, 1),
        "heading lost coxa": ("heading-hold", 1, 1),
        "heading lost coxa alone": ("heading-hold", 0, 0),  # no such row here
        "obstacle box": ("obstacle", 1, 2),
        "obstacle wall": ("obstacle", 1, 2),
    }
    fired = false_triggers(ROWS)
    assert fired["flat"]["searching"] == (1, 3.0)
    assert fired["slope30"]["elevator"] == (3, 2.0)
    assert sweep(ROWS) == {200: (1, 1, 2.0, 1.0)}


def test_the_report_is_a_table_and_a_plot(tmp_path: Path) -> None:
    md, png = write_report(ROWS, tmp_path)
    assert md == tmp_path / "reflex-campaign.md"
    assert png == tmp_path / "img" / "reflex-campaign.png"
    assert png.stat().st_size > 1000
    text = md.read_text()
    assert "| elevator | past the 6 cm sill" in text
    assert "| 50% | 1/2 |" in text
    assert "15.00 (3 in 2.0 min)" in text  # the elevator on 30°: 3 in 2 minutes
    assert "| 200 | 1/1 | 20.00 |" in text


def test_the_campaign_file_builds_every_run() -> None:
    campaign = load_campaign("reflexes")
    labels = {r.label for r in campaign.runs}
    assert labels == {
        "nominal",
        "elevator sill",
        "searching trench",
        "searching deep",
        "stepping snag",
        "heading lost coxa",
        "heading lost coxa alone",
        "obstacle box",
        "obstacle wall",
        "sweep sill",
        "sweep slope23",
    }
    assert len([r for r in campaign.runs if r.label == "nominal"]) == 18
    assert campaign.report == "reflexes"
