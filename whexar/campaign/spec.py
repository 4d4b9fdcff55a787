"""Campaign files: a base scenario, its variations, the metrics to keep.

Theory of operation
-------------------
A campaign is a TOML file (``config/campaigns/*.toml``; :func:`load_campaign`
takes a bare name for those), validated like every other file: strict keys,
and every problem — of the file and of every run it describes — listed at once
with its key path, the value found and what is allowed, before anything runs. ::

    name = "slopes"
    description = "The tripod gait up slopes, with and without the trochanter."
    scenario = "slope"            # the base: a built-in scenario or a path from here
    metrics = ["speed_mps", "mean_current_a", "fell"]
    record = false                # keep each run's MCAP recording
    timeout_s = 600.0             # wall seconds a run may take
    measure = { from_s = 8.0 }    # the window the metrics measure

    [grid]                        # every combination of these values
    "terrain.slope_deg" = [0, 14, 23, 32]
    "config.locomotion.trochanter_follows_pitch" = [true, false]

    [[runs]]                      # a list of variations, each with an optional grid
    label = "tripod"
    "commands[0].gait" = "tripod"

The runs are each ``[[runs]]`` entry, expanded by its own ``grid``, times the
top-level ``[grid]`` (no ``[[runs]]``: the grid alone). A variation key is a
path (:func:`parse_path`):

* into the base scenario's document (:class:`~whexar.sim.scenario.ScenarioFile`):
  ``duration_s``, ``seed``, ``terrain``, ``terrain.slope_deg`` (a built-in
  terrain name becomes ``{base = name}`` first, ``slope15`` ``{slope_deg = 15}``),
  ``start.yaw_deg``, ``commands``, ``commands[1].vx_m_s``, ``faults`` (a path
  from the campaign file, or an inline fault plan table), ``faults.faults[0].ids``,
  ``sensor_faults``;
* ``config.<section>.<key>…`` into the robot configuration: the base
  scenario's configuration file (or the one :func:`load_campaign` is given in
  its place, the command line's ``--config``), or the defaults, with the values
  set;
* ``measure.from_s`` and ``measure.to_s``, the metrics' window;
* ``timeout_s``, this run's own limit of wall time;
* ``label``, the row's label.

Each run is built whole — its scenario parsed, its configuration and fault
plan checked, in a scratch folder — when the campaign is loaded, so a bad
value fails before the first run, named by the key that set it.

A run's :attr:`RunSpec.key` hashes everything that decides its result (the
documents, the window, the metrics): ``--resume`` keeps a finished row only
while its key is unchanged.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import re
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import tomli_w
from pydantic import Field, ValidationError

from whexar.campaign.metrics import Window, registry
from whexar.config import parse_config
from whexar.errors import ConfigError, Problem
from whexar.runtime.schema import (
    NonNegative,
    Positive,
    Section,
    builtin_names,
    builtin_path,
    format_path,
    problem_from_error,
    read_toml,
)
from whexar.sim.scenario import ScenarioFile, parse_scenario, robot_config, scenario_path

if TYPE_CHECKING:
    from whexar.sim.scenario import Scenario

CAMPAIGN_DIR: Final = Path(__file__).resolve().parents[2] / "config" / "campaigns"
"""The shipped campaigns: the repository's ``config/campaigns`` folder."""
DEFAULT_METRICS: Final = (
    "progress_m",
    "distance_m",
    "speed_mps",
    "mean_power_w",
    "mean_current_a",
    "window_cost_of_transport",
    "max_tilt_deg",
    "falls",
    "events",
)
"""The metrics a campaign keeps when it names none."""
REPORTS: Final = {
    "experiments": "whexar.campaign.experiments",
    "servo-failures": "whexar.campaign.failures",
    "reflexes": "whexar.campaign.reflexes",
}
"""The built-in reports a campaign can ask for (``report = …``), and the module whose
``write_report(rows, out_dir, config=…)`` writes each (``config``: :attr:`Campaign.config`)."""
_SCENARIO_KEYS: Final = tuple(ScenarioFile.model_fields)
_ALLOWED_KEYS: Final = (
    f"a scenario key ({', '.join(_SCENARIO_KEYS)}, with .key and [index] inside them), "
    "config.<section>.<key>, measure.from_s, measure.to_s, timeout_s or label"
)


class MeasureSpec(Section):
    """The window the metrics measure, in simulated seconds."""

    from_s: NonNegative = 0.0
    to_s: Positive | None = None


class CampaignFile(Section):
    """The TOML document of a campaign (see the module docstring)."""

    name: str | None = Field(default=None, min_length=1)
    description: str = ""
    scenario: str = Field(min_length=1)
    metrics: tuple[str, ...] = DEFAULT_METRICS
    record: bool = False
    timeout_s: Positive = 600.0
    report: str | None = None
    measure: MeasureSpec = MeasureSpec()
    grid: dict[str, list[Any]] = Field(default_factory=dict)
    runs: tuple[dict[str, Any], ...] = ()


@dataclass(frozen=True)
class RunSpec:
    """One run of a campaign, everything resolved: picklable, to go to a worker."""

    id: str
    """Its place in the campaign, ``"0007"``: rows and recordings are named by it."""
    label: str
    variation: dict[str, Any]
    """The keys this run sets, as the campaign file writes them."""
    scenario: dict[str, Any]
    """The scenario document, ``config`` and ``faults`` left out (see below)."""
    base: str
    """The folder the scenario's own relative paths start from."""
    config: dict[str, Any] | None
    """The robot configuration document (``None``: the built-in defaults)."""
    faults: dict[str, Any] | None
    """The bus fault plan document, if any."""
    window: Window
    metrics: tuple[str, ...]
    record: bool = False
    timeout_s: float = 600.0

    @property
    def key(self) -> str:
        """What decides the result, hashed (:func:`run_key`)."""
        return run_key(self)

    def build(self, folder: Path) -> Scenario:
        """The checked scenario, its configuration and fault plan written into ``folder``.

        Raises :class:`ConfigError` naming the run.
        """
        doc = copy.deepcopy(self.scenario)
        if self.config is not None:
            path = folder / f"{self.id}-config.toml"
            path.write_text(tomli_w.dumps(_toml_safe(self.config)))
            doc["config"] = str(path.resolve())
        if self.faults is not None:
            path = folder / f"{self.id}-faults.toml"
            path.write_text(tomli_w.dumps(_toml_safe(self.faults)))
            doc["faults"] = str(path.resolve())
        source = f"run {self.id}" + (f" ({self.label})" if self.label else "")
        return parse_scenario(doc, source, base=Path(self.base), stem=self.label or self.id)


@dataclass(frozen=True)
class Campaign:
    """A checked campaign, ready to run."""

    name: str
    description: str
    source: str
    runs: tuple[RunSpec, ...]
    metrics: tuple[str, ...]
    report: str | None = None
    variation_keys: tuple[str, ...] = ()
    """Every key some run varies, in the order the file names them: the table's columns."""
    config: str | None = None
    """The robot configuration file given in place of the base scenario's (``--config``),
    or ``None``: the reports say which robot they describe."""


def config_note(config: str | None) -> list[str]:
    """A report's paragraph naming the robot configuration given with ``--config``
    (:attr:`Campaign.config`), or nothing for the base scenario's own."""
    if config is None:
        return []
    return [
        f"Robot configuration: `{config}` (`--config`), in place of the base scenario's.",
        "",
    ]


# --------------------------------------------------------------------------- paths

_TOKEN = re.compile(r"([A-Za-z_][A-Za-z0-9_\-]*)|\[(\d+)\]|\.")


def parse_path(key: str) -> list[str | int]:
    """``"faults.faults[0].ids"`` → ``["faults", "faults", 0, "ids"]``; raises ValueError."""
    parts: list[str | int] = []
    pos = 0
    expect_name = True
    while pos < len(key):
        m = _TOKEN.match(key, pos)
        if m is None:
            raise ValueError(f"unexpected {key[pos]!r} at character {pos + 1}")
        name, index = m.group(1), m.group(2)
        if name is not None:
            if not expect_name:
                raise ValueError(f"a '.' is missing before {name!r}")
            parts.append(name)
            expect_name = False
        elif index is not None:
            if not parts:
                raise ValueError("an index needs a key before it")
            parts.append(int(index))
        else:
            if expect_name:
                raise ValueError("an empty part between dots")
            expect_name = True
        pos = m.end()
    if not parts or expect_name:
        raise ValueError("an empty key or a trailing '.'")
    return parts


def set_path(doc: dict[str, Any], parts: Sequence[str | int], value: Any) -> None:
    """Set ``value`` at ``parts`` in ``doc``: tables are made where missing, list items must
    exist. Raises ValueError saying where the path cannot go."""
    node: Any = doc
    for k, part in enumerate(parts):
        last = k == len(parts) - 1
        here = format_path(parts[: k + 1])
        if isinstance(part, int):
            if not isinstance(node, list):
                raise ValueError(f"{format_path(parts[:k])} is not a list")
            if part >= len(node):
                raise ValueError(f"{here}: the list has {len(node)} items")
            if last:
                node[part] = copy.deepcopy(value)
            else:
                node = node[part]
            continue
        if not isinstance(node, dict):
            raise ValueError(f"{format_path(parts[:k])} is {node!r}, not a table")
        if last:
            node[part] = copy.deepcopy(value)
            return
        if part not in node or node[part] is None:
            node[part] = {}
        node = node[part]


# --------------------------------------------------------------------------- loading


def campaign_names() -> tuple[str, ...]:
    """The shipped campaigns, by name."""
    return builtin_names(CAMPAIGN_DIR)


def campaign_path(name_or_path: str | Path) -> Path:
    """A campaign's file: a bare name (no folder, no ``.toml``) is a shipped campaign."""
    return builtin_path(name_or_path, CAMPAIGN_DIR, "campaign", "shipped")


def load_campaign(name_or_path: str | Path, *, config: str | Path | None = None) -> Campaign:
    """Read and check a campaign and every run it describes (see the module docstring);
    ``config``, a robot configuration file, replaces the base scenario's (the runs'
    ``config.*`` keys are set on it).

    Raises :class:`~whexar.errors.ConfigError` naming the file and listing every
    problem, before anything runs.
    """
    path = campaign_path(name_or_path)
    return parse_campaign(
        read_toml(path), str(path), base=path.parent, stem=path.stem, config=config
    )


def parse_campaign(
    data: Mapping[str, Any],
    source: str = "<campaign>",
    *,
    base: Path | None = None,
    stem: str = "campaign",
    config: str | Path | None = None,
) -> Campaign:
    """Check a campaign document (as parsed from TOML); relative paths start at ``base``;
    ``config`` as :func:`load_campaign` takes it."""
    folder = (base if base is not None else Path.cwd()).resolve()
    try:
        spec = CampaignFile.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(
            source, [problem_from_error(e, CampaignFile) for e in exc.errors(include_url=False)]
        ) from None
    problems: list[Problem] = []
    known = registry()
    for i, name in enumerate(spec.metrics):
        if name not in known:
            problems.append(Problem(f"metrics[{i}]", name, f"a metric: {', '.join(known)}"))
    if spec.report is not None and spec.report not in REPORTS:
        problems.append(Problem("report", spec.report, f"a built-in report: {', '.join(REPORTS)}"))
    base_doc, base_folder = _base_scenario(spec.scenario, folder, problems)
    if config is not None and base_doc is not None:
        # Checked once, here, so that its problems are named once and not per run.
        robot_config(str(config), Path.cwd(), problems)
        base_doc["config"] = str(Path(config).resolve())
    variations = _variations(spec, problems)
    if problems or base_doc is None:
        raise ConfigError(source, problems)
    base_config = _base_config(base_doc, base_folder, problems)
    runs: list[RunSpec] = []
    width = max(4, len(str(len(variations) - 1)))
    for n, (at, variation) in enumerate(variations):
        run = _run_spec(
            f"{n:0{width}d}", at, variation, spec, base_doc, base_folder, base_config, folder,
            problems,
        )  # fmt: skip
        if run is not None:
            runs.append(run)
    if not problems:
        _check_runs(runs, problems)
    if problems:
        raise ConfigError(source, problems)
    keys: list[str] = []
    for _, variation in variations:
        keys.extend(k for k in variation if k not in keys)
    return Campaign(
        name=spec.name or stem,
        description=spec.description,
        source=source,
        runs=tuple(runs),
        metrics=spec.metrics,
        report=spec.report,
        variation_keys=tuple(keys),
        config=str(config) if config is not None else None,
    )


def _base_scenario(
    name: str, folder: Path, problems: list[Problem]
) -> tuple[dict[str, Any] | None, Path]:
    try:
        candidate = folder / name if ("/" in name or name.endswith(".toml")) else name
        path = scenario_path(candidate)
        return read_toml(path), path.parent.resolve()
    except ConfigError as exc:
        found = "; ".join(str(p) for p in exc.problems)
        problems.append(Problem("scenario", name, f"a readable scenario; {found}"))
        return None, folder


def _base_config(doc: Mapping[str, Any], folder: Path, problems: list[Problem]) -> dict[str, Any]:
    name = doc.get("config")
    if not isinstance(name, str):
        return {}
    try:
        return read_toml(folder / name)
    except ConfigError as exc:
        problems.append(Problem("scenario.config", name, "; ".join(str(p) for p in exc.problems)))
        return {}


def _variations(spec: CampaignFile, problems: list[Problem]) -> list[tuple[str, dict[str, Any]]]:
    """Every run's variation, with where it comes from (for error messages)."""
    top = _expand(spec.grid, "grid", problems)
    entries: list[tuple[str, dict[str, Any]]] = []
    if spec.runs:
        for i, entry in enumerate(spec.runs):
            own = dict(entry)
            grid = own.pop("grid", {})
            if not isinstance(grid, dict):
                problems.append(Problem(f"runs[{i}].grid", grid, "a table of key = [values]"))
                continue
            for combo in _expand(grid, f"runs[{i}].grid", problems):
                entries.append((f"runs[{i}]", {**own, **combo}))
    else:
        entries.append(("", {}))
    if not spec.runs and not spec.grid:
        problems.append(
            Problem("(campaign)", "(no runs)", "a [grid] or [[runs]]: the campaign has no run")
        )
        return []
    out = []
    for at, own in entries:
        for combo in top:
            clash = sorted(set(own) & set(combo))
            if clash:
                problems.append(
                    Problem(f"grid.{clash[0]}", combo[clash[0]], f"a key {at} does not set too")
                )
            out.append((at or "grid", {**own, **combo}))
    return out


def _expand(grid: Mapping[str, Any], at: str, problems: list[Problem]) -> list[dict[str, Any]]:
    """The cartesian product of a grid's values, in the file's key order."""
    keys = list(grid)
    for key in keys:
        values = grid[key]
        if not isinstance(values, list) or not values:
            problems.append(
                Problem(
                    f"{at}.{key}", values, "a non-empty list of values: an empty grid has no run"
                )
            )
            return []
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grid.values())]


def _run_spec(
    run_id: str,
    at: str,
    variation: dict[str, Any],
    spec: CampaignFile,
    base_doc: dict[str, Any],
    base_folder: Path,
    base_config: dict[str, Any],
    folder: Path,
    problems: list[Problem],
) -> RunSpec | None:
    scenario = copy.deepcopy(base_doc)
    config = copy.deepcopy(base_config)
    config_set = bool(base_config)
    faults: dict[str, Any] | None = None
    base_faults = scenario.get("faults")
    if isinstance(base_faults, str):
        try:
            faults = read_toml(base_folder / base_faults)
        except ConfigError as exc:
            problems.append(Problem("scenario.faults", base_faults, str(exc)))
    label = ""
    timeout_s = spec.timeout_s
    measure = {"from_s": spec.measure.from_s, "to_s": spec.measure.to_s}
    bad = False
    for key, value in variation.items():
        where = f"{at}.{key}" if at.startswith("runs") else f"grid.{key}"
        try:
            parts = parse_path(key)
        except ValueError as exc:
            problems.append(Problem(where, value, f"a key path: {exc}"))
            bad = True
            continue
        head = parts[0]
        try:
            if key == "label":
                if not isinstance(value, str):
                    raise ValueError("a string")
                label = value
            elif key == "timeout_s":
                if isinstance(value, bool) or not isinstance(value, int | float) or value <= 0:
                    raise ValueError("a number of wall seconds > 0")
                timeout_s = float(value)
            elif head == "measure":
                if len(parts) != 2 or parts[1] not in ("from_s", "to_s"):
                    raise ValueError("measure.from_s or measure.to_s")
                measure[str(parts[1])] = value
            elif head == "config" and len(parts) > 1:
                set_path(config, parts[1:], value)
                config_set = True
            elif head == "faults":
                if len(parts) == 1:
                    faults = _faults_value(value, folder)
                else:
                    if faults is None:
                        raise ValueError("the base scenario has no fault plan: set faults first")
                    set_path(faults, parts[1:], value)
            elif head in _SCENARIO_KEYS:
                if head == "terrain" and len(parts) > 1:
                    scenario["terrain"] = _terrain_table(scenario.get("terrain", "flat"))
                set_path(scenario, parts, value)
            else:
                raise ValueError(_ALLOWED_KEYS)
        except (ValueError, ConfigError) as exc:
            problems.append(Problem(where, value, str(exc)))
            bad = True
    scenario.pop("config", None)
    scenario.pop("faults", None)
    window = _window(measure, f"{at}.measure", problems)
    if bad or window is None:
        return None
    return RunSpec(
        id=run_id,
        label=label,
        variation=variation,
        scenario=scenario,
        base=str(base_folder),
        config=config if config_set else None,
        faults=faults,
        window=window,
        metrics=spec.metrics,
        record=spec.record,
        timeout_s=timeout_s,
    )


def _terrain_table(terrain: object) -> object:
    """A terrain as a table its features can be set in: a built-in name is its base, and
    ``slope<deg>`` the flat with that slope, so that ``terrain.slope_deg`` replaces it."""
    if not isinstance(terrain, str):
        return terrain
    m = re.fullmatch(r"slope(\d+(?:\.\d+)?)", terrain)
    if m is not None:
        return {"base": "flat", "slope_deg": float(m.group(1))}
    return {"base": terrain}


def _faults_value(value: Any, folder: Path) -> dict[str, Any]:
    if isinstance(value, dict):
        return copy.deepcopy(value)
    if isinstance(value, str):
        return read_toml(folder / value)
    raise ValueError("a fault plan file (from the campaign's folder) or a fault plan table")


def _window(measure: Mapping[str, Any], at: str, problems: list[Problem]) -> Window | None:
    try:
        checked = MeasureSpec.model_validate(measure)
    except ValidationError as exc:
        problems.extend(problem_from_error(e, MeasureSpec, (at,)) for e in exc.errors())
        return None
    if checked.to_s is not None and checked.to_s <= checked.from_s:
        problems.append(Problem(f"{at}.to_s", checked.to_s, f"more than from_s = {checked.from_s}"))
        return None
    return Window(checked.from_s, checked.to_s)


def _check_runs(runs: Sequence[RunSpec], problems: list[Problem]) -> None:
    """Build every run in a scratch folder: its scenario, configuration and fault plan."""
    with tempfile.TemporaryDirectory(prefix="whexar-campaign-") as scratch:
        for run in runs:
            if run.config is not None:
                try:  # checked here first, so that its problems are named config.<key>
                    parse_config(run.config)
                except ConfigError as exc:
                    problems.extend(
                        Problem(f"run {run.id}: config.{p.path}", p.value, p.allowed)
                        for p in exc.problems
                    )
                    continue
            try:
                scenario = run.build(Path(scratch))
            except ConfigError as exc:
                problems.extend(
                    Problem(f"{exc.source}: {p.path}", p.value, p.allowed) for p in exc.problems
                )
                continue
            end = run.window.to_s
            if end is not None and end > scenario.duration_s + 1e-9:
                problems.append(
                    Problem(
                        f"run {run.id}: measure.to_s",
                        end,
                        f"at most the run's duration_s = {scenario.duration_s:g}",
                    )
                )


def run_key(run: RunSpec) -> str:
    """A hash of everything that decides a run's result (for ``--resume``)."""
    blob = json.dumps(
        {
            "scenario": run.scenario,
            "base": run.base,
            "config": run.config,
            "faults": run.faults,
            "window": [run.window.from_s, run.window.to_s],
            "metrics": run.metrics,
        },
        sort_keys=True,
        default=str,
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _toml_safe(value: Any) -> Any:
    """A document tomli-w can write: TOML has no null, so a ``None`` value is left out."""
    if isinstance(value, dict):
        return {k: _toml_safe(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple):
        return [_toml_safe(v) for v in value]
    return value


__all__ = [
    "CAMPAIGN_DIR",
    "DEFAULT_METRICS",
    "REPORTS",
    "Campaign",
    "CampaignFile",
    "MeasureSpec",
    "RunSpec",
    "campaign_names",
    "campaign_path",
    "config_note",
    "load_campaign",
    "parse_campaign",
    "parse_path",
    "run_key",
    "set_path",
]
