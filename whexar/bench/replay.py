"""Replay speed, for ``whexar bench record``: a 60 s log replayed with ``--fast``.

Target (issue 15): a 60 s log replays at **≥ 50×** real time with ``--fast``
(:data:`REPLAY_TARGET`).

What is measured: the first :data:`LOG_SECONDS` of the ``course`` scenario are
simulated and recorded once; then :func:`whexar.record.replay.replay` plays the
file back as fast as it goes, :data:`REPEATS` times, and the least wall time of
the whole call (reading the file included, the interpreter's start not) divides
the replayed seconds. The same with ``--check`` (every message compared) beside it.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any, Final

from whexar.bench import Progress
from whexar.record.replay import replay
from whexar.sim.scenario import DEFAULT_SCENARIO, load_scenario

REPLAY_TARGET: Final = 50.0
LOG_SECONDS: Final = 60.0
REPEATS: Final = 2


def measure(
    seconds: float = LOG_SECONDS, repeats: int = REPEATS, progress: Progress = None
) -> dict[str, Any]:
    """``replay_realtime_factor`` and what it was measured on (module docstring)."""
    say = progress or (lambda _: None)
    chosen = load_scenario(DEFAULT_SCENARIO).with_overrides(duration_s=seconds)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bench.mcap"
        say(f"recording {seconds:g} s of {DEFAULT_SCENARIO}…")
        chosen.run(record=path)
        fast: list[float] = []
        checked: list[float] = []
        for k in range(repeats):
            say(f"replay {k + 1}/{repeats}: --fast, then --fast --check…")
            plain = replay(path)
            fast.append(plain.wall_s)
            full = replay(path, check=True)
            if full.divergence is not None:  # a replay that disagrees measures nothing
                raise RuntimeError(f"the bench's replay diverged: {full.divergence.describe()}")
            checked.append(full.wall_s)
        replayed = plain.duration_s
    # The quickest of each: what the code costs, without what a busy machine added.
    wall, wall_checked = min(fast), min(checked)
    return {
        "replay_realtime_factor": round(replayed / wall, 2),
        "replay_check_realtime_factor": round(replayed / wall_checked, 2),
        "replayed_s": round(replayed, 3),
        "replay_wall_s": round(wall, 3),
        "replay_check_wall_s": round(wall_checked, 3),
    }
