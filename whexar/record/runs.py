"""The recorder of a run: what ``whexar sim`` and ``whexar run`` record with every message.

:func:`run_recorder` makes the recorder of one run — in a process of its own
(:mod:`whexar.record.sidecar`), or here when a live view needs the messages — with
what a replay needs attached: the configuration file the run read and every value
it ran with, beside the caller's attachments (the wiring) and metadata. The URDF,
for Foxglove's 3D view, is the caller's: building it compiles the simulation's
model, which the robot's plain install does not have (``whexar[sim]``).

Every recording keeps the budget of the configuration's ``[recording]`` section
(:mod:`whexar.record.budget`): in the recordings folder, older recordings are deleted
as it needs; anywhere else (``--record FILE``) nothing is deleted, but the recording
stops all the same when it alone passes the budget or its disk runs low.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from whexar.config import RobotConfig
from whexar.record.budget import Budget, BudgetGuard, recordings_folder

if TYPE_CHECKING:
    from whexar.record.sidecar import AnyRecorder
    from whexar.record.writer import LiveSink

__all__ = ["run_recorder"]


def run_recorder(
    path: str | Path,
    cfg: RobotConfig,
    config: str | Path | None,
    attachments: Mapping[str, str | bytes],
    metadata: Mapping[str, str],
    live: LiveSink | None = None,
    *,
    urdf: str | None = None,
) -> AnyRecorder:
    """A recorder for a run of robot ``cfg`` (read from file ``config``, ``None`` for the
    built-in): ``attachments`` and ``metadata`` as given, plus the configuration file and
    every value the run used; ``urdf``, if given, attached and on ``/robot_description``."""
    from whexar.record.sidecar import RecorderProcess
    from whexar.record.writer import (
        CONFIG_ATTACHMENT,
        EFFECTIVE_CONFIG_ATTACHMENT,
        URDF_ATTACHMENT,
        Recorder,
    )

    attached: dict[str, str | bytes] = {
        **attachments,
        EFFECTIVE_CONFIG_ATTACHMENT: cfg.model_dump_json(indent=1),
    }
    if config is not None:
        attached[CONFIG_ATTACHMENT] = Path(config).read_bytes()
    if urdf is not None:
        attached[URDF_ATTACHMENT] = urdf
    budget = Budget.from_spec(cfg.recording)
    guard = None
    if budget.limited and os.path.abspath(path) != os.path.abspath(os.devnull):
        guard = BudgetGuard(budget, path, _folder(Path(path)))
    # Written by a process of its own (the runtime only packs), unless a live view
    # needs the messages here: see whexar.record.sidecar.
    recorder: Recorder | RecorderProcess = (
        RecorderProcess(path, metadata=metadata, attachments=attached, guard=guard)
        if live is None
        else Recorder(path, metadata=metadata, attachments=attached, live=live, guard=guard)
    )
    if urdf is not None:
        recorder.robot_description(urdf)
    return recorder


def _folder(path: Path) -> Path | None:
    """The recordings folder if ``path`` is in it (the budget covers it), else ``None``."""
    folder = recordings_folder()
    try:
        return path.parent if os.path.samefile(path.parent, folder) else None
    except OSError:  # either is missing: not the same folder
        return None
