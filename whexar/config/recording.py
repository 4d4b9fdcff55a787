"""The recordings' budget on the robot's disk (``[recording]``): how much the recordings
folder may hold, for how long, and how much free space every recording leaves
(:mod:`whexar.record.budget` keeps to it)."""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator

from whexar.runtime.schema import Section


def _limit(unit: str) -> AfterValidator:
    def check(value: float) -> float:
        if not value >= 0 or value == float("inf"):
            raise ValueError(f"a finite number of {unit} ≥ 0 (0: no limit)")
        return value

    return AfterValidator(check)


class RecordingSpec(Section):
    """The budget of the recordings folder (``recordings/`` or ``WHEXAR_RECORDINGS``).

    The oldest recordings are deleted first, never the one being written; when
    the budget cannot be kept with only that one left, or the disk has less than
    ``min_free_mb`` free, the recording stops and the robot runs on
    (docs/recording.md). Sizes in MB of 10⁶ bytes, as disks are sold; 0: no limit.

    The defaults fit the Raspberry Pi 4's SD card: a 16 GB card, the smallest one
    commonly sold, holds Raspberry Pi OS (about 5 GB with the desktop) and 8 GB of
    recordings, about ten hours at the 0.22–0.24 MB a second of a recorded course
    (docs/recording.md); 1 GB stays free whatever the card holds, for the system's
    journal, package updates and swap, which a full card stops.
    """

    max_total_mb: Annotated[float, _limit("MB")] = 8000.0
    """The most all recordings of the folder may take together."""
    max_age_days: Annotated[float, _limit("days")] = 30.0
    """Recordings older than this are deleted (by their last change): a month, time
    enough to copy a field trial's logs off the robot, and forgotten simulation runs do
    not pile up on a desk. The Pi has no clock of its own: a robot run offline should
    set 0 (docs/recording.md)."""
    min_free_mb: Annotated[float, _limit("MB")] = 1000.0
    """The free space every recording leaves on the disk: older recordings go first,
    then the recording itself stops."""
