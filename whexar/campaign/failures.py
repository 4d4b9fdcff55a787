"""Single servo failures as a campaign: their metrics and their table.

Theory of operation
-------------------
The campaign ``config/campaigns/servo-failures.toml`` walks the tripod gait
on the flat and silences one servo for good 5 s into the walk (a bus fault
plan of kind ``silent``: the servo neither hears nor answers, and holds its
last goal once its Bus Watchdog fires), once for each of the 42 servos. The
metrics here say what became of the robot; :func:`write_report` turns the
rows into ``servo-failures.md`` and a legs × joints picture.

*Which servo, and when.* A metric sees the run, not the campaign's
variation, so the failure is read back from the run itself: the fault
injector attached to the emulated chain (its plan and its log of faults
started) gives the servo and the time the fault began; without an injector
(a recording, a hand-made result) the first servo the bus reported a fault
of stands in, from its first :class:`~whexar.actors.messages.ServoFault`.
Leg and joint names come from the run's own configuration
(``legs[].servo_ids``), so a renumbered robot is named right.

*After the failure* is from the fault's start to the end of the measuring
window, and never past the run's duration less :data:`STOP_LAG_S`: at the
end of a run the runtime stops and the coordinator sits the robot down, and
that sit-down is the run ending, not the robot's reaction.

*The outcome* (:func:`robot_outcome`), decided in this order:

1. ``fall`` — after the failure the body tilted past 60° (the simulation's
   :data:`~whexar.sim.run.FALLEN_TILT_RAD`, as the generic ``fell``), or its
   centre sank by more than :data:`COLLAPSE_DROP_FRACTION` of its height at
   the failure while the coordinator was not sitting down: it lies on its
   belly or its side.
2. ``safe stop`` — the runtime stopped the robot (a :class:`BusLost` or
   :class:`~whexar.runtime.messages.SafeStop` after the failure), or the
   coordinator is no longer moving at the end (standing, sitting down,
   seated): it stopped under control.
3. ``stalled`` — the coordinator still walks, but the body keeps less than
   :data:`STALL_SPEED_FRACTION` of its speed before the failure: it treads
   in place.
4. ``walk goes on`` — the coordinator still walks and the body still goes.

*A stop in simulation.* The world's time is the bus's: once the bus
scheduler stops cycling, nothing steps the world, and the samples keep the
time and pose of that moment (:func:`world_stopped_at_s` says when). After a
lost servo the scheduler cycles on while the robot sits down, until it parks
the servos; only a lost port stops it at once. Such a run shows the robot as
it stood when the cycles ended, not what parking the servos did after.

A run whose data does not allow a decision (no samples, no failure found)
has no outcome (``None``); no metric raises on bad data.
"""

from __future__ import annotations

import itertools
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Final, cast

from whexar.actors.messages import BusLost, ServoDegraded, ServoFault
from whexar.bus.emulator.faults import FaultInjector
from whexar.campaign.metrics import MetricFn, Value, Window, metric, progress_speed
from whexar.campaign.spec import config_note
from whexar.record.plots import new_figure, save_figure
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.runtime.messages import ActorStopped, SafeStop, StopRequested
from whexar.sim.run import FALLEN_TILT_RAD, SAMPLE_PERIOD_S, Quiet, progress, travelled
from whexar.sim.series import LocomotionPoint

if TYPE_CHECKING:
    from whexar.campaign.rows import Row
    from whexar.sim.run import Sample, SimResult

# --------------------------------------------------------------------------- thresholds

STOP_LAG_S: Final = 0.1
"""The end of a run is its duration less this: the coordinator stamps its state with the
servo states' time, which lags the runtime's stop by up to a bus cycle, so the sit-down
that ends every run would otherwise show as the robot's own reaction."""
COLLAPSE_DROP_FRACTION: Final = 1 / 3
"""A body centre that sinks by more than this fraction of its height at the failure,
without a sit-down, lies on the ground: standing, WHexaR's centre is about 0.28 m up and
seated 0.08 m, so a third is well past a stumble and short of seated."""
STALL_SPEED_FRACTION: Final = 0.25
"""A walk that keeps less than this fraction of its speed before the failure treads in
place rather than goes on."""
STILL_WORLD_S: Final = 0.5
"""Samples of the same world time for this long of the runtime's time: the world stopped."""
BEFORE_S: Final = 3.0
"""The speed before the failure is measured over this long (three tripod steps at 1 Hz)."""
MOVING: Final = frozenset({"walking", "riding", "hybrid", "transition"})
"""The coordinator's activities in which the robot is under way."""
SITTING: Final = frozenset({"sitting_down", "seated"})
"""Activities in which the body is lowered on purpose."""
ROUTINE: Final = (*Quiet, ActorStopped)
"""Events that are no reaction to a failure: start-up and actors stopping (a swing's end is
no event: it has its own channel)."""
OUTCOMES: Final = ("walk goes on", "stalled", "safe stop", "fall")
"""The robot's outcomes, from the best to the worst."""
OUTCOME_COLOURS: Final = {
    "walk goes on": "#4caf50",
    "stalled": "#ffc107",
    "safe stop": "#ff9800",
    "fall": "#e53935",
}
NO_OUTCOME_COLOUR: Final = "#bdbdbd"
REPORT_NAME: Final = "servo-failures"
"""``servo-failures.md`` and ``img/servo-failures.png`` in the report's folder."""


# --------------------------------------------------------------------------- the failure


@dataclass(frozen=True)
class Failure:
    """The servo that failed in a run, and when: ``t`` s, the fault's start."""

    servo_id: int
    t: float
    leg: int | None
    """Index into :data:`~whexar.robot.LEG_NAMES`; ``None`` for an ID not on the robot."""
    joint: int | None
    """Index into :data:`~whexar.robot.JOINT_NAMES`."""

    @property
    def leg_name(self) -> str | None:
        """``"RF"``… or ``None``."""
        return None if self.leg is None else LEG_NAMES[self.leg]

    @property
    def joint_name(self) -> str | None:
        """``"femur"``… or ``None``."""
        return None if self.joint is None else JOINT_NAMES[self.joint]


def _locate(result: SimResult, servo_id: int) -> tuple[int | None, int | None]:
    """(leg, joint) of ``servo_id`` in the run's configuration."""
    try:
        legs = result.world.cfg.legs
    except AttributeError:
        return None, None
    for leg, spec in enumerate(legs):
        ids = list(spec.servo_ids)
        if servo_id in ids:
            return leg, ids.index(servo_id)
    return None, None


def _injected(result: SimResult) -> tuple[int, float] | None:
    """(servo, start) of the first silent fault the run's injector started."""
    try:
        hooks = list(result.world.chain.hooks)
    except AttributeError:
        return None
    for hook in hooks:
        if not isinstance(hook, FaultInjector):
            continue
        started: dict[int, float] = {}
        for t, text in hook.log:
            # "fault 0: silent servo 3 started (at 8 s, for good)"
            head, _, rest = text.partition(":")
            if " started (" in rest and head.startswith("fault "):
                try:
                    started.setdefault(int(head.split()[1]), t)
                except ValueError:
                    continue
        for index, fault in enumerate(hook.plan.faults):
            if fault.kind == "silent" and fault.ids and index in started:
                return fault.ids[0], started[index]
    return None


def failure(result: SimResult) -> Failure | None:
    """The run's failed servo: from its fault injector, else from the bus's first fault."""
    found = _injected(result)
    if found is None:
        faults = [e for e in result.events if isinstance(e, ServoFault)]
        if not faults:
            return None
        found = faults[0].servo_id, faults[0].t
    sid, t = found
    return Failure(sid, t, *_locate(result, sid))


def _end(result: SimResult, window: Window) -> float:
    """Where "after the failure" ends: the window's end, at most the duration less the lag."""
    end = result.duration_s - STOP_LAG_S
    return end if window.to_s is None else min(window.to_s, end)


def _after(result: SimResult, window: Window) -> tuple[Failure, list[Sample]] | None:
    """The failure and the samples from it to the end (``None`` if either is missing)."""
    f = failure(result)
    if f is None:
        return None
    samples = Window(f.t, _end(result, window)).samples(result)
    return (f, samples) if samples else None


def _states(result: SimResult, t0: float, t1: float) -> list[LocomotionPoint]:
    return result.series.locomotion.between(t0, t1)


# --------------------------------------------------------------------------- the metrics


def _failure_field(attr: str) -> MetricFn:
    def fn(result: SimResult, window: Window) -> Value:
        f = failure(result)
        return None if f is None else cast(Value, getattr(f, attr))

    return fn


for _name, _attr, _unit, _text in (
    (
        "failed_servo",
        "servo_id",
        "",
        "the servo the run silenced (from its fault plan, else the bus)",
    ),
    ("failed_leg", "leg_name", "", "the failed servo's leg (RF, LF, RM, LM, RR, LR)"),
    ("failed_joint", "joint_name", "", "the failed servo's joint (coxa … wheel)"),
    ("failed_at_s", "t", "s", "when the servo went silent"),
):
    metric(_name, _unit, _text)(_failure_field(_attr))


@metric("detected_after_s", "s", "from the failure to the bus leaving the servo out (degraded)")
def detected_after_s(result: SimResult, window: Window) -> Value:
    f = failure(result)
    if f is None:
        return None
    for e in result.events:
        if isinstance(e, ServoDegraded) and e.servo_id == f.servo_id and e.t >= f.t - 1e-9:
            return e.t - f.t
    return None


@metric("distance_after_m", "m", "length of the body's path from the failure to the end")
def distance_after_m(result: SimResult, window: Window) -> Value:
    found = _after(result, window)
    return None if found is None else travelled(found[1])


@metric(
    "progress_after_m",
    "m",
    "net progress: the body's displacement from the failure to the end (a robot treading "
    "in place has a path, distance_after_m, and no progress)",
)
def progress_after_m(result: SimResult, window: Window) -> Value:
    found = _after(result, window)
    return None if found is None else progress(found[1])


@metric(
    "speed_kept",
    "",
    f"net progress speed after the failure over the same in the {BEFORE_S:g} s before it "
    "(1: unchanged; a robot treading in place keeps none)",
)
def speed_kept(result: SimResult, window: Window) -> Value:
    found = _after(result, window)
    if found is None:
        return None
    f, after = found
    before = progress_speed(Window(f.t - BEFORE_S, f.t).samples(result))
    # Over the whole stretch after the failure, not the samples': once the runtime stops,
    # nothing steps the world any more and the samples stop at that time; the robot
    # made no more way.
    span = _end(result, window) - f.t
    if before is None or before < 1e-3 or span <= 0:
        return None
    return progress(after) / span / before


@metric("heading_change_deg", "°", "change of the body's yaw from the failure to the end")
def heading_change_deg(result: SimResult, window: Window) -> Value:
    found = _after(result, window)
    if found is None:
        return None
    _, s = found
    turn = s[-1].yaw - s[0].yaw
    return math.degrees(math.atan2(math.sin(turn), math.cos(turn)))


@metric("max_tilt_after_deg", "°", "largest |roll| or |pitch| from the failure to the end")
def max_tilt_after_deg(result: SimResult, window: Window) -> Value:
    found = _after(result, window)
    return None if found is None else math.degrees(max(s.tilt for s in found[1]))


@metric("height_drop_m", "m", "how far the body centre sank below its height at the failure")
def height_drop_m(result: SimResult, window: Window) -> Value:
    found = _after(result, window)
    if found is None:
        return None
    s = found[1]
    return max(0.0, s[0].z - min(x.z for x in s))


@metric("stopped_at_s", "s", "when the runtime stopped the robot (BusLost / SafeStop), if it did")
def stopped_at_s(result: SimResult, window: Window) -> Value:
    f = failure(result)
    if f is None:
        return None
    for e in result.events:
        if isinstance(e, BusLost | SafeStop) and e.t >= f.t - 1e-9:
            return e.t
    return None


@metric(
    "world_stopped_at_s",
    "s",
    "when the simulated world stopped advancing before the end, if it did: nothing steps "
    "it once the bus stops cycling, so the run shows nothing after that",
)
def world_stopped_at_s(result: SimResult, window: Window) -> Value:
    # The run samples the world every SAMPLE_PERIOD_S of the runtime's clock, and a
    # sample's time is the world's: samples that keep the same time are a world that
    # stands still while the runtime goes on.
    end = _end(result, window)
    same = 0
    for a, b in itertools.pairwise(result.samples):
        if a.t > end:
            break
        same = same + 1 if b.t == a.t else 0
        if same * SAMPLE_PERIOD_S >= STILL_WORLD_S:
            return a.t
    return None


@metric(
    "reaction",
    "",
    "the runtime's events from the failure to the end, counted by type in order of first "
    "occurrence (routine ones left out: start-up, steps' ends, actors stopping)",
)
def reaction(result: SimResult, window: Window) -> Value:
    f = failure(result)
    if f is None:
        return None
    end = _end(result, window)
    counts: Counter[str] = Counter()
    for e in result.events:
        if not f.t - 1e-9 <= e.t <= end + 1e-9 or isinstance(e, ROUTINE):
            continue
        if isinstance(e, StopRequested) and not e.reason.startswith("safe stop"):
            continue  # the run's end, or a signal: no reaction of the robot's
        counts[type(e).__name__] += 1
    return " ".join(name if n == 1 else f"{name}×{n}" for name, n in counts.items())


@metric(
    "robot_outcome",
    "",
    "what became of the robot after the failure: walk goes on, stalled, safe stop or fall "
    "(whexar.campaign.failures documents the rule)",
)
def robot_outcome(result: SimResult, window: Window) -> Value:
    found = _after(result, window)
    if found is None:
        return None
    f, after = found
    end = after[-1].t if after[-1].t > f.t else _end(result, window)
    states = _states(result, f.t, _end(result, window))
    sat = any(m.activity in SITTING for m in states)
    z0 = after[0].z
    sank = z0 > 0 and (z0 - min(s.z for s in after)) > COLLAPSE_DROP_FRACTION * z0
    if any(s.tilt > FALLEN_TILT_RAD for s in after) or (sank and not sat):
        return "fall"
    stopped = stopped_at_s(result, Window(f.t, end)) is not None
    if stopped or not states or states[-1].activity not in MOVING:
        return "safe stop"
    kept = speed_kept(result, window)
    if isinstance(kept, float) and kept < STALL_SPEED_FRACTION:
        return "stalled"
    return "walk goes on"


# --------------------------------------------------------------------------- the report


@dataclass(frozen=True)
class _Line:
    """One servo's line of the table."""

    servo_id: int | None
    leg: str
    joint: str
    outcome: str | None
    progress_m: float | None
    """The net progress from the failure to the end (m)."""
    speed_kept: float | None
    heading_deg: float | None
    detected_s: float | None
    events: str
    failed_at_s: float | None
    world_stopped_s: float | None


def _planned_servo(row: Row) -> int | None:
    """The servo a row's variation silences, for a run that gave no metrics."""
    # A grid's ids override the inline plan's, so they are looked at first.
    keys = sorted(row.variation, key=lambda k: not k.endswith(".ids"))
    for key in keys:
        value = row.variation[key]
        if key == "faults" and isinstance(value, Mapping):
            plan = value.get("faults")
            first = plan[0] if isinstance(plan, list) and plan else {}
            value = first.get("ids") if isinstance(first, Mapping) else None
        elif not key.endswith(".ids"):
            continue
        if isinstance(value, list | tuple) and value and isinstance(value[0], int):
            return value[0]
    return None


def _number(value: Value) -> float | None:
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


def _line(row: Row) -> _Line:
    m = row.metrics
    sid = m.get("failed_servo")
    servo = sid if isinstance(sid, int) and not isinstance(sid, bool) else _planned_servo(row)
    leg, joint = m.get("failed_leg"), m.get("failed_joint")
    if not isinstance(leg, str) or not isinstance(joint, str):
        leg, joint = "?", "?"
        if servo is not None and 1 <= servo <= len(LEG_NAMES) * len(JOINT_NAMES):
            # The default numbering (thesis eq. 4.2–4.3), for a run that named nothing.
            leg, joint = LEG_NAMES[(servo - 1) // 7], JOINT_NAMES[(servo - 1) % 7]
    outcome = m.get("robot_outcome")
    events = m.get("reaction")
    if row.outcome != "ok":
        outcome, events = None, f"run failed: {row.error or 'unknown error'}"
    return _Line(
        servo,
        leg,
        joint,
        outcome if isinstance(outcome, str) else None,
        _number(m.get("progress_after_m")),
        _number(m.get("speed_kept")),
        _number(m.get("heading_change_deg")),
        _number(m.get("detected_after_s")),
        events if isinstance(events, str) else "",
        _number(m.get("failed_at_s")) or _planned_time(row),
        _number(m.get("world_stopped_at_s")),
    )


def _fmt(value: float | None, spec: str) -> str:
    return "–" if value is None else format(value, spec)


def _planned_time(row: Row) -> float | None:
    """When a row's variation has its fault start, for a run that gave no time."""
    plan = row.variation.get("faults")
    faults = plan.get("faults") if isinstance(plan, Mapping) else None
    first = faults[0] if isinstance(faults, list) and faults else None
    at = first.get("at_s") if isinstance(first, Mapping) else None
    return _number(at)


def _failure_times(lines: Sequence[_Line]) -> str:
    """``"8 s"``, or ``"7–8 s"`` when the runs differ."""
    times = sorted({round(ln.failed_at_s, 2) for ln in lines if ln.failed_at_s is not None})
    if not times:
        return "?"
    return f"{times[0]:g} s" if len(times) == 1 else f"{times[0]:g}–{times[-1]:g} s"


def _markdown(lines: Sequence[_Line], image: str, config: str | None = None) -> str:
    counts = Counter(line.outcome for line in lines)
    summary = ", ".join(f"{name}: {counts[name]}" for name in OUTCOMES if counts[name])
    if counts[None]:
        summary += f", no outcome: {counts[None]}"
    by_joint: dict[str, Counter[str | None]] = {}
    for line in lines:
        by_joint.setdefault(line.joint, Counter())[line.outcome] += 1
    out = [
        "# Single servo failures",
        "",
        "Each servo of WHexaR silenced for good (fault kind `silent`: it neither hears nor",
        "answers; its Bus Watchdog then holds its last goal) during a tripod walk on the flat,",
        f"at {_failure_times(lines)} of the run, one run per servo:",
        "`whexar campaign config/campaigns/servo-failures.toml`. This page is written by",
        "`whexar.campaign.failures.write_report` from the runs. There is no target on the",
        "outcomes yet: the table shows where the robot is weak.",
        "",
        *config_note(config),
        f"**{len(lines)} servos** — {summary}.",
        "",
        f"![outcome of each servo's failure, legs × joints]({image})",
        "",
        "## By joint",
        "",
        "| joint | " + " | ".join(OUTCOMES) + " |",
        "|---|" + "---:|" * len(OUTCOMES),
    ]
    for joint in [*JOINT_NAMES, *sorted(set(by_joint) - set(JOINT_NAMES))]:
        if joint in by_joint:
            c = by_joint[joint]
            out.append(f"| {joint} | " + " | ".join(str(c[o]) for o in OUTCOMES) + " |")
    out += [
        "",
        "## Each servo",
        "",
        "From the failure to the end of the walk: the net progress the body made, the speed",
        "it kept (progress against the 3 s before the failure) and how far its heading turned.",
        "*Detected* is how long the bus took to leave the servo out (`ServoDegraded`); the",
        "events are the runtime's after the failure.",
        "",
        "| id | leg | joint | outcome | progress after (m) | speed kept | heading change (°) "
        "| detected after (s) | events |",
        "|---:|---|---|---|---:|---:|---:|---:|---|",
    ]
    for ln in sorted(lines, key=lambda x: (x.servo_id is None, x.servo_id or 0)):
        out.append(
            f"| {'?' if ln.servo_id is None else ln.servo_id} | {ln.leg} | {ln.joint} "
            f"| {ln.outcome or '–'} | {_fmt(ln.progress_m, '.2f')} "
            f"| {_fmt(ln.speed_kept, '.0%')} "
            f"| {_fmt(ln.heading_deg, '+.1f')} | {_fmt(ln.detected_s, '.2f')} "
            f"| {ln.events.replace('|', '/') or '–'} |"
        )
    out += [
        "",
        "## How the outcome is decided",
        "",
        "From the run after the failure (`whexar.campaign.failures.robot_outcome`), in order:",
        "",
        "1. **fall** — the body tilted past 60°, or its centre sank by more than "
        f"{COLLAPSE_DROP_FRACTION:.0%} of its height at the failure while the coordinator "
        "was not sitting down;",
        "2. **safe stop** — the runtime stopped the robot (`BusLost` / `SafeStop`), or the "
        "coordinator no longer moves at the end (standing, sitting down, seated);",
        "3. **stalled** — the coordinator still walks but the body keeps less than "
        f"{STALL_SPEED_FRACTION:.0%} of its speed of the {BEFORE_S:g} s before the failure;",
        "4. **walk goes on** — otherwise.",
    ]
    frozen = [ln for ln in lines if ln.world_stopped_s is not None]
    if frozen:
        ids = ", ".join(str(ln.servo_id) for ln in frozen if ln.servo_id is not None)
        out += [
            "",
            "## What the simulation does not show",
            "",
            f"In {len(frozen)} runs (servos {ids}) the simulated world stopped advancing before "
            "the end of the walk, when the runtime stopped: once the bus scheduler stops "
            "cycling nothing steps the world (its time is the bus's). Those rows show the robot "
            "as it stood then; what parking the servos (`bus.on_stop`) did to the body after "
            "that is not simulated.",
        ]
    out.append("")
    return "\n".join(out)


def _grid(lines: Sequence[_Line], path: Path) -> Path:
    """A legs × joints grid, each cell coloured by its servo's outcome."""
    from matplotlib.colors import to_rgb
    from matplotlib.patches import Patch

    cells = {(ln.leg, ln.joint): ln for ln in lines}
    fig, ax = new_figure(9.0, 5.2)
    colours = [
        [
            to_rgb(
                OUTCOME_COLOURS.get(cells[leg, joint].outcome or "", NO_OUTCOME_COLOUR)
                if (leg, joint) in cells
                else "white"
            )
            for joint in JOINT_NAMES
        ]
        for leg in LEG_NAMES
    ]
    ax.imshow(colours, aspect="auto")
    for r, leg in enumerate(LEG_NAMES):
        for c, joint in enumerate(JOINT_NAMES):
            ln = cells.get((leg, joint))
            if ln is None:
                continue
            text = f"{'?' if ln.servo_id is None else ln.servo_id}"
            if ln.progress_m is not None:
                text += f"\n{ln.progress_m:.2f} m"
            if ln.heading_deg is not None:
                text += f"\n{round(ln.heading_deg) + 0:+d}°"  # + 0: no "-0°"
            ax.text(c, r, text, ha="center", va="center", fontsize=8)
    ax.set_xticks(range(len(JOINT_NAMES)), JOINT_NAMES)
    ax.set_yticks(range(len(LEG_NAMES)), LEG_NAMES)
    ax.set_xticks([x - 0.5 for x in range(1, len(JOINT_NAMES))], minor=True)
    ax.set_yticks([y - 0.5 for y in range(1, len(LEG_NAMES))], minor=True)
    ax.grid(which="minor", color="white", linewidth=2)
    ax.tick_params(which="minor", length=0)
    ax.set_title(
        "One servo silent during a tripod walk: outcome, progress made and heading change after"
    )
    present = [o for o in OUTCOMES if any(ln.outcome == o for ln in lines)]
    handles = [Patch(color=OUTCOME_COLOURS[o], label=o) for o in present]
    if any(ln.outcome is None for ln in lines):
        handles.append(Patch(color=NO_OUTCOME_COLOUR, label="no outcome"))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=5)
    return save_figure(fig, path)


def write_report(rows: Sequence[Row], out_dir: Path, *, config: str | None = None) -> list[Path]:
    """Write ``servo-failures.md`` and ``img/servo-failures.png`` into ``out_dir``,
    naming the robot configuration ``config`` if one was given.

    One line per row (per servo): its ID, leg, joint, outcome, net progress made after
    the failure, heading change, detection time and the runtime's events. The folder's
    layout is ``docs/``'s, so the two files can be copied there as they are. Returns
    the files written.
    """
    out_dir = Path(out_dir)
    (out_dir / "img").mkdir(parents=True, exist_ok=True)
    lines = [_line(row) for row in rows]
    image = _grid(lines, out_dir / "img" / f"{REPORT_NAME}.png")
    md = out_dir / f"{REPORT_NAME}.md"
    md.write_text(_markdown(lines, f"img/{REPORT_NAME}.png", config), encoding="utf-8")
    return [md, image]


__all__ = [
    "OUTCOMES",
    "Failure",
    "Row",
    "failure",
    "write_report",
]
