"""Gear backlash as play in the drive: the encoder reads the horn (whexar.sim.world.gear_play)."""

from __future__ import annotations

import math

import numpy as np

from whexar.sim.world import gear_play

HALF = np.array([math.radians(10 / 60)])  # 20 arcmin of play: ±10
H = 0.001


def test_a_steady_load_keeps_a_flank_engaged_and_meets_no_play() -> None:
    # The motor pushes +; once at the flank every step passes its torque whole.
    play = np.zeros(1)
    passed = []
    for _ in range(50):
        out, play = gear_play(np.array([1.5]), np.array([2.0]), np.zeros(1), play, HALF, H)
        passed.append(float(out[0]))
    assert play[0] == HALF[0]
    assert passed[-1] == 1.5
    # From the middle of the play the flank is 2.9 mrad away; 2 mrad a step at 2 rad/s.
    assert passed[0] == 0.0
    assert all(p == 1.5 for p in passed[1:])


def test_a_torque_that_turns_round_is_lost_while_the_motor_crosses_the_play() -> None:
    play = HALF.copy()  # engaged on the + flank
    crossing = []
    for _ in range(20):
        out, play = gear_play(np.array([-0.8]), np.array([-1.0]), np.zeros(1), play, HALF, H)
        crossing.append(float(out[0]))
    # 5.8 mrad at 1 mrad a step: 5 steps with nothing through, then the − flank.
    assert crossing[:5] == [0.0] * 5
    assert crossing[5:] == [-0.8] * 15
    assert play[0] == -HALF[0]


def test_a_horn_pushed_ahead_of_its_motor_runs_through_the_play_freely() -> None:
    # A load drives the horn at 3 rad/s while the motor, pushing +, turns at 1: the horn
    # leaves the flank, and the motor's torque does not reach it until it catches up.
    out, play = gear_play(np.array([0.5]), np.array([1.0]), np.array([3.0]), HALF, HALF, H)
    assert out[0] == 0.0
    assert play[0] < HALF[0]


def test_without_play_nothing_is_lost() -> None:
    zero = np.zeros(3)
    tau = np.array([0.3, -0.2, 0.0])
    out, _ = gear_play(tau, np.array([1.0, -1.0, 0.0]), zero, zero, zero, H)
    assert list(out) == list(tau)
