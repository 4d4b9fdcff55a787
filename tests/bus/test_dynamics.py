"""The motor seam: a servo's table drives any ServoDynamics, and reads what it reports."""

import math

from whexar.bus.control_table import MODELS
from whexar.bus.emulator.chain import ServoChain
from whexar.bus.emulator.dynamics import Drive, Motion, TrapezoidalProfile
from whexar.bus.emulator.servo import VirtualServo


class World:
    """Stands in for a physics world: remembers each order, puts the horn where it likes."""

    def __init__(self) -> None:
        self.orders: list[tuple[Drive, float]] = []

    def advance(self, motion: Motion, drive: Drive, dt: float) -> None:
        self.orders.append((drive, dt))
        motion.position = 1000.0  # a joint the world holds, whatever the goal
        motion.velocity = 0.0


def _write(servo: VirtualServo, name: str, value: int) -> None:
    reg = servo.model.register(name)
    assert servo.write(reg.address, reg.encode(value)) == 0


def test_a_servo_hands_its_orders_to_its_dynamics_and_reads_its_motion() -> None:
    servo = VirtualServo(1, MODELS["MX-64"])
    world = World()
    servo.dynamics = world
    _write(servo, "profile_velocity", 100)
    _write(servo, "torque_enable", 1)
    _write(servo, "goal_position", 3000)
    servo.advance(0.5)
    drive, dt = world.orders[-1]
    assert drive.torque
    assert drive.mode == 3
    assert drive.goal_position == 3000
    assert drive.profile_active
    assert math.isinf(drive.max_acceleration)  # Profile Acceleration 0: a step
    assert drive.max_velocity > 0
    assert dt == 0.5
    assert servo.register_value("present_position") == 1000
    servo.advance(0.5)  # no time passed: the world is not asked again
    assert len(world.orders) == 1


def test_the_default_dynamics_is_the_trapezoidal_profile() -> None:
    servo = VirtualServo(1, MODELS["MX-64"])
    assert isinstance(servo.dynamics, TrapezoidalProfile)
    _write(servo, "torque_enable", 1)
    _write(servo, "goal_position", 2148)  # 100 ticks from the centre
    servo.advance(10.0)
    assert servo.register_value("present_position") == 2148
    assert servo.register_value("moving") == 0


def test_without_torque_the_horn_stops_where_it_is() -> None:
    motion = Motion(position=10.0, velocity=5.0, acceleration=1.0)
    limp = Drive(
        torque=False,
        mode=3,
        goal_position=0,
        profile_active=False,
        goal_velocity=0.0,
        max_velocity=1.0,
        max_acceleration=1.0,
    )
    TrapezoidalProfile().advance(motion, limp, 1.0)
    assert motion == Motion(position=10.0, velocity=0.0, acceleration=0.0)


def test_a_chain_mover_moves_every_servo_at_once_and_the_firmware_still_supervises() -> None:
    """A physics world as the chain's mover: one call per transaction, each servo follows."""
    chain = ServoChain.for_models({1: "MX-64", 2: "MX-106"})
    calls: list[float] = []

    def mover(t: float) -> None:
        calls.append(t)
        for k, servo in enumerate(chain.servos.values()):
            servo.follow(t, 1000.0 + k, 0.0, 0.0)

    chain.mover = mover
    one = chain.servos[1]
    _write(one, "bus_watchdog", 5)  # 100 ms
    _write(one, "torque_enable", 1)
    _write(one, "goal_position", 1000)
    chain.advance(0.05)
    assert calls == [0.05]
    assert [s.register_value("present_position") for s in chain.servos.values()] == [1000, 1001]
    assert one.register_value("moving_status") & 1  # in position: the profile ended
    chain.advance(0.2)  # nothing heard for 200 ms: the watchdog still trips
    assert one.register_value("bus_watchdog") == -1  # the watchdog error (e-manual)
