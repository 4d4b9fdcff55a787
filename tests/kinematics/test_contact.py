"""The contact estimate, called directly: readings in, an estimate and health changes out."""

from __future__ import annotations

import pytest

from whexar.config import RobotConfig
from whexar.kinematics.contact import (
    ContactEstimate,
    ContactEstimator,
    HealthChange,
    depth_below_plane,
)

CFG = RobotConfig()
MODEL = CFG.contact.model(CFG.locomotion.contact_current_a)
DT = 0.01


class Leg:
    """Drives one estimator through gait cycles: 0.4 s of stance, 0.4 s of swing."""

    def __init__(self, preference: str = "auto") -> None:
        self.est = ContactEstimator(MODEL, preference)  # type: ignore[arg-type]
        self.t = 0.0
        self.changes: list[tuple[float, HealthChange]] = []
        self.last: ContactEstimate | None = None

    def phase(
        self,
        phase: str,
        seconds: float,
        *,
        fsr: bool | None,
        amps: float | None,
        fresh_current: bool = True,
    ) -> list[ContactEstimate]:
        out = []
        for _ in range(round(seconds / DT)):
            self.t = round(self.t + DT, 9)
            e = self.est.estimate(
                self.t,
                phase,
                fsr=fsr,
                fsr_t=self.t if fsr is not None else -1.0,
                current_a=amps,
                current_t=self.t if fresh_current else 0.0,
            )
            out.append(e)
            self.changes += [(self.t, c) for c in self.est.take_changes()]
        self.last = out[-1]
        return out

    def cycles(self, n: int, *, stance_fsr: bool = True, swing_fsr: bool = False) -> None:
        """``n`` gait cycles, the femur drawing −1.2 A in stance and +0.2 A in swing."""
        for _ in range(n):
            self.phase("stance", 0.4, fsr=stance_fsr, amps=-1.2)
            self.phase("swing", 0.4, fsr=swing_fsr, amps=0.2)


def test_a_sound_force_sensor_is_read_as_it_reads_with_the_confidence_of_all() -> None:
    leg = Leg()
    leg.cycles(2)
    (agree,) = leg.phase("stance", DT, fsr=True, amps=-1.2)
    assert (agree.contact, agree.source) == (True, "fsr")
    assert agree.confidence > 0.99  # phase, FSR and current all say load
    (alone,) = leg.phase("stance", DT, fsr=False, amps=-1.2)
    assert (alone.contact, alone.source) == (False, "fsr")  # as it reads…
    assert alone.confidence < 0.5  # …but the current and the stance say otherwise
    (air,) = leg.phase("swing", DT, fsr=False, amps=0.2)
    assert (air.contact, air.confidence > 0.99) == (False, True)
    assert leg.changes == []


def test_each_leg_learns_its_current_threshold_from_its_force_sensor() -> None:
    leg = Leg()
    # A front leg: −0.5 A in stance, +0.3 A in swing; |−0.5| never passes the 0.8 A of 6.7.3.
    assert not leg.est.reads_load(-0.5)
    for _ in range(3):
        leg.phase("stance", 0.4, fsr=True, amps=-0.5)
        leg.phase("swing", 0.4, fsr=False, amps=0.3)
    assert leg.est.stance_a == pytest.approx(-0.5)
    assert leg.est.swing_a == pytest.approx(0.3)
    assert leg.est.reads_load(-0.5)
    assert leg.est.reads_load(-0.2)  # past the midpoint, −0.1 A
    assert not leg.est.reads_load(0.0)
    assert not leg.est.reads_load(0.3)


def test_currents_that_do_not_separate_keep_the_configured_threshold() -> None:
    leg = Leg()
    for _ in range(3):
        leg.phase("stance", 0.4, fsr=True, amps=-0.5)
        leg.phase("swing", 0.4, fsr=False, amps=-0.4)  # 0.1 A apart: below separation_a
    assert not leg.est.reads_load(-0.5)
    assert leg.est.reads_load(-0.9)


def test_a_dead_force_sensor_is_set_aside_and_the_current_takes_over() -> None:
    leg = Leg()
    leg.cycles(3)
    leg.cycles(CFG.contact.fault_steps, stance_fsr=False)  # the wire breaks: 0 from now on
    (t, change) = leg.changes[0]
    assert (change.sensor, change.usable) == ("fsr", False)
    assert "no load" in change.reason
    assert t == pytest.approx(0.8 * (3 + CFG.contact.fault_steps - 1) + 0.4 + DT)
    (stance,) = leg.phase("stance", DT, fsr=False, amps=-1.2)
    assert (stance.contact, stance.source) == (True, "current")
    (swing,) = leg.phase("swing", DT, fsr=False, amps=0.2)
    assert (swing.contact, swing.source) == (False, "current")


def test_a_foot_in_a_hole_is_no_fault_of_the_force_sensor() -> None:
    leg = Leg()
    leg.cycles(3)
    for _ in range(5):  # neither sensor feels load: the foot found nothing
        leg.phase("stance", 0.4, fsr=False, amps=0.1)
        leg.phase("swing", 0.4, fsr=False, amps=0.2)
    assert leg.changes == []


def test_a_stuck_force_sensor_is_set_aside_and_taken_back_once_it_releases() -> None:
    leg = Leg()
    leg.cycles(2)
    leg.cycles(CFG.contact.fault_steps, swing_fsr=True)
    leg.phase("stance", DT, fsr=True, amps=-1.2)  # the last swing is judged as it ends
    assert [(c.sensor, c.usable) for _, c in leg.changes] == [("fsr", False)]
    assert "through 3 swings" in leg.changes[0][1].reason
    (swing,) = leg.phase("swing", DT, fsr=True, amps=0.2)
    assert swing.source == "current"
    leg.cycles(2)  # load in a stance, none in the swing after it
    assert [(c.sensor, c.usable) for _, c in leg.changes] == [("fsr", False), ("fsr", True)]
    (back,) = leg.phase("stance", DT, fsr=True, amps=-1.2)
    assert back.source == "fsr"


def test_a_current_the_bus_stopped_reading_is_set_aside_until_it_comes_back() -> None:
    leg = Leg()
    leg.cycles(2)
    leg.phase("stance", 0.4, fsr=None, amps=-1.2, fresh_current=False)  # no frames, no reads
    assert [(c.sensor, c.usable) for _, c in leg.changes] == [("current", False)]
    assert leg.last == ContactEstimate(False, 0.0, "none")
    leg.phase("stance", 0.1, fsr=None, amps=-1.2)
    assert [(c.sensor, c.usable) for _, c in leg.changes][-1] == ("current", True)
    assert leg.last is not None
    assert (leg.last.contact, leg.last.source) == (True, "current")


def test_a_noisy_current_is_set_aside_after_a_noisy_stance() -> None:
    leg = Leg()
    leg.cycles(2)
    for k in range(40):  # ±0.6 A of noise on the stance's −1.2 A
        leg.phase("stance", DT, fsr=True, amps=-1.2 + (0.6 if k % 2 else -0.6))
    leg.phase("swing", 0.4, fsr=False, amps=0.2)
    assert [(c.sensor, c.usable) for _, c in leg.changes] == [("current", False)]
    assert "A a cycle" in leg.changes[0][1].reason
    leg.cycles(1)  # a calm stance
    assert [(c.sensor, c.usable) for _, c in leg.changes][-1] == ("current", True)


def test_the_preference_picks_the_sensor() -> None:
    none = Leg("none")
    none.cycles(1)
    assert none.last == ContactEstimate(False, 0.0, "none")
    current = Leg("current")
    (e,) = current.phase("stance", DT, fsr=False, amps=-1.2)
    assert (e.contact, e.source) == (True, "current")
    fsr = Leg("fsr")
    (e,) = fsr.phase("stance", DT, fsr=None, amps=-1.2)
    assert e.source == "none"


def test_a_foot_is_judged_against_the_plane_of_the_others_however_tilted() -> None:
    # Four feet on a plane tilted 5° about x and 3° about y, the body over them.
    def ground(x: float, y: float) -> float:
        return -0.27 + 0.0875 * y - 0.0524 * x

    feet = [(x, y, ground(x, y)) for x, y in ((0.3, 0.25), (0.3, -0.25), (-0.3, 0.3), (0, -0.35))]
    on = (-0.3, -0.3, ground(-0.3, -0.3))
    assert depth_below_plane(feet, on) == pytest.approx(0.0, abs=1e-9)
    below = (on[0], on[1], on[2] - 0.03)
    assert depth_below_plane(feet, below) == pytest.approx(0.03)
    assert depth_below_plane(feet[:3], below) == pytest.approx(0.03)  # three make a plane


def test_two_feet_or_feet_in_a_line_make_no_plane() -> None:
    assert depth_below_plane([(0.3, 0.2, -0.27), (-0.3, 0.2, -0.27)], (0.0, 0.0, -0.3)) is None
    line = [(0.3, 0.2, -0.27), (0.0, 0.23, -0.27), (-0.3, 0.2, -0.27)]  # one side's feet
    assert depth_below_plane(line, (0.0, -0.2, -0.3)) is None
