"""The robot's parts: body, servo models, joints and their limits, the DH table, the legs
(Tables 5.2, 5.3; eq. 4.1)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated, Literal

from pydantic import (
    Field,
)

from whexar.bus.protocol import MAX_ID
from whexar.config.common import ServoModelName
from whexar.errors import MISSING, Problem
from whexar.kinematics.indices import STANDARD_GRAVITY, SUPPLY_VOLTAGE, WHEXAR_MASS
from whexar.robot import JOINT_NAMES, LEG_NAMES, POSITIONING_JOINTS, servo_id
from whexar.runtime.schema import (
    Finite,
    NonNegative,
    Positive,
    Section,
)

# --------------------------------------------------------------------------- robot & body


class RobotSpec(Section):
    """Whole-robot constants."""

    name: str = "WHexaR"
    mass_kg: Positive = WHEXAR_MASS
    """Total mass used for the cost of transport (6.8.1)."""
    supply_voltage_v: Positive = SUPPLY_VOLTAGE
    """Supply voltage in the experiments (5.3.1, 6.8)."""
    gravity_m_s2: Positive = STANDARD_GRAVITY
    """Gravitational acceleration used by the thesis (6.8.1)."""


class BodySpec(Section):
    """The body tube: an aluminium rectangular profile 60 × 10 × 6 cm (5.2)."""

    length_mm: Positive = 600.0
    width_mm: Positive = 100.0
    height_mm: Positive = 60.0
    cog_mm: tuple[Finite, Finite, Finite] = (0.0, 0.0, -43.0)
    """The whole robot's centre of gravity in the body frame (x forward, y left, z up from
    the coxa joints' plane), walking in the default stance: the stability margin projects
    it along gravity (3.2.2). Six legs of 1.02 kg hang below the body, so it sits 43 mm
    below the coxa joints over a tripod cycle (52 mm standing, the swing legs raised
    lift it): the mass model's figure, the simulation's model of these masses
    (``tests/sim/test_model.py`` keeps the two equal). The thesis gives none; on the
    robot, balance it on a knife edge."""


# --------------------------------------------------------------------------- servos & joints


class ServoModelSpec(Section):
    """One Dynamixel MX model (Table 5.1; ROBOTIS e-manual, MX (2.0) pages)."""

    model_number: int = Field(ge=0, le=65535)
    """Value of the Model Number register (address 0) under Protocol 2.0."""
    mass_g: Positive
    stall_torque_nm: Positive
    """Stall torque at 12 V (Table 5.1)."""
    stall_current_a: Positive
    """Current at stall torque, 12 V (5.3.1)."""
    resolution_ticks: int = Field(default=4096, gt=0)
    """Encoder ticks per revolution (Table 5.1)."""


def default_servo_models() -> dict[ServoModelName, ServoModelSpec]:
    return {
        "MX-28": ServoModelSpec(
            model_number=30, mass_g=77.0, stall_torque_nm=2.5, stall_current_a=1.4
        ),
        "MX-64": ServoModelSpec(
            model_number=311, mass_g=135.0, stall_torque_nm=6.0, stall_current_a=4.1
        ),
        "MX-106": ServoModelSpec(
            model_number=321, mass_g=153.0, stall_torque_nm=8.4, stall_current_a=5.2
        ),
    }


GainValue = Annotated[int, Field(strict=True, ge=0, le=16383)]
"""A gain register's value: 0…16 383 (e-manual, MX (2.0): Position D/I/P Gain)."""


class PositionGains(Section):
    """The servo's position controller, in register units (e-manual, MX (2.0): Position D
    Gain (80), I (82), P (84); KPD = D/16, KPI = I/65 536, KPP = P/128). The thesis's leg
    controller sets them (5.4) and gives no values. A gain left out stays the servo's own;
    they are RAM, so start-up writes them, and again after a servo reboots."""

    p: GainValue | None = None
    """Position P Gain (84); the servo's initial value is 850."""
    i: GainValue | None = None
    """Position I Gain (82); initial 0."""
    d: GainValue | None = None
    """Position D Gain (80); initial 0."""

    def registers(self) -> dict[str, int]:
        """The gains given, by register name (``position_p_gain`` …)."""
        named = {"position_p_gain": self.p, "position_i_gain": self.i, "position_d_gain": self.d}
        return {name: v for name, v in named.items() if v is not None}


class JointSpec(Section):
    """One joint of every leg: its servo, range and segment (Table 5.2)."""

    model: ServoModelName
    min_deg: Finite | None = None
    """Lower limit; absent only for an endless joint."""
    max_deg: Finite | None = None
    """Upper limit; absent only for an endless joint."""
    endless: bool = False
    """Continuous rotation (the wheel), no limits."""
    length_mm: NonNegative
    """Distance to the next joint, or to the ground for the wheel (Table 5.2)."""
    gains: PositionGains | None = None
    """Its position controller's gains; absent: the servo's own (:class:`PositionGains`)."""

    @property
    def limits_rad(self) -> tuple[float, float] | None:
        """(min, max) in radians, or ``None`` for an endless joint."""
        if self.endless or self.min_deg is None or self.max_deg is None:
            return None
        return math.radians(self.min_deg), math.radians(self.max_deg)

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        if self.endless:
            if self.gains is not None and self.gains.registers():
                found.append(
                    Problem(
                        f"{at}.gains",
                        self.gains.model_dump(exclude_none=True),
                        "an endless joint runs in velocity control: position gains do nothing",
                    )
                )
            for key in ("min_deg", "max_deg"):
                if getattr(self, key) is not None:
                    found.append(
                        Problem(f"{at}.{key}", getattr(self, key), "an endless joint has no limits")
                    )
            return found
        for key in ("min_deg", "max_deg"):
            if getattr(self, key) is None:
                found.append(Problem(f"{at}.{key}", MISSING, "required unless endless = true"))
        if self.min_deg is not None and self.max_deg is not None and self.min_deg >= self.max_deg:
            found.append(
                Problem(
                    f"{at}.min_deg",
                    self.min_deg,
                    f"must be below max_deg ({self.max_deg:g}); limits are (min, max)",
                )
            )
        return found


class JointsSpec(Section):
    """The seven joints, coxa to wheel (Fig. 4.1, Table 5.2)."""

    coxa: JointSpec = JointSpec(model="MX-64", min_deg=-135, max_deg=135, length_mm=0)
    trochanter: JointSpec = JointSpec(model="MX-106", min_deg=-360, max_deg=360, length_mm=63)
    femur: JointSpec = JointSpec(model="MX-106", min_deg=-120, max_deg=120, length_mm=127)
    tibia: JointSpec = JointSpec(model="MX-64", min_deg=-150, max_deg=150, length_mm=124)
    tarsus: JointSpec = JointSpec(model="MX-64", min_deg=-155, max_deg=170, length_mm=95)
    direction: JointSpec = JointSpec(model="MX-28", min_deg=-360, max_deg=360, length_mm=42)
    wheel: JointSpec = JointSpec(model="MX-28", endless=True, length_mm=33)

    def by_name(self, name: str) -> JointSpec:
        """The joint called ``name`` (one of :data:`whexar.robot.JOINT_NAMES`)."""
        spec: JointSpec = getattr(self, name)
        return spec

    def problems(self, at: str) -> list[Problem]:
        return [p for name in JOINT_NAMES for p in self.by_name(name).problems(f"{at}.{name}")]


class DHRow(Section):
    """One row of the Denavit–Hartenberg table (eq. 4.4–4.5, Table 5.3).

    The DH angle of the joint is ``theta_sign · q + theta_offset`` where q is
    the joint angle in the servo convention of Table 6.5 (positive femur lifts
    the leg; the tarsus keeps the last segment vertical at −90° − femur − tibia).
    """

    d_mm: Finite
    a_mm: Finite
    alpha_deg: Finite
    theta_offset_deg: Finite = 0.0
    theta_sign: Literal[1, -1] = 1


class DHSpec(Section):
    """DH table of the five positioning joints (Table 5.3).

    Table 5.3 gives d, a, α and the trochanter's +π/2. The femur's +90° and the
    sign flips of femur, tibia and tarsus map Table 6.5's joint convention onto
    these DH angles: with them FK reproduces every row of Table 6.5.
    """

    coxa: DHRow = DHRow(d_mm=0, a_mm=0, alpha_deg=90)
    trochanter: DHRow = DHRow(d_mm=65, a_mm=0, alpha_deg=90, theta_offset_deg=90)
    femur: DHRow = DHRow(d_mm=0, a_mm=127, alpha_deg=0, theta_offset_deg=90, theta_sign=-1)
    tibia: DHRow = DHRow(d_mm=0, a_mm=124, alpha_deg=0, theta_sign=-1)
    tarsus: DHRow = DHRow(d_mm=0, a_mm=95, alpha_deg=0, theta_sign=-1)

    def rows(self) -> tuple[DHRow, ...]:
        """The five rows in joint order."""
        return tuple(getattr(self, name) for name in POSITIONING_JOINTS)


# --------------------------------------------------------------------------- legs


def default_legs() -> tuple[LegSpec, ...]:
    # Coxa joints 300 mm apart along the body (5.2) and 74 mm from its axis
    # (Table 5.2, "Body 74 mm"); body frame x forward, y left, z up.
    xs = {"F": 300.0, "M": 0.0, "R": -300.0}
    return tuple(
        LegSpec(
            name=name,
            mount_mm=(xs[name[1]], -74.0 if name[0] == "R" else 74.0, 0.0),
            servo_ids=tuple(servo_id(name, joint) for joint in JOINT_NAMES),
        )
        for name in LEG_NAMES
    )


class LegSpec(Section):
    """One leg: where its coxa sits on the body and which servo drives each joint."""

    name: Literal["RF", "LF", "RM", "LM", "RR", "LR"]
    mount_mm: tuple[Finite, Finite, Finite]
    """Coxa joint in the body frame (x forward, y left, z up)."""
    servo_ids: tuple[int, int, int, int, int, int, int]
    """Servo ID of each joint, coxa to wheel; default i = 7l + j + 1 (eq. 4.1)."""

    def problems(self, at: str) -> list[Problem]:
        found: list[Problem] = []
        lo, hi = 0, MAX_ID
        for j, sid in enumerate(self.servo_ids):
            if not lo <= sid <= hi:
                found.append(
                    Problem(
                        f"{at}.servo_ids[{j}]",
                        sid,
                        f"a Dynamixel ID in {lo}–{hi} ({JOINT_NAMES[j]} of {self.name})",
                    )
                )
        y = self.mount_mm[1]
        if (self.name[0] == "R" and y >= 0) or (self.name[0] == "L" and y <= 0):
            side = "right (y < 0)" if self.name[0] == "R" else "left (y > 0)"
            found.append(
                Problem(f"{at}.mount_mm[1]", y, f"{self.name} is a {side} leg in the body frame")
            )
        return found


def check_legs(legs: Sequence[LegSpec], at: str) -> list[Problem]:
    found: list[Problem] = []
    names = tuple(leg.name for leg in legs)
    if names != LEG_NAMES:
        found.append(
            Problem(at, list(names), f"exactly six legs in the order {', '.join(LEG_NAMES)}")
        )
    seen: dict[int, str] = {}
    for i, leg in enumerate(legs):
        found.extend(leg.problems(f"{at}[{i}]"))
        for j, sid in enumerate(leg.servo_ids):
            here = f"{at}[{i}].servo_ids[{j}]"
            if sid in seen:
                found.append(
                    Problem(
                        here,
                        sid,
                        f"servo IDs must be unique; {sid} is already used by {seen[sid]}",
                    )
                )
            else:
                seen[sid] = f"{here} ({leg.name} {JOINT_NAMES[j]})"
    return found
