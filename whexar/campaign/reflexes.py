"""The reflexes as a campaign: their metrics, success rates, false triggers and sweep.

Theory of operation
-------------------
The campaign ``config/campaigns/reflexes.toml`` walks the robot with every
shipped reflex running (``config/reflexes.toml``) through
each reflex's scenarios, over gaits and seeds (the robot's parts drawn from
the seed), and through nominal walks with nothing to react to. The metrics
here count what the reflexes did (:func:`activations`: a reflex's active
spells that began in the measuring window, from the run's compact series),
how the swings ended, the coordinator's re-steps and safe stops, where the
body got to; :func:`write_report` turns the rows into ``reflex-campaign.md``
and ``img/reflex-campaign.png``:

* **success rate** per reflex: the share of its scenario's runs that meet the
  scenario's criterion (:data:`CRITERIA`, by the run's label);
* **false triggers** per reflex: its activations per 10 minutes of walking in
  the ``nominal`` runs, by terrain (a reflex active in a nominal walk fired
  with nothing to react to);
* **the sweep**: by the force sensors' contact threshold, the elevator's
  success at the sill and its activations per minute on 23° without the
  trochanter (the thesis's false triggers, 6.7.2), the elevator running alone.

The targets (issue, docs/reflexes.md): success ≥ 90 % where the thesis reports
the reflex working, false triggers ≤ 1 per 10 minutes of nominal walking.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Final

from whexar.actors.messages import NoFoothold, Restepped
from whexar.campaign.metrics import Value, Window, metric
from whexar.campaign.rows import Row
from whexar.campaign.spec import config_note
from whexar.record.plots import new_figure, save_figure

if TYPE_CHECKING:
    from whexar.sim.run import SimResult

REPORT_NAME: Final = "reflex-campaign"
REFLEXES: Final = ("elevator", "searching", "stepping", "heading-hold", "obstacle")
"""The shipped reflexes the campaign runs (the battery's never fires on the bench supply)."""
TARGET_SUCCESS: Final = 0.9
TARGET_FALSE_PER_10_MIN: Final = 1.0
_WALKING: Final = frozenset({"walking", "hybrid"})


# --------------------------------------------------------------------------- metrics


def activations(result: SimResult, window: Window, reflex: str) -> int:
    """How many active spells of ``reflex`` began inside the window."""
    spells = result.series.reflex_intervals().get(reflex, [])
    return sum(1 for t0, _ in spells if window.contains(t0))


def _counter(reflex: str) -> Callable[[SimResult, Window], Value]:
    def fn(result: SimResult, window: Window) -> Value:
        return activations(result, window, reflex)

    return fn


for _name in REFLEXES:
    metric(
        f"{_name.replace('-', '_')}_activations",
        "",
        f"active spells of the {_name} reflex that began in the window",
    )(_counter(_name))


@metric(
    "walking_min", "min", "time the coordinator walked (or stepped the hybrid gait) in the window"
)
def walking_min(result: SimResult, window: Window) -> Value:
    points = [p for p in result.series.locomotion if window.contains(p.t)]
    walked = sum(b.t - a.t for a, b in itertools.pairwise(points) if a.activity in _WALKING)
    return walked / 60.0


@metric("no_contact_swings", "", "swings that ended with no ground where expected, in the window")
def no_contact_swings(result: SimResult, window: Window) -> Value:
    return sum(
        1 for t, _, o in result.series.swing_ends if o == "no_contact" and window.contains(t)
    )


@metric("restepped", "", "legs the coordinator stepped again at a reflex's request, in the window")
def restepped(result: SimResult, window: Window) -> Value:
    return sum(
        1 for e in result.events if isinstance(e, Restepped) and e.done and window.contains(e.t)
    )


@metric("no_foothold", "", "searches that found no foothold and held the body, in the window")
def no_foothold(result: SimResult, window: Window) -> Value:
    return sum(1 for e in result.events if isinstance(e, NoFoothold) and window.contains(e.t))


@metric("x_end_m", "m", "the body centre's x at the end of the window (how far along it got)")
def x_end_m(result: SimResult, window: Window) -> Value:
    s = window.samples(result)
    return s[-1].x if s else None


# --------------------------------------------------------------------------- judging rows


def _n(row: Row, key: str) -> float:
    value = row.metrics.get(key)
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else math.nan


def _upright(row: Row) -> bool:
    return _n(row, "falls") == 0


CRITERIA: Final[Mapping[str, tuple[str, str, Callable[[Row], bool]]]] = {
    "elevator sill": (
        "elevator",
        "past the 6 cm sill (x = 1.2 m) by 0.4 m within 30 s, upright",
        lambda r: _upright(r) and _n(r, "x_end_m") >= 1.6,
    ),
    "searching trench": (
        "searching",
        "a 30 × 5 cm trench: no foot left hanging, past it (x ≥ 1.4 m) in 25 s, upright",
        lambda r: _upright(r) and _n(r, "no_contact_swings") == 0 and _n(r, "x_end_m") >= 1.4,
    ),
    "searching deep": (
        "searching",
        "a 40 × 20 cm trench: held safely at its edge (NoFoothold), upright",
        lambda r: _upright(r) and _n(r, "no_foothold") >= 1,
    ),
    "stepping snag": (
        "stepping",
        "RF's coxa snagged 2 s: stepped back, on to x ≥ 0.8 m by 14 s, upright",
        lambda r: _upright(r) and _n(r, "restepped") >= 1 and _n(r, "x_end_m") >= 0.8,
    ),
    "heading lost coxa": (
        "heading-hold",
        "RM's coxa silent from 8 s: the heading kept within 5° to 20 s",
        lambda r: _upright(r) and abs(_n(r, "heading_change_deg")) <= 5.0,
    ),
    "heading lost coxa alone": (
        "heading-hold",
        "the same, the other reflexes off",
        lambda r: _upright(r) and abs(_n(r, "heading_change_deg")) <= 5.0,
    ),
    "obstacle box": (
        "obstacle",
        "an 8 × 30 cm box at x = 1.3 m: measured, climbed, past it (x ≥ 1.9 m) in 40 s, upright",
        lambda r: _upright(r) and _n(r, "obstacle_activations") >= 1 and _n(r, "x_end_m") >= 1.9,
    ),
    "obstacle wall": (
        "obstacle",
        "a 40 cm wall at x = 1.3 m: kept off, the front legs short of it (x ≤ 0.8 m) to "
        "20 s, upright",
        lambda r: _upright(r) and _n(r, "obstacle_activations") >= 1 and _n(r, "x_end_m") <= 0.8,
    ),
}
"""Run label → (the reflex it tests, the criterion in words, the criterion)."""


def _ok(rows: Sequence[Row]) -> list[Row]:
    return [r for r in rows if r.outcome == "ok"]


def success(rows: Sequence[Row]) -> dict[str, tuple[str, str, int, int]]:
    """Per scenario label: (reflex, criterion, runs that met it, runs)."""
    out = {}
    for label, (reflex, text, judge) in CRITERIA.items():
        mine = _ok([r for r in rows if r.label == label])
        out[label] = (reflex, text, sum(1 for r in mine if judge(r)), len(mine))
    return out


def _terrain(row: Row) -> str:
    value = row.variation.get("terrain", "flat")
    return str(value) if isinstance(value, str) else "table"


def false_triggers(rows: Sequence[Row]) -> dict[str, dict[str, tuple[int, float]]]:
    """Per terrain of the nominal runs: per reflex (activations, minutes walked)."""
    out: dict[str, dict[str, tuple[int, float]]] = {}
    for row in _ok([r for r in rows if r.label == "nominal"]):
        by = out.setdefault(_terrain(row), {})
        minutes = _n(row, "walking_min")
        for reflex in REFLEXES:
            n = _n(row, f"{reflex.replace('-', '_')}_activations")
            a, m = by.get(reflex, (0, 0.0))
            by[reflex] = (a + int(n if math.isfinite(n) else 0), m + minutes)
    return out


def sweep(rows: Sequence[Row]) -> dict[int, tuple[int, int, float, float]]:
    """By contact threshold: (runs past the sill, runs at the sill, elevator activations
    on 23° without the trochanter, minutes walked there)."""
    out: dict[int, list[float]] = {}
    for row in _ok(rows):
        threshold = row.variation.get("config.fsr.contact_on_counts")
        if not isinstance(threshold, int) or not row.label.startswith("sweep"):
            continue
        acc = out.setdefault(threshold, [0, 0, 0.0, 0.0])
        if row.label == "sweep sill":
            acc[0] += CRITERIA["elevator sill"][2](row)
            acc[1] += 1
        else:
            acc[2] += _n(row, "elevator_activations")
            acc[3] += _n(row, "walking_min")
    return {k: (int(v[0]), int(v[1]), v[2], v[3]) for k, v in sorted(out.items())}


# --------------------------------------------------------------------------- the report


def _terrains(fired: Mapping[str, object]) -> list[str]:
    """The nominal runs' terrains, the shipped three first."""
    known = [t for t in ("flat", "slope15", "slope30") if t in fired]
    return known + sorted(t for t in fired if t not in known)


def _per_10(count: float, minutes: float) -> str:
    return f"{10.0 * count / minutes:.2f}" if minutes > 0 else "—"


def _markdown(rows: Sequence[Row], image: str, config: str | None = None) -> str:
    ok = success(rows)
    fired = false_triggers(rows)
    terrains = _terrains(fired)
    lines = [
        "# The reflexes: success and false triggers",
        "",
        "`whexar campaign config/campaigns/reflexes.toml` (whexar.campaign.reflexes): every "
        "shipped reflex running; the robot's parts drawn from each seed. Targets: success "
        f"≥ {TARGET_SUCCESS:.0%}, false triggers ≤ {TARGET_FALSE_PER_10_MIN:g} per 10 minutes "
        "of nominal walking.",
        "",
        *config_note(config),
        "| reflex | scenario | success | runs | "
        + " | ".join(f"false triggers /10 min, {t}" for t in terrains)
        + " |",
        "|---|---|---|---|" + "---|" * len(terrains),
    ]
    for _label, (reflex, text, met, n) in ok.items():
        rate = f"{met / n:.0%}" if n else "—"
        cells = []
        for t in terrains:
            a, m = fired.get(t, {}).get(reflex, (0, 0.0))
            cells.append(f"{_per_10(a, m)} ({a} in {m:.1f} min)")
        lines.append(f"| {reflex} | {text} | {rate} | {met}/{n} | " + " | ".join(cells) + " |")
    table = sweep(rows)
    if table:
        lines += [
            "",
            "## The contact threshold and the elevator",
            "",
            "| contact_on_counts | past the sill | elevator activations /10 min on 23°, no "
            "trochanter |",
            "|---|---|---|",
        ]
        for k, (past, n, fires, minutes) in table.items():
            lines.append(f"| {k} | {past}/{n} | {_per_10(fires, minutes)} |")
    failed = [r for r in rows if r.outcome != "ok"]
    if failed:
        lines += ["", f"{len(failed)} runs failed: " + ", ".join(r.id for r in failed)]
    lines += ["", f"![success and false triggers]({image})", ""]
    return "\n".join(lines)


def _plot(rows: Sequence[Row], path: Path) -> Path:
    ok = success(rows)
    fired = false_triggers(rows)
    fig, (left, right) = new_figure(11.0, 7.5, rows=2)
    labels = list(ok)
    rates = [100.0 * m / n if n else 0.0 for _, _, m, n in ok.values()]
    left.barh(range(len(labels)), rates, color="#3182bd")
    left.axvline(100 * TARGET_SUCCESS, color="#d73027", lw=1, ls="--", label="target")
    left.set_yticks(range(len(labels)))
    left.set_yticklabels(labels)
    left.set_xlim(0, 100)
    left.set_xlabel("success (%)")
    left.legend(loc="lower right", fontsize=8)
    terrains = _terrains(fired)
    width = 0.8 / max(len(terrains), 1)
    for k, t in enumerate(terrains):
        values = []
        for reflex in REFLEXES:
            a, m = fired[t].get(reflex, (0, 0.0))
            values.append(10.0 * a / m if m > 0 else 0.0)
        right.bar([i + k * width for i in range(len(REFLEXES))], values, width, label=t)
    right.axhline(TARGET_FALSE_PER_10_MIN, color="#d73027", lw=1, ls="--", label="target")
    right.set_xticks([i + 0.4 - width / 2 for i in range(len(REFLEXES))])
    right.set_xticklabels(REFLEXES)
    right.set_ylabel("activations per 10 min walking")
    right.set_yscale("symlog", linthresh=1.0)
    right.legend(fontsize=8)
    right.set_title("false triggers (nominal walks)")
    return save_figure(fig, path)


def write_report(rows: Sequence[Row], out_dir: Path, *, config: str | None = None) -> list[Path]:
    """Write ``reflex-campaign.md`` and ``img/reflex-campaign.png`` into ``out_dir``
    (``docs/``'s layout), naming the robot configuration ``config`` if one was given;
    returns the files written."""
    out_dir = Path(out_dir)
    (out_dir / "img").mkdir(parents=True, exist_ok=True)
    image = _plot(rows, out_dir / "img" / f"{REPORT_NAME}.png")
    md = out_dir / f"{REPORT_NAME}.md"
    md.write_text(_markdown(rows, f"img/{REPORT_NAME}.png", config), encoding="utf-8")
    return [md, image]


__all__ = [
    "CRITERIA",
    "REFLEXES",
    "activations",
    "false_triggers",
    "success",
    "sweep",
    "write_report",
]
