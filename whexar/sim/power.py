"""What feeds WHexaR's 12 V line, and what the line carries: the supply current.

Theory of operation
-------------------
The thesis's current (Table 6.7, eq. 6.5) is the supply's, measured by an
ACS712 Hall sensor on the 12 V line (6.8). Three things draw from that line:

* each servo's H-bridge. Averaged over a PWM period, an ideal bridge at duty
  d draws d·I from the supply, I the winding current (τ/kt, what Present
  Current reports). A braking motor (d·I < 0) gives current back: the servos
  share the line, so a braking servo feeds the others, and only the line's
  net motor current counts; a net surplus is lost (a switching bench supply
  cannot sink current);
* each servo's own electronics, its standby current (:data:`STANDBY_A`),
  whether its torque is on or not;
* the control electronics on the 5 V regulator (:data:`ELECTRONICS_W`,
  through :data:`CONVERTER_EFFICIENCY`), drawing more current as the line's
  voltage falls.

The line is fed either by the bench supply of the experiments
(:class:`BenchSupply`: 12 V whatever the load, 5.3.1) or by the robot's 3S
Li-Po (:class:`LiPoBattery`): its open-circuit voltage follows its state of
charge (:data:`LIPO_CELL_OCV`) and sags by the current times its internal
resistance. The servos see the line's voltage: their torque (kt·V/R) and
their Present Input Voltage register follow it, and below their Min Voltage
Limit (9.5 V by default) they raise Input Voltage Error, as in a brownout.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Final

STANDBY_A: Final = 0.1
"""A servo's standby current, A: 100 mA for the MX-28, MX-64 and MX-106 (2.0) (ROBOTIS
e-manual, specifications, "Standby Current"); 5.3.1 takes the same 0.1 A."""
ELECTRONICS_W: Final = 5.0
"""The control electronics and sensors on the 5 V line, W: "about 5 W (1 A at 5 V)"
(5.3.1)."""
CONVERTER_EFFICIENCY: Final = 0.80
"""Efficiency of the 5 V step-down regulator on the 12 V line. The thesis names no part
(5.3.1, Fig. 5.6: "a voltage regulator"); 80 % is the typical efficiency of a common
buck regulator at 12 V in, 5 V out (TI LM2596-5.0 data sheet, SNVS124, electrical
characteristics: η = 80 % at V_IN = 12 V, I_LOAD = 3 A)."""
BENCH_VOLTS: Final = 12.0
"""The switching bench supply of the experiments (5.3.1, 6.8): 12 V."""

LIPO_CELLS: Final = 3
"""The robot's battery is a three-cell Li-Po, 11.1 V nominal (5.3.1)."""
LIPO_CAPACITY_AH: Final = 6.0
"""Its capacity (5.3.1, eq. 5.2: 6 Ah)."""
LIPO_CELL_RESISTANCE_OHM: Final = 0.004
"""Internal resistance per cell, Ω: healthy high-capacity RC Li-Po cells measure 1–4 mΩ
(rchelicopterfun.com, "LiPo Internal Resistance", 2023); the upper end, for a pack that
is not new."""
LIPO_CELL_OCV: Final = (
    (0.00, 3.27),
    (0.05, 3.61),
    (0.10, 3.69),
    (0.15, 3.71),
    (0.20, 3.73),
    (0.25, 3.75),
    (0.30, 3.77),
    (0.35, 3.79),
    (0.40, 3.80),
    (0.45, 3.82),
    (0.50, 3.84),
    (0.55, 3.85),
    (0.60, 3.87),
    (0.65, 3.91),
    (0.70, 3.95),
    (0.75, 3.98),
    (0.80, 4.02),
    (0.85, 4.08),
    (0.90, 4.11),
    (0.95, 4.15),
    (1.00, 4.20),
)
"""A Li-Po cell's resting voltage against its state of charge (AMPOW, "LiPo voltage
chart", blog.ampow.com/lipo-voltage-chart): 4.20 V full, 3.27 V empty, so a 3S pack spans
12.6 V to 9.8 V, the thesis's "12.6 V" full and "9.6–9.9 V" lowest (5.3.1). Drawn past
empty, the cell falls on along the chart's last slope (the knee of the discharge
curve)."""


def cell_ocv(charge: float) -> float:
    """A cell's open-circuit voltage at state of charge ``charge`` (0–1; below 0: past
    empty, extrapolated along the last segment, never below 0 V), V."""
    table = LIPO_CELL_OCV
    if charge >= table[-1][0]:
        return table[-1][1]
    if charge <= table[0][0]:
        (s0, v0), (s1, v1) = table[0], table[1]
        return max(0.0, v0 + (charge - s0) * (v1 - v0) / (s1 - s0))
    k = bisect.bisect_right([s for s, _ in table], charge)
    (s0, v0), (s1, v1) = table[k - 1], table[k]
    return v0 + (charge - s0) * (v1 - v0) / (s1 - s0)


@dataclass
class BenchSupply:
    """The bench supply: a fixed voltage whatever the load."""

    volts: float = BENCH_VOLTS
    drawn_c: float = 0.0
    """Charge drawn so far, C."""
    energy_j: float = 0.0
    """Energy delivered so far, J."""

    @property
    def terminal_volts(self) -> float:
        """The line's voltage now, V."""
        return self.volts

    def draw(self, amps: float, dt: float) -> None:
        """Deliver ``amps`` for ``dt`` seconds at the present voltage."""
        self.energy_j += self.terminal_volts * amps * dt
        self.drawn_c += amps * dt

    @property
    def state_of_charge(self) -> float | None:
        """None: a bench supply does not run out."""
        return None


@dataclass
class LiPoBattery:
    """A Li-Po pack: its voltage follows its charge and sags under load (module docstring)."""

    capacity_ah: float = LIPO_CAPACITY_AH
    cells: int = LIPO_CELLS
    cell_resistance_ohm: float = LIPO_CELL_RESISTANCE_OHM
    initial_charge: float = 1.0
    """State of charge at the start, 0–1."""
    drawn_c: float = 0.0
    energy_j: float = 0.0
    amps: float = 0.0
    """The current it delivered over the last interval, A (its sag)."""
    empty_at_s: float | None = field(default=None)
    """When its state of charge first reached 0 (None: not yet)."""
    _t: float = 0.0

    @property
    def state_of_charge(self) -> float:
        """1 full, 0 empty; negative when drawn past empty."""
        return self.initial_charge - self.drawn_c / (self.capacity_ah * 3600.0)

    @property
    def open_circuit_volts(self) -> float:
        return self.cells * cell_ocv(self.state_of_charge)

    @property
    def terminal_volts(self) -> float:
        """Open-circuit voltage less the sag across the internal resistance, V (≥ 0)."""
        sag = self.amps * self.cells * self.cell_resistance_ohm
        return max(0.0, self.open_circuit_volts - sag)

    def draw(self, amps: float, dt: float) -> None:
        """Deliver ``amps`` for ``dt`` seconds: the charge leaves, the voltage sags."""
        self.amps = amps
        self.energy_j += self.terminal_volts * amps * dt
        self.drawn_c += amps * dt
        self._t += dt
        if self.empty_at_s is None and self.state_of_charge <= 0.0:
            self.empty_at_s = self._t


Supply = BenchSupply | LiPoBattery
"""What feeds the 12 V line."""


def electronics_amps(volts: float) -> float:
    """The 5 V electronics' current on the line at ``volts``, A (0 with no voltage)."""
    return ELECTRONICS_W / (CONVERTER_EFFICIENCY * volts) if volts > 0 else 0.0


def supply_amps(motor_amps: float, servos: int, volts: float) -> float:
    """The line's current: the bridges' net draw ``motor_amps`` (Σ duty × winding current;
    a net surplus is lost, not given back), ``servos`` standby currents and the
    electronics, A."""
    return max(0.0, motor_amps) + servos * STANDBY_A + electronics_amps(volts)


__all__ = [
    "BENCH_VOLTS",
    "CONVERTER_EFFICIENCY",
    "ELECTRONICS_W",
    "LIPO_CAPACITY_AH",
    "LIPO_CELLS",
    "LIPO_CELL_OCV",
    "LIPO_CELL_RESISTANCE_OHM",
    "STANDBY_A",
    "BenchSupply",
    "LiPoBattery",
    "Supply",
    "cell_ocv",
    "electronics_amps",
    "supply_amps",
]
