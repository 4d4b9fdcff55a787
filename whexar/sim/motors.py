"""What the motors inside WHexaR's servos are, and how their firmware drives them.

The model is Rhoban's "BAM: Better Actuator Models" (Duclusaud and Passault, ICRA 2025;
github.com/Rhoban/bam), identified on MX-64 and MX-106 servos on a pendulum bench. The
firmware turns the position error into a PWM duty cycle, the H-bridge puts duty × supply
on the motor, and the motor gives

    τ = kt·V/R − kt²·ω/R        (back-EMF through the winding resistance)

at the output shaft (kt in N·m/A at the output, ω the joint's speed), less the gearbox's
friction, with the rotor's reflected inertia as armature. Present Current is τ / kt: the
motor current.

The friction is BAM's model m6 by default (:class:`GearFriction`): on top of Coulomb and
viscous friction, a budget that grows with the torque the gears carry, more when the load
drives the motor than when the motor drives the load, and more at rest (Stribeck). An MX
servo's gears so hold a load well beyond the torque its motor makes, which m1 (Coulomb
and viscous only) leaves out. docs/sim.md, "Motors", weighs the two.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Final, Literal

from whexar.bus.control_table import TICKS_PER_REV


@dataclass(frozen=True)
class GearFriction:
    """BAM's friction budget of model m6 beyond Coulomb and viscous (bam/model.py,
    ``compute_frictions``; docs/theory/models.rst). With τm the motor's torque and τe the
    external torque on the joint, the joint does not move while the net torque is within

        τf = Kc + Kv·|ω| + |Ke·τe − Km·τm|
             + s(ω)·(Kcs + |Kes·τe − Kms·τm| + Q),   s(ω) = exp(−|ω/ωs|^α),

    Q = Keq·τe² when |τm| > |τe|, else Kmq·τm², and only when τe opposes τm. Kc and Kv
    are the motor's ``coulomb`` and ``viscous``; the rest is here, named as in BAM's
    parameter files."""

    friction_stribeck: float
    """Kcs, N·m: the extra Coulomb friction at rest."""
    load_friction_motor: float
    """Km: friction per N·m of the motor's torque."""
    load_friction_external: float
    """Ke: friction per N·m of the external torque."""
    load_friction_motor_stribeck: float
    load_friction_external_stribeck: float
    load_friction_motor_quad: float
    """Kmq, 1/(N·m)."""
    load_friction_external_quad: float
    dtheta_stribeck: float
    """ωs, rad/s: the speed over which the Stribeck terms fade."""
    alpha: float


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
    gear: GearFriction | None = None
    """The gears' load-dependent friction (model m6); ``None``: Coulomb and viscous only."""

    def stall_torque(self, volts: float) -> float:
        """The motor's τ at ω = 0 and full voltage: kt·V/R."""
        return self.kt * volts / self.resistance

    def lifted_torque(self, volts: float) -> float:
        """The largest load the servo lifts at full voltage, just moving: its datasheet's
        stall torque. The motor's kt·V/R less what the gears take, (1 − Km)·kt·V/R − Kc,
        against the load and its own share (1 + Ke); m1 has no such share."""
        if self.gear is None:
            return self.stall_torque(volts)
        g = self.gear
        driven = self.stall_torque(volts) * (1 - g.load_friction_motor) - self.coulomb
        return driven / (1 + g.load_friction_external)

    def no_load_speed(self, volts: float) -> float:
        """ω where the motor's torque falls to its friction unloaded (viscous left out),
        rad/s: (V − Kc·R/(kt·(1 − Km)))/kt."""
        share = 1 - self.gear.load_friction_motor if self.gear else 1.0
        return (volts - self.coulomb * self.resistance / (self.kt * share)) / self.kt


M1_MOTORS: Final[dict[str, MotorModel]] = {
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
"""BAM's model m1 of each servo model: Coulomb and viscous friction only."""

MOTORS: Final[dict[str, MotorModel]] = {
    # BAM, bam/params/mx64/m6.json and mx106/m6.json (model m6: Stribeck, load-dependent,
    # directional, quadratic), identified on the same bench as m1.
    "MX-64": MotorModel(
        kt=1.6016832750318712,
        resistance=2.3164043271967447,
        armature=0.012265893049213158,
        coulomb=6.217919698787649e-07,
        viscous=0.02533701181690149,
        source="BAM (ICRA 2025), bam/params/mx64/m6.json",
        gear=GearFriction(
            friction_stribeck=0.12269525980968875,
            load_friction_motor=0.3114720375111298,
            load_friction_external=2.0462014258729542e-08,
            load_friction_motor_stribeck=0.18774381222411038,
            load_friction_external_stribeck=0.014065853481003015,
            load_friction_motor_quad=0.006908512882777861,
            load_friction_external_quad=0.009999980627672081,
            dtheta_stribeck=2.575277366960116,
            alpha=0.8409018066017007,
        ),
    ),
    "MX-106": MotorModel(
        kt=2.209828156174588,
        resistance=2.033661749312417,
        armature=0.026016184370993383,
        coulomb=1.0232526438525893e-05,
        viscous=0.05071566473605552,
        source="BAM (ICRA 2025), bam/params/mx106/m6.json",
        gear=GearFriction(
            friction_stribeck=0.12195409579603411,
            load_friction_motor=0.19800553725822115,
            load_friction_external=0.022215529897348624,
            load_friction_motor_stribeck=0.19859970173941574,
            load_friction_external_stribeck=0.08710328264676681,
            load_friction_motor_quad=0.009999930103371748,
            load_friction_external_quad=7.326919843140997e-05,
            dtheta_stribeck=1.7463251741328727,
            alpha=1.142827788004191,
        ),
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
# m1's line with m1's friction: a line through the datasheet's two points has no room for
# load-dependent friction, which would take its share of the stall torque.
M1_MOTORS["MX-28"] = MOTORS["MX-28"] = from_datasheet(
    DATASHEETS["MX-28"],
    replace(
        M1_MOTORS["MX-64"],
        armature=M1_MOTORS["MX-64"].armature * 2.5 / 6.0,
        coulomb=M1_MOTORS["MX-64"].coulomb * 2.5 / 6.0,
        viscous=M1_MOTORS["MX-64"].viscous * 2.5 / 6.0,
    ),
    "MX-28 datasheet (2.5 N·m stall, 55 rpm at 12 V); armature and friction scaled "
    "from BAM's MX-64 (m1) by stall torque (estimate)",
)

DATASHEET_MOTORS: Final[dict[str, MotorModel]] = {
    name: from_datasheet(
        DATASHEETS[name],
        motor,
        f"{name} datasheet line at 12 V; armature and friction: {motor.source}",
    )
    for name, motor in M1_MOTORS.items()
}
"""Every motor on its datasheet's line at 12 V, with BAM's m1 friction and armature."""

MotorSource = Literal["bam", "bam-m1", "datasheet"]
"""Which motors a run uses: BAM's identification with its gearbox friction (model m6; the
MX-28, which BAM did not identify, from its datasheet), BAM's m1 (Coulomb and viscous
friction only), or every model on its datasheet's line with m1's friction (docs/sim.md
weighs them)."""
DEFAULT_MOTORS: Final[MotorSource] = "bam"


def motors(source: MotorSource = DEFAULT_MOTORS) -> dict[str, MotorModel]:
    """The motor of each servo model for ``source``."""
    table = {"bam": MOTORS, "bam-m1": M1_MOTORS, "datasheet": DATASHEET_MOTORS}[source]
    return dict(table)


MAX_DUTY: Final = 0.9625
"""Largest duty cycle the MX firmware outputs (BAM, bam/dynamixel/actuator.py: measured
with an oscilloscope)."""
PWM_LIMIT: Final = 885
"""PWM Limit (36) of the MX (2.0) servos: 885 = 100 % duty (e-manual)."""
KPP_DIVISOR: Final = 128
"""Position P Gain (84) / 128 = KPP (e-manual, MX (2.0), "Position PID Gain")."""
TICKS_PER_RAD: Final = TICKS_PER_REV / (2 * math.pi)
KPD_DIVISOR: Final = 16
KPI_DIVISOR: Final = 65536
"""Position D Gain (80) / 16 = KPD, Position I Gain (82) / 65 536 = KPI (e-manual, MX (2.0),
"Position PID Gain")."""
CONTROL_PERIOD_S: Final = 0.001
"""The firmware's control period (1 kHz), the time base of the velocity loop's integral
and the position loop's I and D terms. The e-manual gives the gains' scales, not their
time base: an **estimate**."""


def position_duty_per_rad(p_gain: int) -> float:
    """Duty cycle per radian of position error for Position P Gain (84) = ``p_gain``.

    Protocol 2.0 firmware: PWM = KPP · error in ticks, KPP = P/128, full duty at the PWM
    Limit (885), the mapping BAM uses for the XL330 (bam/dynamixel/actuator.py). At the
    default P = 850 this is 4.89 per rad; BAM's MX fit under Protocol 1.0 (error gain 0.158
    × P 32) is 5.06 per rad: the two agree within 4 %.
    """
    return p_gain / KPP_DIVISOR * TICKS_PER_RAD / PWM_LIMIT


def position_id_duty(i_gain: int, d_gain: int) -> tuple[float, float]:
    """Duty per radian·period of summed error (I) and per rad/s of the error's rate (D)
    for Position I Gain (82) = ``i_gain`` and D Gain (80) = ``d_gain``.

    PWM = KPI · Σ error in ticks, one term a control period, + KPD · the error's change
    in ticks over a period (:data:`CONTROL_PERIOD_S`). Both are 0 at the initial gains.
    """
    ki = i_gain / KPI_DIVISOR * TICKS_PER_RAD / PWM_LIMIT
    kd = d_gain / KPD_DIVISOR * TICKS_PER_RAD * CONTROL_PERIOD_S / PWM_LIMIT
    return ki, kd


__all__ = [
    "CONTROL_PERIOD_S",
    "DATASHEETS",
    "DATASHEET_MOTORS",
    "DEFAULT_MOTORS",
    "KPD_DIVISOR",
    "KPI_DIVISOR",
    "KPP_DIVISOR",
    "M1_MOTORS",
    "MAX_DUTY",
    "MOTORS",
    "PWM_LIMIT",
    "Datasheet",
    "GearFriction",
    "MotorModel",
    "MotorSource",
    "from_datasheet",
    "motors",
    "position_duty_per_rad",
    "position_id_duty",
]
