"""How the robot moves: the gait selector's thresholds (Table 5.9), the stance presets
(6.3, 6.4) and locomotion's settings."""

from __future__ import annotations

import itertools
import math
from typing import Annotated, Literal

from pydantic import (
    Field,
)

from whexar.errors import Problem
from whexar.kinematics.body import Stance
from whexar.kinematics.contact import ContactModel, SensorModel
from whexar.kinematics.gait import GAIT_RANKING
from whexar.runtime.schema import (
    NonNegative,
    Positive,
    Section,
)

# --------------------------------------------------------------------------- gait selection


class GaitThresholds(Section):
    """Limits of one locomotion mode; beyond any of them a more stable mode is chosen.

    An absent ``max_obstacles`` or ``max_bumps`` means no limit (Table 5.9 "> 0",
    "> 10": walking gaits accept any count).
    """

    max_step_height_mm: NonNegative
    max_tilt_deg: float = Field(gt=0, le=90, allow_inf_nan=False)
    """Body pitch tolerated, symmetric about level; roll too unless ``max_roll_deg``."""
    max_roll_deg: float | None = Field(default=None, gt=0, le=90, allow_inf_nan=False)
    """Body roll tolerated, when it differs from pitch: 4.2.3 counts them apart, "as it
    has different impact on the gaits"; absent: ``max_tilt_deg``."""
    max_obstacles: int | None = Field(default=None, ge=0)
    max_bumps: int | None = Field(default=None, ge=0)
    """IMU bumps counted by the terrain controller (4.2.3)."""
    max_lost_supports: int = Field(ge=0)
    """Disappeared leg supports within the window (4.2.3, 6.7.5)."""

    @property
    def roll_limit_deg(self) -> float:
        """The roll tolerated: ``max_roll_deg``, else ``max_tilt_deg``."""
        return self.max_tilt_deg if self.max_roll_deg is None else self.max_roll_deg


class GaitSelectorSpec(Section):
    """Gait-selector thresholds: Table 5.9, wheel tilt raised from 7° to 20° (6.7.5)."""

    lost_support_window_cycles: Positive = 1.0
    """Disappeared supports are counted over a floating window of one gait cycle (6.7.5);
    the terrain estimator's other metrics share the window."""
    tilt_hysteresis_deg: NonNegative = 3.0
    """A return to a less stable gait waits for the tilt to lie this far inside its limit:
    a slope near a threshold does not make the gait flap."""
    step_hysteresis_mm: NonNegative = 10.0
    """… the step height this far inside it."""
    count_hysteresis: int = Field(default=1, ge=0, le=100)
    """… the counts (obstacles, bumps, lost supports) this many below it."""
    min_dwell_s: NonNegative = 5.0
    """A gait the selector chose is kept at least this long before a return: three tripod
    cycles of 1.6 s, so that a change is walked in before it is judged."""
    calm_s: NonNegative = 5.0
    """… and the terrain must have stayed within the less stable gait's limits (with the
    hysteresis) this long. A move to a more stable gait is never delayed."""
    wheels: GaitThresholds = GaitThresholds(
        max_step_height_mm=0, max_tilt_deg=20, max_obstacles=0, max_bumps=10, max_lost_supports=3
    )
    tripod: GaitThresholds = GaitThresholds(
        max_step_height_mm=100, max_tilt_deg=20, max_lost_supports=3
    )
    tetrapod: GaitThresholds = GaitThresholds(
        max_step_height_mm=120, max_tilt_deg=25, max_lost_supports=4
    )
    ripple: GaitThresholds = GaitThresholds(
        max_step_height_mm=220, max_tilt_deg=30, max_lost_supports=5
    )
    wave: GaitThresholds = GaitThresholds(
        max_step_height_mm=350, max_tilt_deg=30, max_lost_supports=5
    )

    def ranked(self) -> tuple[tuple[str, GaitThresholds], ...]:
        """(mode, thresholds) from wheels to wave."""
        return tuple((name, getattr(self, name)) for name in GAIT_RANKING)

    def problems(self, at: str) -> list[Problem]:
        # A more stable mode must tolerate at least what a less stable one does,
        # or the selector could escalate into a mode that rejects the terrain.
        found: list[Problem] = []
        keys = (
            "max_step_height_mm",
            "max_tilt_deg",
            "max_obstacles",
            "max_bumps",
            "max_lost_supports",
        )
        ranked = self.ranked()
        for (lo_name, lo), (hi_name, hi) in itertools.pairwise(ranked):
            if hi.max_roll_deg is not None and hi.roll_limit_deg < lo.roll_limit_deg:
                found.append(
                    Problem(
                        f"{at}.{hi_name}.max_roll_deg",
                        hi.max_roll_deg,
                        f"at least {lo_name}'s roll limit ({lo.roll_limit_deg:g}): thresholds "
                        f"may not fall along the ranking {' < '.join(GAIT_RANKING)}",
                    )
                )
        for key in keys:
            for (lo_name, lo), (hi_name, hi) in itertools.pairwise(ranked):
                a, b = getattr(lo, key), getattr(hi, key)
                a_val = math.inf if a is None else a
                b_val = math.inf if b is None else b
                if b_val < a_val:
                    shown = "no limit" if a is None else f"{a:g}"
                    found.append(
                        Problem(
                            f"{at}.{hi_name}.{key}",
                            b,
                            f"at least {lo_name}'s {shown}: thresholds may not fall along "
                            f"the ranking {' < '.join(GAIT_RANKING)}",
                        )
                    )
        return found


class TerrainSpec(Section):
    """The terrain estimator's settings (4.2.3, :mod:`whexar.actors.reactive.terrain`): how it
    turns readings into the gait selector's metrics."""

    tick_s: Positive = 0.1
    """It publishes its estimate this often: ten times in a tripod swing of 0.8 s."""
    min_window_s: Positive = 1.0
    """The shortest window, s: a fast gait's cycle (0.8 s) still holds two footfalls."""
    still_window_s: Positive = 2.0
    """The window while no gait runs (riding, standing): the cycle of a slow walk."""
    min_offset_mm: NonNegative = 10.0
    """A swing that met ground less than this above where it expected met the flat
    (the foot's compliance and the ground's roughness): no step asked."""
    bump_g: float = Field(default=0.5, gt=0, lt=5, allow_inf_nan=False)
    """An IMU reading further than this from 1 g is a jolt (4.2.3's bumps): twice the
    accelerometer's plausibility band (0.2 g), so a tilt is no bump."""
    bump_gap_s: Positive = 0.1
    """Jolts closer than this to the last are the same bump."""
    obstacle_near_m: Positive = 0.4
    """A rangefinder reading nearer than this sees an obstacle ahead: within two steps of
    the front feet (the rangefinders look forward from the front legs, 5.3.5)."""
    obstacle_clear_m: Positive = 0.6
    """… which is counted again only once the reading was beyond this (hysteresis)."""
    lost_confidence: float = Field(default=0.5, gt=0, lt=1, allow_inf_nan=False)
    """A foot counts as a lost support when its contact estimate believes the loss at
    least this much (a dead force sensor's "no contact" while the current and the stance
    say load does not count)."""

    def problems(self, at: str) -> list[Problem]:
        if self.obstacle_clear_m <= self.obstacle_near_m:
            return [
                Problem(
                    f"{at}.obstacle_clear_m",
                    self.obstacle_clear_m,
                    f"beyond obstacle_near_m ({self.obstacle_near_m:g}) for hysteresis",
                )
            ]
        return []


# --------------------------------------------------------------------------- contact


Probability = Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)]


class ContactSpec(Section):
    """The legs' contact estimate (:mod:`whexar.kinematics.contact`): how far each sensor is
    to be believed, and when one is set aside. ``locomotion.contact`` says which sensor
    the legs prefer and ``locomotion.contact_current_a`` the current that reads as load.

    The sensors' rates are per control cycle, measured in the simulated tripod walk on the
    flat (docs/reflexes.md, "The contact estimate"); they include each sensor's lag at
    touchdown and lift-off, which is most of their errors."""

    fsr_hit: Probability = 0.89
    """P(the FSR reads contact | the foot is in stance)."""
    fsr_false_alarm: Probability = 0.16
    """P(the FSR reads contact | the foot is in swing): its ~0.1 s lag at lift-off."""
    current_hit: Probability = 0.46
    """P(|femur current| above the threshold | stance): the middle legs carry less."""
    current_false_alarm: Probability = 0.12
    """P(|femur current| above the threshold | swing)."""
    stance_prior: Probability = 0.9
    """P(load) of a foot the leg holds down: its step says so, unless the ground is not
    where the leg thinks."""
    swing_prior: Probability = 0.1
    fsr_fresh_s: Positive = 0.5
    """Force-sensor frames older than this no longer count: ten frames at 20 Hz (5.4)."""
    current_fresh_s: Positive = 0.1
    """A femur current read longer ago than this is stale: ten control cycles, every read
    plan reads currents each cycle (:mod:`whexar.bus.plan`)."""
    fault_steps: int = Field(default=3, ge=1, le=50)
    """A force sensor that contradicts this many stances (or swings) in a row is set
    aside: one could be a hole, three are the sensor."""
    noisy_step_a: Positive = 0.4
    """A femur current that moves by more than this per cycle, on average over a stance,
    is noise and set aside until a stance is calm again (walking: 0.03–0.24 A a cycle,
    docs/reflexes.md)."""
    loaded_share: float = Field(default=0.25, gt=0, le=1, allow_inf_nan=False)
    """A stance counts against a silent force sensor when the femur current read load for
    this share of it: a dead sensor's loaded leg reads so for 0.46–0.55 of a stance, a
    leg the others unload (the foot of a ramp) for 0.01–0.07 (docs/reflexes.md)."""
    learn_cycles: float = Field(default=200.0, ge=10, le=100000, allow_inf_nan=False)
    """Each leg learns its femur current's threshold from running means over this many
    control cycles (2 s at 100 Hz: a gait cycle or more), labelled by its force sensor."""
    separation_a: Positive = 0.2
    """The learnt stance and swing currents must lie this far apart to be used (the
    front legs' lie 0.8 A apart walking the tripod gait, docs/reflexes.md)."""
    search_speed_m_s: Positive = 0.05
    """A foot searching for ground below where it expected it goes down at this speed
    (the searching reflex, 4.2.2): the FSR's 0.13 s lag lets it press 7 mm into what it
    finds."""
    search_stop_m: Positive = 0.015
    """A searching foot whose distance from its goal's point grew by this much since the
    search began is held by the ground it looks for: found, before the force sensor says
    so where the leg carries little load (the front legs uphill on 30°)."""
    balance_gain_m_s: float = Field(default=5e-5, ge=0.0, le=1e-3, allow_inf_nan=False)
    """A stance foot whose force sensor reads a count below the loaded feet's mean goes
    down this fast, m/s (up, above it), where the ground tilts (``balance_tilt_deg``); 0:
    the stance never shares its load (the thesis's leg-load control, 6.8.1). On 30° it
    stops the body rocking on a diagonal pair (measured in docs/reflexes.md, "On slopes
    only")."""
    balance_speed_m_s: float = Field(default=0.02, gt=0.0, le=0.2, allow_inf_nan=False)
    """… at most this fast."""
    balance_m: float = Field(default=0.02, ge=0.0, le=0.1, allow_inf_nan=False)
    """… and no further than this from where its stance began: walking 30° a foot hangs
    1–1.5 cm above the ground as the body rolls (docs/reflexes.md)."""
    balance_tilt_deg: float = Field(default=20.0, ge=0.0, le=90.0, allow_inf_nan=False)
    """… where the ground tilts this far from level or more (the body's low-passed tilt
    less its pose, ``locomotion.tilt_filter_s``); 0: everywhere. On the flat the share
    cost the snag and the deep trench their success (docs/reflexes.md); the default
    course's 15° ramp stays below it."""
    touchdown_s: Positive = 0.25
    """A swing that ended with no contact is judged this long after its end: ``completed``
    if contact came meanwhile, else ``no_contact`` (the FSR's contact lags the swing's end
    by up to 0.13 s, docs/reflexes.md)."""

    def model(self, current_a: float) -> ContactModel:
        """The estimator's model, ``current_a`` the femur current that reads as load."""
        return ContactModel(
            fsr=SensorModel(self.fsr_hit, self.fsr_false_alarm),
            current=SensorModel(self.current_hit, self.current_false_alarm),
            current_a=current_a,
            stance_prior=self.stance_prior,
            swing_prior=self.swing_prior,
            fsr_fresh_s=self.fsr_fresh_s,
            current_fresh_s=self.current_fresh_s,
            fault_steps=self.fault_steps,
            noisy_step_a=self.noisy_step_a,
            loaded_share=self.loaded_share,
            learn_cycles=self.learn_cycles,
            separation_a=self.separation_a,
        )

    def problems(self, at: str) -> list[Problem]:
        found = []
        for sensor in ("fsr", "current"):
            hit, false = getattr(self, f"{sensor}_hit"), getattr(self, f"{sensor}_false_alarm")
            if false >= hit:
                found.append(
                    Problem(
                        f"{at}.{sensor}_false_alarm",
                        false,
                        f"below {sensor}_hit ({hit:g}): a sensor that reads contact more "
                        "often in swing than in stance tells nothing",
                    )
                )
        if self.swing_prior >= self.stance_prior:
            found.append(
                Problem(
                    f"{at}.swing_prior",
                    self.swing_prior,
                    f"below stance_prior ({self.stance_prior:g})",
                )
            )
        return found


# --------------------------------------------------------------------------- stances


class StanceSpec(Section):
    """A standing posture, the same for all legs up to the front/rear yaw (6.3, 6.4).

    ``reach_mm`` is the horizontal distance from the coxa joint to the wheel's
    contact point, ``height_mm`` the height of the coxa joints above the ground,
    ``front_rear_yaw_deg`` how far front legs turn forward and rear legs
    backward (6.4: 25° stopped the tripod gait from tipping backwards).
    """

    reach_mm: Positive
    height_mm: Positive
    front_rear_yaw_deg: float = Field(default=0.0, ge=-90, le=90, allow_inf_nan=False)
    description: str = ""

    def to_stance(self) -> Stance:
        """This preset in SI, as the kinematics takes it."""
        return Stance(
            reach=self.reach_mm / 1000,
            height=self.height_mm / 1000,
            front_rear_yaw=math.radians(self.front_rear_yaw_deg),
        )


def default_stances() -> dict[str, StanceSpec]:
    # Fig. 6.1 shows the stances without joint values; reach and height are
    # chosen to match its captions and Table 6.5 (row 1: tarsus at x = 190,
    # y = 120 mm, i.e. contact 120 + 170 mm below the coxa).
    return {
        "default": StanceSpec(
            reach_mm=190,
            height_mm=290,
            front_rear_yaw_deg=25,
            description="walking stance of 6.4: Table 6.5 row 1, front/rear legs turned 25 deg",
        ),
        "basic": StanceSpec(
            reach_mm=190,
            height_mm=290,
            description="Table 6.5 row 1 on every leg (Fig. 6.1 b)",
        ),
        "high": StanceSpec(
            reach_mm=160,
            height_mm=380,
            front_rear_yaw_deg=25,
            description="highest stance, for stepping over high obstacles (Fig. 6.1 a)",
        ),
        "low": StanceSpec(
            reach_mm=240,
            height_mm=200,
            front_rear_yaw_deg=25,
            description="20 cm stance for crawling under low obstacles (Fig. 6.1 c)",
        ),
        "narrow": StanceSpec(
            reach_mm=140,
            height_mm=290,
            description="shortest stance (Fig. 6.1 e)",
        ),
    }


# --------------------------------------------------------------------------- locomotion

Trajectory = Literal["parabola", "half_sine", "hopf", "van_der_pol", "rayleigh", "stick_slip"]
"""Swing shapes: Diosdado 2014, 3.3–3.4, and the CPG orbits of Grzelczyk et al., 8.4."""
ContactSource = Literal["auto", "fsr", "current", "none"]


class LocomotionSpec(Section):
    """The coordinator's and the leg actors' settings (4.2.5, 4.2.6, 5.4, 6.3–6.6).

    Speeds follow from steps: a gait covers one step length per stance, so
    v = L / (β·T) for step length L, duty factor β and cycle time T. The
    coordinator keeps every swing at least ``min_swing_s`` long, T at most
    ``max_cycle_s`` and L within ``max_step_length_mm``; a faster command is
    clamped with an event.
    """

    stance: str = "default"
    """Stance at start (a ``[stances]`` preset); the walking stance of 6.4."""
    ride_stance: str = "basic"
    """Stance for riding: every leg square to the body, so the wheels sit symmetric."""
    gait: Literal["tripod", "tetrapod", "ripple", "wave"] = "tripod"
    hybrid_gait: Literal["tripod", "tetrapod", "ripple", "wave"] = "ripple"
    """The gait stepping while the wheels drive; ripple for its stability (6.6)."""
    trajectory: Trajectory = "parabola"
    min_swing_s: Positive = 0.4
    """Shortest swing: the tripod gait's cycle then lasts 0.8 s, half the 1.6 s of 6.8.1."""
    max_cycle_s: Positive = 6.0
    """Longest gait cycle; slower commands take shorter steps instead."""
    step_length_mm: Positive = 100.0
    """Preferred step. The cycle follows the speed, T = L / (β·v): the tripod gait at
    0.125 m/s steps every 1.6 s, as in 6.8.1 (0.07–0.12 m/s, 1.6 s)."""
    max_step_length_mm: Positive = 140.0
    """Longest step the workspace of every stance preset allows with margin."""
    step_height_mm: Positive = 60.0
    max_step_height_mm: Positive = 120.0
    """Table 5.9: tetrapod steps over 120 mm; the swing apex may not exceed it."""
    max_accel_m_s2: Positive = 0.25
    """Body acceleration limit while walking or riding; velocity changes ramp."""
    max_yaw_accel_deg_s2: Positive = 60.0
    ride_max_speed_m_s: Positive = 0.2
    """Top riding speed measured in 6.5.1."""
    min_turn_radius_mm: Positive = 400.0
    """A circle about a point inside the body (half its length, 300 mm) is refused."""
    hybrid_wheel_share: float = Field(default=0.5, gt=0, lt=1)
    """Share of the hybrid gait's speed the wheels make; the legs step the rest (6.6)."""
    min_stability_margin_mm: Positive = 30.0
    """No leg lifts when the static margin of the remaining feet would fall below this."""
    trochanter_follows_pitch: bool = True
    """Turn the trochanters with the body pitch (eq. 4.18), commanded and measured; they
    carry the feet on their arcs (:func:`whexar.kinematics.leg.trochanter_arc`)."""
    max_trochanter_deg: float = Field(default=60.0, gt=0, lt=90, allow_inf_nan=False)
    """The trochanters follow the pitch up to this. The joint turns a full circle (it flips
    the legs, 6.8.1); the IK of eq. 4.18 needs the angle strictly inside ±90°, and beyond
    60° the arc lifts the feet by more than half their depth."""
    settle_s: NonNegative = 0.5
    """Standing, the feet's goals follow where the feet are, with this time constant, so
    the legs stop pushing each other through the ground (:mod:`whexar.actors.locomotion.
    settle`); 0: the goals hold."""
    settle_max_mm: Positive = 40.0
    """… never further than this from the stance's neutral point."""
    tilt_filter_s: Positive = 1.0
    """Time constant of the low-pass on the measured pitch the trochanters follow: a slope
    is steady, the accelerations of walking are not."""
    transition_s: Positive = 1.0
    """Duration of a stance change, a leg re-placement, a body pose change."""
    stand_up_s: Positive = 2.0
    sit_height_mm: Positive = 80.0
    """Coxa joints above the ground when seated: the 60 mm body resting on the ground."""
    sit_down_s: Positive = 1.5
    flip_s: Positive = 2.0
    """Time to turn the legs 180° about their trochanters (6.8.1)."""
    align_tolerance_deg: Positive = 3.0
    """Direction servos within this of their heading before the wheels turn."""
    align_timeout_s: Positive = 1.5
    wheel_stop_speed_m_s: Positive = 0.005
    """A wheel slower than this counts as stopped before its leg lifts."""
    contact: ContactSource = "auto"
    """Foot contact: the force sensor when frames arrive (auto), always it, the femur
    current (6.7.3), or none (no adaptive swing)."""
    contact_current_a: Positive = 0.8
    """|femur current| above this means the foot carries load (6.7.3)."""
    lost_after_s: float = Field(default=0.3, gt=0.02, le=5.0, allow_inf_nan=False)
    """A joint the bus has not read for this long (and three of its read periods) is
    lost, and the coordinator walks on without it (:mod:`whexar.actors.locomotion.losses`):
    longer than the bus's ``degrade_after`` failed cycles, so that a read that fails once
    changes nothing."""
    ride_lost_coxa: bool = True
    """A leg whose coxa is lost rides its wheel while the others walk; false: it is dragged
    along (only heading hold then keeps the robot's heading)."""
    reflex_hold_s: Positive = 0.3
    """A reflex goal keeps its joint this long after it was sent."""
    reflex_blend_s: Positive = 0.3
    """Then the leg blends back from the reflex's pose to its own in this time."""

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        if self.min_swing_s >= self.max_cycle_s:
            found.append(
                Problem(
                    f"{at}.min_swing_s",
                    self.min_swing_s,
                    f"below max_cycle_s ({self.max_cycle_s:g})",
                )
            )
        if self.step_length_mm > self.max_step_length_mm:
            found.append(
                Problem(
                    f"{at}.step_length_mm",
                    self.step_length_mm,
                    f"at most max_step_length_mm ({self.max_step_length_mm:g})",
                )
            )
        if self.step_height_mm > self.max_step_height_mm:
            found.append(
                Problem(
                    f"{at}.step_height_mm",
                    self.step_height_mm,
                    f"at most max_step_height_mm ({self.max_step_height_mm:g})",
                )
            )
        return found
