"""A campaign's rows: one :class:`Row` per run, and the :class:`CampaignResult` of them all."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

from whexar.campaign.metrics import Value
from whexar.campaign.spec import Campaign

Outcome = Literal["ok", "failed"]
"""Whether the run itself went through (not what the robot did in it)."""


@dataclass
class Row:
    """One run's result: one line of ``results.csv``."""

    id: str
    label: str
    variation: dict[str, Any]
    metrics: dict[str, Value]
    state_hash: str | None
    outcome: Outcome
    error: str | None = None
    wall_s: float = 0.0
    """Wall time of the run itself, in its worker (not deterministic; never compared)."""
    key: str = ""
    details: str | None = field(default=None, repr=False)
    """The traceback of a failed run."""

    def same_result(self, other: Row) -> bool:
        """Whether two rows have the same result: everything but the wall time."""
        mine, theirs = asdict(self), asdict(other)
        for d in (mine, theirs):
            d.pop("wall_s")
            d.pop("details")
        return json.dumps(mine, sort_keys=True) == json.dumps(theirs, sort_keys=True)

    def to_json(self) -> dict[str, Any]:
        """The row as a JSON object (floats exact: JSON numbers round-trip)."""
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Row:
        """A row read back from :meth:`to_json`."""
        return cls(**data)


@dataclass
class CampaignResult:
    """What :func:`run_campaign` did: every row in the campaign's order, the files."""

    campaign: Campaign
    rows: list[Row]
    out_dir: Path
    wall_s: float
    files: list[Path] = field(default_factory=list)

    @property
    def failed(self) -> list[Row]:
        """The rows whose run failed."""
        return [r for r in self.rows if r.outcome == "failed"]


__all__ = ["CampaignResult", "Outcome", "Row"]
