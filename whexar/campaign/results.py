"""A campaign's results on disk: ``results.json``, ``results.csv``, ``summary.md``, plots.

Theory of operation
-------------------
One row per run, in the campaign's order. ``results.json`` keeps every row
whole (:meth:`~whexar.campaign.rows.Row.to_json`); ``results.csv`` has one
column per variation key (its value as JSON, so a list stays one cell), per
metric, then the state hash, the outcome, the error and the wall time.
``summary.md`` is the same table for a person, with the failed runs' errors.
``metrics.png`` plots every numeric metric: against the campaign's one numeric
variation key when it has exactly one (a line per combination of the other
keys), else per run. The campaign's built-in report, if it names one
(:data:`~whexar.campaign.spec.REPORTS`), comes last.
"""

from __future__ import annotations

import csv
import importlib
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from whexar._json import dumps as strict_dumps
from whexar.campaign.metrics import registry
from whexar.campaign.spec import REPORTS, config_note

if TYPE_CHECKING:
    from whexar.campaign.rows import CampaignResult, Row

LEGEND_MAX: Final = 12
"""Most lines a metric's plot labels in its legend."""


def write_results(result: CampaignResult) -> list[Path]:
    """Write every results file of ``result`` into its folder; the paths written."""
    out = result.out_dir
    camp = result.campaign
    written = [_json(result), _csv(result), _markdown(result)]
    plot = _plot(result)
    if plot is not None:
        written.append(plot)
    if camp.report is not None:
        module = importlib.import_module(REPORTS[camp.report])
        written.extend(module.write_report(result.rows, out, config=camp.config))
    return written


def _json(result: CampaignResult) -> Path:
    path = result.out_dir / "results.json"
    camp = result.campaign
    doc = {
        "campaign": camp.name,
        "source": camp.source,
        "metrics": list(camp.metrics),
        "variation_keys": list(camp.variation_keys),
        "config": camp.config,
        "wall_s": result.wall_s,
        "rows": [r.to_json() for r in result.rows],
    }
    # Strict JSON: a metric with no finite value (a margin of −∞) is null, as one
    # undefined for its run is.
    path.write_text(strict_dumps(doc, indent=1, default=str) + "\n")
    return path


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return value
    if isinstance(value, float):
        return repr(value)
    return json.dumps(value)


def _csv(result: CampaignResult) -> Path:
    path = result.out_dir / "results.csv"
    camp = result.campaign
    header = [
        "id",
        "label",
        *camp.variation_keys,
        *camp.metrics,
        "state_hash",
        "outcome",
        "error",
        "wall_s",
    ]
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in result.rows:
            w.writerow(
                [
                    r.id,
                    r.label,
                    *(_cell(r.variation.get(k)) for k in camp.variation_keys),
                    *(_cell(r.metrics.get(m)) for m in camp.metrics),
                    r.state_hash or "",
                    r.outcome,
                    r.error or "",
                    f"{r.wall_s:.2f}",
                ]
            )
    return path


def shown(value: Any) -> str:
    """A value for a table: numbers to 4 significant digits."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else str(value)
    if isinstance(value, list | dict):
        return json.dumps(value)
    return str(value)


def _markdown(result: CampaignResult) -> Path:
    path = result.out_dir / "summary.md"
    camp = result.campaign
    table = registry()
    failed = result.failed
    lines = [
        f"# Campaign `{camp.name}`",
        "",
        camp.description,
        "",
        f"{len(result.rows)} runs, {len(failed)} failed, {result.wall_s:.0f} s of wall time "
        f"(`{camp.source}`).",
        "",
        *config_note(camp.config),
    ]
    cols = [*camp.variation_keys, *camp.metrics]
    units = {m: table[m].unit for m in camp.metrics if m in table}
    head = [c + (f" ({units[c]})" if units.get(c) else "") for c in cols]
    lines.append("| run | label | " + " | ".join(head) + " | outcome |")
    lines.append("|---|---|" + "---|" * len(cols) + "---|")
    for r in result.rows:
        cells = [shown(r.variation.get(c)) for c in camp.variation_keys]
        cells += [shown(r.metrics.get(m)) for m in camp.metrics]
        lines.append(f"| {r.id} | {r.label} | " + " | ".join(cells) + f" | {r.outcome} |")
    if failed:
        lines += ["", "## Failed runs", ""]
        lines += [f"- run {r.id} {r.label}: {r.error}" for r in failed]
    path.write_text("\n".join(lines) + "\n")
    return path


def _numeric(rows: Sequence[Row], name: str) -> bool:
    values = [r.metrics.get(name) for r in rows if r.outcome == "ok"]
    found = [v for v in values if v is not None]
    return bool(found) and all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in found
    )


def _plot(result: CampaignResult) -> Path | None:
    from whexar.record.plots import new_figure, save_figure

    rows = result.rows
    camp = result.campaign
    numeric = [m for m in camp.metrics if _numeric(rows, m)]
    if not numeric or not rows:
        return None
    x_keys = [
        k
        for k in camp.variation_keys
        if all(
            isinstance(r.variation.get(k), int | float) and not isinstance(r.variation[k], bool)
            for r in rows
        )
    ]
    units = {m: registry()[m].unit for m in numeric}
    fig, axes = new_figure(
        9, 2.4 * len(numeric) + 0.6, len(numeric), squeeze=False, layout="constrained"
    )
    x_key = x_keys[0] if len(x_keys) == 1 else None
    for ax, m in zip(axes[:, 0], numeric, strict=True):
        if x_key is not None:
            groups: dict[str, list[Row]] = {}
            for r in rows:
                rest = {k: v for k, v in r.variation.items() if k != x_key}
                groups.setdefault(json.dumps(rest, sort_keys=True, default=str), []).append(r)
            for name, members in groups.items():
                pts = [
                    (r.variation[x_key], r.metrics.get(m))
                    for r in members
                    if r.metrics.get(m) is not None
                ]
                if pts:
                    xs, ys = zip(*sorted(pts), strict=True)
                    ax.plot(xs, ys, marker="o", label=_legend(name))
            ax.set_xlabel(x_key)
            if 1 < len(groups) <= LEGEND_MAX:
                ax.legend(fontsize=7)
            elif len(groups) > LEGEND_MAX:  # a legend that tall leaves the plot no room
                ax.set_title(f"{len(groups)} variations, one line each", fontsize=8)
        else:
            ids = list(range(len(rows)))
            values = [r.metrics.get(m) if r.metrics.get(m) is not None else math.nan for r in rows]
            colours = ["tab:blue" if r.outcome == "ok" else "tab:red" for r in rows]
            ax.bar(ids, values, color=colours)
            ax.set_xticks(ids, [r.label or r.id for r in rows], rotation=60, fontsize=7)
        ax.set_ylabel(f"{m} ({units[m]})" if units[m] else m, fontsize=8)
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"campaign {camp.name}: {len(rows)} runs")
    path = result.out_dir / "metrics.png"
    save_figure(fig, path)
    return path


def metrics_table() -> str:
    """Every registered metric as a Markdown table: name, unit, where it is defined, what it is
    (``docs/campaigns.md`` carries it; a test keeps the two the same)."""
    lines = ["| metric | unit | module | what |", "|---|---|---|---|"]
    for m in registry().values():
        # The campaign module or package that defines it: metrics, experiments, failures.
        module = m.fn.__module__.removeprefix("whexar.campaign.").split(".", 1)[0]
        lines.append(f"| `{m.name}` | {m.unit or '–'} | {module} | {m.description} |")
    return "\n".join(lines)


def _legend(key: str) -> str:
    rest = json.loads(key)
    return ", ".join(f"{k}={shown(v)}" for k, v in rest.items()) or "all"


__all__ = ["metrics_table", "shown", "write_results"]
