"""The supply: what the servos draw from the 12 V line (thesis 5.3.1, 6.8, Table 6.7), the
cost of transport on it, the motors against their datasheets, and the 3S Li-Po."""

from __future__ import annotations

import math

import pytest

from whexar.bus.control_table import CENTER_TICKS
from whexar.bus.emulator.chain import ServoChain
from whexar.campaign.experiments.metrics import cost_of_transport
from whexar.config import RobotConfig
from whexar.sim.model import load_model
from whexar.sim.motors import (
    DATASHEET_MOTORS,
    DATASHEETS,
    M1_MOTORS,
    MOTORS,
    TICKS_PER_RAD,
    position_duty_per_rad,
)
from whexar.sim.power import (
    CONVERTER_EFFICIENCY,
    ELECTRONICS_W,
    STANDBY_A,
    BenchSupply,
    LiPoBattery,
    Supply,
    cell_ocv,
)
from whexar.sim.run import seated_angles
from whexar.sim.world import SimWorld

CFG = RobotConfig()
FEMUR = 3  # RF's femur (eq. 4.1), an MX-106
SERVOS = 42


def _holding(duty: float, supply: Supply) -> tuple[SimWorld, float]:
    """The robot in the air without gravity, every servo holding; RF's femur is held fast
    and told to go ``duty`` / KPP further: it pushes at that duty against the stop.
    Returns the world and the femur's winding current after 0.5 s."""
    model = load_model(CFG)
    model.opt.gravity[:] = 0.0
    model.dof_armature[0:6] = 1e9  # the body does not move
    chain = ServoChain.for_models(CFG.servos(), baudrate=CFG.bus.baudrate)
    world = SimWorld(model, chain, cfg=CFG, supply=supply)
    world.set_pose(seated_angles(CFG), base_xyz=(0.0, 0.0, 1.0))
    joint = world.by_servo[FEMUR]
    model.dof_armature[joint.dadr] = 1e9  # the femur cannot turn: a stall at that duty
    for servo in chain.servos.values():
        servo.set_register("goal_position", round(servo.position))
        servo.set_register("torque_enable", 1)
    error = duty / position_duty_per_rad(850)
    goal = world.q[joint.index] + error
    chain.servos[FEMUR].set_register("goal_position", round(goal * TICKS_PER_RAD + CENTER_TICKS))
    for k in range(1, 51):
        for s in chain.servos.values():
            s.advance(k * 0.01)
    return world, float(world._torque[joint.index]) / joint.kt


def test_a_servo_holding_at_duty_d_draws_d_times_its_winding_current() -> None:
    world, amps = _holding(0.5, BenchSupply())
    motor = MOTORS["MX-106"]
    assert amps == pytest.approx(0.5 * 12.0 / motor.resistance, rel=0.02)  # d·V/R at stall
    # The line: d × I of the femur, 42 standby currents, 5 W through the regulator.
    extra = SERVOS * STANDBY_A + ELECTRONICS_W / (CONVERTER_EFFICIENCY * 12.0)
    assert world.supply_a == pytest.approx(0.5 * amps + extra, rel=0.02)
    assert world.supply_a - extra < 0.6 * amps  # not the winding current itself
    # Present Current stays the winding current (Fig. 6.8).
    amps_read = world.chain.servos[FEMUR].register_value("present_current") * 3.36e-3
    assert amps_read == pytest.approx(amps, abs=0.01)


def test_the_cost_of_transport_of_table_6_7() -> None:
    # Tripod on the flat: 12 V × 5.22 A at 0.12 m/s, 8.8 kg (6.8.1): CoT 6.05.
    assert cost_of_transport(12.0 * 5.22, 8.8, 0.12) == pytest.approx(6.05, abs=0.005)
    # Wheels on the flat: 3.47 A at 0.20 m/s: 2.41.
    assert cost_of_transport(12.0 * 3.47, 8.8, 0.20) == pytest.approx(2.41, abs=0.005)


@pytest.mark.parametrize("name", sorted(DATASHEETS))
def test_the_motors_against_their_datasheets(name: str) -> None:
    """The datasheet motors lie on their datasheet's line within 0.5 %; BAM's
    identifications within 25 % (docs/sim.md): m6 (the default) lifts MX-64 −5 %,
    no-load +14 %, MX-106 +22 %, +15 %; m1 MX-64 −18 %, +10 %, MX-106 +6 %, +15 %. The
    MX-28, which BAM did not measure, lies on its datasheet."""
    sheet = DATASHEETS[name]
    ds = DATASHEET_MOTORS[name]
    assert ds.stall_torque(12.0) == pytest.approx(sheet.stall_torque_nm, rel=0.005)
    assert ds.no_load_speed(12.0) == pytest.approx(sheet.no_load_rad_s, rel=0.005)
    tolerance = 0.005 if name == "MX-28" else 0.25
    for bam in (MOTORS[name], M1_MOTORS[name]):
        assert bam.lifted_torque(12.0) == pytest.approx(sheet.stall_torque_nm, rel=tolerance)
        assert bam.no_load_speed(12.0) == pytest.approx(sheet.no_load_rad_s, rel=tolerance)


def test_the_lipo_curve_spans_the_thesis_voltages() -> None:
    # 3S: 12.6 V full, 9.6–9.9 V at the lowest (5.3.1).
    assert 3 * cell_ocv(1.0) == pytest.approx(12.6)
    assert 9.6 <= 3 * cell_ocv(0.0) <= 9.9
    assert cell_ocv(0.5) < cell_ocv(0.6)
    assert 0.0 <= cell_ocv(-1.0) < cell_ocv(-0.01) < cell_ocv(0.0)
    pack = LiPoBattery(initial_charge=0.5)
    rest = pack.terminal_volts
    pack.draw(10.0, 1.0)
    assert rest - pack.terminal_volts == pytest.approx(10.0 * 3 * 0.004, rel=0.05)


def test_on_a_battery_the_servos_see_its_sagging_voltage() -> None:
    battery = LiPoBattery(initial_charge=0.5)
    world, amps = _holding(0.9, battery)
    volts = battery.terminal_volts
    assert volts < battery.open_circuit_volts  # sagged under the line's current
    assert volts == pytest.approx(battery.open_circuit_volts - world.supply_a * 3 * 0.004, abs=1e-6)
    servo = world.chain.servos[FEMUR]
    assert servo.input_voltage_v == volts
    # Present Input Voltage in 0.1 V (e-manual), and the torque follows the voltage.
    assert servo.register_value("present_input_voltage") == round(volts / 0.1)
    assert amps == pytest.approx(0.9 * volts / MOTORS["MX-106"].resistance, rel=0.02)


def test_a_small_battery_runs_empty_and_the_servos_report_low_supply() -> None:
    """Standing up on a 4 mAh pack: it runs out within a second or two; the line falls
    below the servos' Min Voltage Limit (9.5 V) and the runtime hears Input Voltage Error."""
    from whexar.actors.messages import SupplyLow
    from whexar.sim.run import simulate

    battery = LiPoBattery(capacity_ah=0.004)
    result = simulate(duration=3.0, supply=battery)
    assert battery.empty_at_s is not None
    assert battery.empty_at_s < 3.0
    assert battery.terminal_volts < 9.5
    assert result.summary()["battery_state_of_charge"] < 0.0
    volts = [s.supply_v for s in result.samples]
    assert volts[0] > 12.0
    assert min(volts) < 9.5
    assert any(isinstance(e, SupplyLow) for e in result.events)
    assert math.isfinite(result.summary()["supply_energy_j"])
