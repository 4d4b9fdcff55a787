"""What the motors inside WHexaR's servos are, and how their firmware drives them.

The model is Rhoban's "BAM: Better Actuator Models" (Duclusaud and Passault, ICRA 2025;
github.com/Rhoban/bam), identified on MX-64 and MX-106 servos on a pendulum bench. The
firmware turns the position error into a PWM duty cycle, the H-bridge puts duty × supply
on the motor, and the motor gives

    τ = kt·V/R − kt²·ω/R        (back-EMF through the winding resistance)

at the output shaft (kt in N·m/A at the output, ω the joint's speed), less friction
(Coulomb and viscous, model "m1"), with the rotor's reflected inertia as armature.
Present Current is τ / kt: the motor current.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Final, Literal

from whexar.bus.control_table import TICKS_PER_REV


@dataclass(frozen=True)
class MotorModel:
    """One servo model's motor at its output shaft, SI units."""

    kt: float
    """Torque constant, N·m/A (= back-EMF constant, V·s/rad)."""
    resistance: float
    """Winding resistance, Ω."""
    armature: float
    """Reflected rotor inertia, kg·m²."""
    coulomb: float
    """Coulomb friction, N·m."""
    viscous: float
    """Viscous friction, N·m·s/rad."""
    source: str

    def stall_torque(self, volts: float) -> float:
        """τ at ω = 0 and full voltage: kt·V/R."""
        return self.kt * volts / self.resistance

    def no_load_speed(self, volts: float) -> float:
        """ω where the motor's torque falls to its Coulomb friction, rad/s."""
        return (volts - self.coulomb * self.resistance / self.kt) / self.kt


MOTORS: Final[dict[str, MotorModel]] = {
    # BAM, bam/params/mx64/m1.json and mx106/m1.json (model m1: Coulomb + viscous).
    "MX-64": MotorModel(
        kt=1.6224667906987444,
        resistance=3.949433673232461,
        armature=0.011951238325312509,
        coulomb=0.09038677246291783,
        viscous=0.011691602145974832,
        source="BAM (ICRA 2025), bam/params/mx64/m1.json",
    ),
    "MX-106": MotorModel(
        kt=2.1913757006745245,
        resistance=2.9649903987776804,
        armature=0.026609234235148084,
        coulomb=0.10352026623606064,
        viscous=0.03520238029013507,
        source="BAM (ICRA 2025), bam/params/mx106/m1.json",
    ),
}
"""The motor of each servo model the configuration may name (:data:`DEFAULT_MOTORS`)."""


@dataclass(frozen=True)
class Datasheet:
    """A servo model's line at 12 V: stall torque and no-load speed (ROBOTIS e-manual)."""

    stall_torque_nm: float
    no_load_rpm: float
    volts: float = 12.0

    @property
    def no_load_rad_s(self) -> float:
        return self.no_load_rpm * 2 * math.pi / 60


DATASHEETS: Final[dict[str, Datasheet]] = {
    # ROBOTIS e-manual, MX-28 (2.0), MX-64 (2.0), MX-106 (2.0), "Specifications" (and
    # Table 5.1 for the stall torques): at 12 V.
    "MX-28": Datasheet(2.5, 55.0),
    "MX-64": Datasheet(6.0, 63.0),
    "MX-106": Datasheet(8.4, 45.0),
}


def from_datasheet(sheet: Datasheet, friction_of: MotorModel, source: str) -> MotorModel:
    """The motor whose line at the sheet's voltage runs through its stall torque and no-load
    speed, with the friction and armature of ``friction_of``.

    τ(ω) = kt·V/R − kt²·ω/R − Coulomb: stall τs = kt·V/R, and τ = 0 at
    ω0 = V·(1 − c/τs)/kt, so kt = V·(1 − c/τs)/ω0 and R = kt·V/τs."""
    v, tau = sheet.volts, sheet.stall_torque_nm
    kt = v * (1 - friction_of.coulomb / tau) / sheet.no_load_rad_s
    return replace(friction_of, kt=kt, resistance=kt * v / tau, source=source)


# BAM did not identify the MX-28: its line is its datasheet's (stall 2.5 N·m, 55 rpm at
# 12 V). Armature and friction are the MX-64's scaled by stall torque (2.5/6.0): an
# estimate, not a measurement.
MOTORS["MX-28"] = from_datasheet(
    DATASHEETS["MX-28"],
    replace(
        MOTORS["MX-64"],
        armature=MOTORS["MX-64"].armature * 2.5 / 6.0,
        coulomb=MOTORS["MX-64"].coulomb * 2.5 / 6.0,
        viscous=MOTORS["MX-64"].viscous * 2.5 / 6.0,
    ),
    "MX-28 datasheet (2.5 N·m stall, 55 rpm at 12 V); armature and friction scaled "
    "from BAM's MX-64 by stall torque (estimate)",
)

DATASHEET_MOTORS: Final[dict[str, MotorModel]] = {
    name: from_datasheet(
        DATASHEETS[name],
        motor,
        f"{name} datasheet line at 12 V; armature and friction: {motor.source}",
    )
    for name, motor in MOTORS.items()
}
"""Every motor on its datasheet's line at 12 V, with BAM's friction and armature."""

MotorSource = Literal["bam", "datasheet"]
"""Which motors a run uses: BAM's identification (the MX-28 from its datasheet), or every
model on its datasheet's line (docs/sim.md weighs the two)."""
DEFAULT_MOTORS: Final[MotorSource] = "bam"


def motors(source: MotorSource = DEFAULT_MOTORS) -> dict[str, MotorModel]:
    """The motor of each servo model for ``source``."""
    return dict(MOTORS if source == "bam" else DATASHEET_MOTORS)


MAX_DUTY: Final = 0.9625
"""Largest duty cycle the MX firmware outputs (BAM, bam/dynamixel/actuator.py: measured
with an oscilloscope)."""
PWM_LIMIT: Final = 885
"""PWM Limit (36) of the MX (2.0) servos: 885 = 100 % duty (e-manual)."""
KPP_DIVISOR: Final = 128
"""Position P Gain (84) / 128 = KPP (e-manual, MX (2.0), "Position PID Gain")."""
TICKS_PER_RAD: Final = TICKS_PER_REV / (2 * math.pi)


def position_duty_per_rad(p_gain: int) -> float:
    """Duty cycle per radian of position error for Position P Gain (84) = ``p_gain``.

    Protocol 2.0 firmware: PWM = KPP · error in ticks, KPP = P/128, full duty at the PWM
    Limit (885), the mapping BAM uses for the XL330 (bam/dynamixel/actuator.py). At the
    default P = 850 this is 4.89 per rad; BAM's MX fit under Protocol 1.0 (error gain 0.158
    × P 32) is 5.06 per rad: the two agree within 4 %.
    """
    return p_gain / KPP_DIVISOR * TICKS_PER_RAD / PWM_LIMIT


__all__ = [
    "DATASHEETS",
    "DATASHEET_MOTORS",
    "DEFAULT_MOTORS",
    "KPP_DIVISOR",
    "MAX_DUTY",
    "MOTORS",
    "PWM_LIMIT",
    "Datasheet",
    "MotorModel",
    "MotorSource",
    "from_datasheet",
    "motors",
    "position_duty_per_rad",
]
