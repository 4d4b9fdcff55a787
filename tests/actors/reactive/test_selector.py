"""The gait selector's policy, called directly: Table 5.9 with hysteresis, a dwell, a calm
period for returns, pitch and roll apart."""

from __future__ import annotations

import itertools
import math

import pytest

from whexar.actors.messages import GaitChoice, GaitSelected, TerrainEstimate
from whexar.actors.reactive.selector import GaitSelector, exceeded
from whexar.config import GaitThresholds, RobotConfig
from whexar.runtime.messages import Message

SPEC = RobotConfig().gait_selector


def est(t: float, **metrics: float) -> TerrainEstimate:
    values: dict[str, float] = {
        "step_height_m": 0.0,
        "pitch_deg": 0.0,
        "roll_deg": 0.0,
        "obstacles": 0,
        "bumps": 0,
        "lost_supports": 0,
        "samples": 10,
    }
    values.update(metrics)
    values["pitch_rad"] = math.radians(values.pop("pitch_deg"))
    values["roll_rad"] = math.radians(values.pop("roll_deg"))
    values["tilt_known"] = bool(values.pop("samples"))
    return TerrainEstimate(t=t, source="terrain", window_s=1.6, **values)  # type: ignore[arg-type]


def modes(out: list[Message]) -> list[str]:
    return [m.after for m in out if isinstance(m, GaitSelected)]


def run(sel: GaitSelector, t0: float, t1: float, **metrics: float) -> list[str]:
    """Estimates every 0.1 s from ``t0`` to ``t1``: the modes chosen on the way."""
    out = []
    k = 0
    while t0 + 0.1 * k < t1 - 1e-9:
        out += modes(sel.take(est(round(t0 + 0.1 * k, 6), **metrics)))
        k += 1
    return out


def test_table_5_9_each_limit_moves_to_the_least_stable_mode_that_holds() -> None:
    cases: list[tuple[dict[str, float], str]] = [
        ({}, "wheels"),
        ({"bumps": 11}, "tripod"),  # wheels ≤ 10 bumps
        ({"obstacles": 1}, "tripod"),  # wheels: none
        ({"pitch_deg": 22.0}, "tetrapod"),  # tripod ±20°
        ({"roll_deg": -27.0}, "ripple"),  # tetrapod ±25°
        ({"step_height_m": 0.11}, "tetrapod"),  # tripod 100 mm
        ({"step_height_m": 0.23}, "wave"),  # ripple 220 mm
        ({"lost_supports": 4}, "tetrapod"),  # tripod ≤ 3
        ({"lost_supports": 9}, "wave"),  # past every limit: the most stable
    ]
    for metrics, mode in cases:
        sel = GaitSelector(SPEC)
        out = sel.take(est(0.0, **metrics))
        (choice,) = [m for m in out if isinstance(m, GaitChoice)]
        assert (sel.mode, choice.wheels) == (mode, mode == "wheels"), metrics
        assert choice.gait == ("tripod" if mode == "wheels" else mode)


def test_a_step_while_riding_is_no_flat_ground() -> None:
    assert exceeded(est(0.0, step_height_m=0.02), SPEC.wheels) == "a step of 20 mm over 0 mm"
    assert exceeded(est(0.0, step_height_m=0.02), SPEC.tripod) is None


def test_without_a_tilt_reading_the_tilt_limits_do_not_apply() -> None:
    assert exceeded(est(0.0, pitch_deg=40.0, samples=0), SPEC.wheels) is None


def test_more_stable_at_once_less_stable_one_rank_at_a_time_after_dwell_and_calm() -> None:
    sel = GaitSelector(SPEC)
    assert run(sel, 0.0, 1.0, lost_supports=2) == ["wheels"]
    assert run(sel, 1.0, 1.1, lost_supports=6) == ["wave"]  # at once, skipping three
    # The terrain calms at 1.1 s: a return waits for the dwell (5 s from 1.0 s) and the
    # calm (5 s), then goes one rank at a time, each after its own calm.
    back = []
    t = 1.1
    while t < 40.0:
        for m in sel.take(est(round(t, 6))):
            if isinstance(m, GaitSelected):
                back.append((round(m.t, 1), m.after))
        t += 0.1
    assert [mode for _, mode in back] == ["ripple", "tetrapod", "tripod", "wheels"]
    assert back[0][0] == pytest.approx(6.1)
    gaps = [b[0] - a[0] for a, b in itertools.pairwise(back)]
    assert all(5.0 <= g <= 5.25 for g in gaps), gaps


def test_a_tilt_at_a_threshold_does_not_make_the_gait_flap() -> None:
    sel = GaitSelector(SPEC)
    changes = []
    for k in range(600):  # a minute of a slope that wavers about tripod's 20° limit
        t = 0.1 * k
        pitch = 20.0 + (0.8 if (k // 7) % 2 else -0.8)
        changes += modes(sel.take(est(t, pitch_deg=pitch, obstacles=1)))
    # Tripod at first (19.2°), up once at 20.8°; 19.2° is inside 20° but not by the 3° margin.
    assert changes == ["tripod", "tetrapod"]


def test_roll_has_its_own_limit() -> None:
    spec = SPEC.model_copy(
        update={
            "tripod": GaitThresholds(
                max_step_height_mm=100, max_tilt_deg=20, max_roll_deg=10, max_lost_supports=3
            )
        }
    )
    sel = GaitSelector(spec)
    sel.take(est(0.0, obstacles=1, roll_deg=12.0))
    assert sel.mode == "tetrapod"
    sel = GaitSelector(spec)
    sel.take(est(0.0, obstacles=1, pitch_deg=12.0))
    assert sel.mode == "tripod"


def test_each_change_says_why() -> None:
    sel = GaitSelector(SPEC)
    sel.take(est(0.0, obstacles=1))
    out = sel.take(est(0.1, obstacles=1, pitch_deg=-21.5))
    (said,) = [m for m in out if isinstance(m, GaitSelected)]
    assert (said.before, said.after) == ("tripod", "tetrapod")
    assert said.reason == "a pitch of -21.5° beyond ±20°"
    (choice,) = [m for m in out if isinstance(m, GaitChoice)]
    assert choice.reason == said.reason


@pytest.mark.parametrize("rank", [1, 2, 3])
def test_a_steady_terrain_keeps_the_gait(rank: int) -> None:
    lost = [0, 4, 5, 6][rank]
    sel = GaitSelector(SPEC)
    assert len(run(sel, 0.0, 30.0, lost_supports=lost, obstacles=1)) == 1
