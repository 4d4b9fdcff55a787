"""``whexar model``: write the robot's simulation model (MJCF) or its URDF.

``whexar model --mjcf [--terrain NAME] [--wheel SHAPE]`` prints the MuJoCo model of
:func:`whexar.sim.model.build_mjcf`; ``whexar model --urdf`` the URDF of
:func:`whexar.sim.urdf.build_urdf` (for Foxglove or RViz). ``-o FILE`` writes a file
instead of standard output; ``--config`` takes a robot configuration instead of the
thesis robot. An unknown terrain is bad input (exit 2, with the known names).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from whexar.cli.common import Commands
from whexar.errors import UsageError


def _model(args: argparse.Namespace) -> int:
    from whexar.config import RobotConfig, load_config

    if args.urdf and args.terrain is not None:
        raise UsageError("--terrain applies to --mjcf only: a URDF describes the robot alone")
    # Resolve the terrain before reading the configuration, so a typo fails fast.
    terrain = None
    if args.terrain is not None:
        from whexar.sim.terrain import terrain_by_name

        terrain = terrain_by_name(args.terrain)
    cfg = RobotConfig() if args.config is None else load_config(args.config)
    if args.mjcf:
        from whexar.sim.model import build_mjcf

        text = build_mjcf(cfg, terrain=terrain, wheel_shape=args.wheel)
    else:
        from whexar.sim.urdf import build_urdf

        text = build_urdf(cfg, wheel_shape=args.wheel)
    if args.output is None:
        sys.stdout.write(text)
        return 0
    try:
        args.output.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UsageError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    model = commands.add_parser(
        "model",
        help="write the simulation model (MJCF) or the URDF of the robot",
        description="Write WHexaR's MuJoCo model (MJCF) or its URDF, built from the "
        "robot configuration. Joint angles are whexar's (Table 6.5's convention).",
    )
    kind = model.add_mutually_exclusive_group(required=True)
    kind.add_argument("--mjcf", action="store_true", help="the MuJoCo model, with a terrain")
    kind.add_argument("--urdf", action="store_true", help="the URDF, for Foxglove or RViz")
    model.add_argument(
        "-o", "--output", type=Path, default=None, help="write to FILE (default: stdout)"
    )
    model.add_argument(
        "--config", type=Path, default=None, help="robot configuration (default: the thesis robot)"
    )
    model.add_argument(
        "--terrain",
        default=None,
        metavar="NAME",
        help="flat (default), slope15, slope30, steps, obstacles, course, or slope<deg> "
        "(--mjcf only)",
    )
    model.add_argument(
        "--wheel",
        choices=("sphere", "cylinder"),
        default="sphere",
        help="wheel collision shape (default sphere: faster; cylinder: the true shape)",
    )
    model.set_defaults(handler=_model)
