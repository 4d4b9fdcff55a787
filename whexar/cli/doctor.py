"""``whexar doctor``: is the robot ready? Each check, what is wrong, and the fix."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from whexar.cli.common import Commands, print_json

MARKS = {"ok": "✓", "warn": "!", "fail": "✗", "skipped": "-"}
"""One mark per status at the start of a check's line."""


def _doctor(args: argparse.Namespace) -> int:
    from whexar.config import RobotConfig, load_config
    from whexar.doctor import Environment, ready, run_checks

    cfg = RobotConfig() if args.config is None else load_config(args.config)
    env = Environment(config=cfg, port=args.port, board_port=args.board_port)
    if args.imu == "fake":
        from whexar.sensors.imu_emulator import lsm9ds1_bus

        # The emulated LSM9DS1 that whexar run and whexar sim use where there is no robot.
        env = replace(env, open_i2c=lambda number: lsm9ds1_bus(number, cfg.imu.address))
    results = run_checks(env)
    if args.json:
        print_json({"ready": ready(results), "checks": [r.as_dict() for r in results]})
    else:
        width = max(len(r.name) for r in results)
        for r in results:
            print(f"{MARKS[r.status]} {r.name:<{width}}  {r.summary}")
            for line in r.details:
                print(f"    {line}")
            if r.fix:
                print(f"    fix: {r.fix}")
        print("ready" if ready(results) else "not ready")
    return 0 if ready(results) else 1


def add_commands(commands: Commands) -> None:
    """Add ``whexar doctor`` to the ``whexar`` command table."""
    doctor = commands.add_parser(
        "doctor",
        help="check that the robot is ready to run, and say how to fix what is not",
        description="Check, in order: the servo port and its permissions, the USB "
        "adapter's latency timer, the bus's baud rate, every configured servo (model, "
        "firmware, ID, and nothing else on the bus), their EEPROM against the "
        "configuration, supply voltage and temperatures, the sensor board (its frames "
        "and their rate), the IMU, free disk for "
        "recordings, Python and package versions. A check that needs a failed one is "
        "skipped. Exit status 0 when no check failed, 1 otherwise.",
    )
    doctor.add_argument(
        "--config", type=Path, default=None, metavar="FILE", help="robot configuration"
    )
    doctor.add_argument(
        "--port", default=None, metavar="DEVICE", help="servo port (default: [bus] port)"
    )
    doctor.add_argument(
        "--board-port",
        default=None,
        metavar="DEVICE",
        help="sensor board port (default: [sensor_board] port); whexar emulate --board "
        "names an emulated one",
    )
    doctor.add_argument(
        "--imu",
        choices=("i2c", "fake"),
        default="i2c",
        help="the IMU to check: the real /dev/i2c-N (default), or the emulated LSM9DS1 "
        "(with whexar emulate, to check a setup without a robot)",
    )
    doctor.add_argument("--json", action="store_true", help="print one JSON object")
    doctor.set_defaults(handler=_doctor)
