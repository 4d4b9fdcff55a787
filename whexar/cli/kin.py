"""``whexar kin …``: leg kinematics in the thesis's leg frame (mm, degrees), gait charts."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from whexar.cli.common import Commands, print_json
from whexar.errors import UsageError
from whexar.robot import LEG_NAMES, POSITIONING_JOINTS, leg_index

if TYPE_CHECKING:
    from whexar.kinematics.geometry import LegGeometry


def _geometry(args: argparse.Namespace) -> LegGeometry:
    from whexar.config import default_geometry, load_config

    if args.config is None:
        return default_geometry()
    return load_config(args.config).leg_geometry()


def _leg(value: str) -> int:
    try:
        return leg_index(value)
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _kin_ik(args: argparse.Namespace) -> int:
    from whexar.kinematics.leg import ik

    geometry = _geometry(args)
    target = np.array([args.x, args.y, args.z]) / 1000.0
    solution = ik(
        target,
        geometry,
        pitch=math.radians(args.pitch),
        target=args.target,
        clamp=args.clamp,
    )
    values = solution.degrees
    degrees = {
        name: round(float(v), 4) + 0.0 for name, v in zip(POSITIONING_JOINTS, values, strict=True)
    }
    if args.json:
        out: dict[str, object] = dict(degrees)
        if args.clamp:
            out["clamped"] = bool(solution.clamped)
        print_json(out)
        return 0
    print(
        f"leg {args.leg} ({LEG_NAMES[args.leg]}), {args.target} at "
        f"({args.x:g}, {args.y:g}, {args.z:g}) mm, pitch {args.pitch:g}°"
    )
    for name, value in degrees.items():
        print(f"  {name:<11}{value:9.2f}°")
    if args.clamp and solution.any_clamped:
        print("  clamped: the target is out of reach or a joint hit its limit")
    return 0


def _kin_fk(args: argparse.Namespace) -> int:
    from whexar.kinematics.leg import fk

    geometry = _geometry(args)
    angles = np.radians(np.array(args.angles, dtype=np.float64))
    point = fk(angles, geometry, point=args.point) * 1000.0
    xyz = {axis: round(float(v), 4) + 0.0 for axis, v in zip("xyz", point, strict=True)}
    if args.json:
        print_json(xyz)
        return 0
    print(
        f"leg {args.leg} ({LEG_NAMES[args.leg]}), {args.point} at "
        f"({xyz['x']:.2f}, {xyz['y']:.2f}, {xyz['z']:.2f}) mm in the leg frame"
    )
    return 0


def _kin_gait(args: argparse.Namespace) -> int:
    from whexar.config import RobotConfig, load_config
    from whexar.kinematics.body import leg_to_body, stance_feet
    from whexar.kinematics.gait import GAIT_RANKING, gait
    from whexar.kinematics.stability import gait_stability_margin
    from whexar.kinematics.trajectory import FootTrajectory

    chosen = gait(args.name)
    if args.width < 16:
        raise UsageError(f"--width {args.width}; allowed: 16 characters or more")
    cfg = RobotConfig() if args.config is None else load_config(args.config)
    feet = leg_to_body(stance_feet(cfg.stance(args.stance)), cfg.leg_geometry())
    trajectory = FootTrajectory(args.step_mm / 1000, args.height_mm / 1000, chosen.duty_factor)
    margin, at = gait_stability_margin(chosen, feet, trajectory)
    if args.json:
        print_json(
            {
                "gait": chosen.name,
                "duty_factor": chosen.duty_factor,
                "offsets": dict(zip(LEG_NAMES, chosen.offsets, strict=True)),
                "groups": [list(g) for g in chosen.groups],
                "stability_rank": chosen.stability_rank,
                "min_margin_mm": round(margin * 1000, 2),
                "min_margin_phase": round(at, 4),
            }
        )
        return 0
    width = args.width
    phases = np.arange(width) / width
    swinging = chosen.in_swing(phases)
    print(
        f"{chosen.name}: duty factor {chosen.duty_factor:.2f}, "
        f"groups {' | '.join('+'.join(g) for g in chosen.groups)}"
    )
    print(f"stability rank {chosen.stability_rank} in {' < '.join(GAIT_RANKING)}")
    ticks = [" "] * width
    for k in range(4):
        label = f"{k / 4:g}"
        pos = k * width // 4
        ticks[pos : pos + len(label)] = list(label)
    print("       " + "".join(ticks) + "1")
    for leg, row in zip(LEG_NAMES, swinging.T, strict=True):
        print(f"  {leg}   " + "".join("^" if up else "_" for up in row))
    print("       ^ swing   _ stance (thesis Fig. 3.3)")
    print(
        f"smallest static stability margin {1000 * margin:.1f} mm at phase {at:.3f} "
        f"({args.stance} stance, step {args.step_mm:g} mm)"
    )
    return 0


def add_commands(commands: Commands) -> None:
    """Add this group's commands to the ``whexar`` command table."""
    kin = commands.add_parser("kin", help="leg kinematics in the thesis's leg frame (mm, degrees)")
    kin_cmds = kin.add_subparsers(dest="kin_command", required=True, metavar="ACTION")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--leg", type=_leg, required=True, help="leg 0–5 or RF, LF, RM, LM, RR, LR")
    common.add_argument("--json", action="store_true", help="print one JSON object")
    common.add_argument(
        "--config", type=Path, default=None, help="robot configuration (default: the thesis robot)"
    )
    ik_cmd = kin_cmds.add_parser(
        "ik",
        parents=[common],
        help="joint angles for a foot target",
        description="Inverse kinematics. X outward, Y down, Z forward from the coxa joint, "
        "in mm, in the leg's own frame (left legs are mirror images, so every leg gives "
        "the same angles for the same leg-frame target). Prints coxa, trochanter, femur, "
        "tibia and tarsus in degrees "
        "(Table 6.5's convention).",
    )
    ik_cmd.add_argument("x", type=float, help="mm outward")
    ik_cmd.add_argument("y", type=float, help="mm down")
    ik_cmd.add_argument("z", type=float, help="mm forward")
    ik_cmd.add_argument(
        "--pitch", type=float, default=0.0, help="body pitch the trochanter follows, degrees"
    )
    ik_cmd.add_argument(
        "--target",
        choices=("tarsus", "contact"),
        default="tarsus",
        help="which point X Y Z gives: the tarsus joint (thesis) or the wheel contact",
    )
    ik_cmd.add_argument(
        "--clamp", action="store_true", help="clamp to the workspace and limits instead of failing"
    )
    ik_cmd.set_defaults(handler=_kin_ik)
    fk_cmd = kin_cmds.add_parser(
        "fk",
        parents=[common],
        help="foot position for joint angles",
        description="Forward kinematics. Angles in degrees, Table 6.5's convention; prints "
        "x, y, z in mm in the leg frame.",
    )
    fk_cmd.add_argument(
        "angles", type=float, nargs=5, metavar="Q", help="coxa trochanter femur tibia tarsus"
    )
    fk_cmd.add_argument(
        "--point",
        choices=("tarsus", "contact"),
        default="tarsus",
        help="the tarsus joint (thesis) or the wheel contact",
    )
    fk_cmd.set_defaults(handler=_kin_fk)
    gait_cmd = kin_cmds.add_parser(
        "gait",
        help="phase chart and stability margin of a gait",
        description="Draw which leg swings when over one cycle, and the smallest static "
        "stability margin of the gait in a stance.",
    )
    gait_cmd.add_argument("name", help="tripod, tetrapod, ripple or wave")
    gait_cmd.add_argument("--stance", default="default", help="stance preset (default: default)")
    gait_cmd.add_argument("--step-mm", type=float, default=100.0, help="step length, mm")
    gait_cmd.add_argument("--height-mm", type=float, default=40.0, help="step height, mm")
    gait_cmd.add_argument("--width", type=int, default=48, help="chart width in characters")
    gait_cmd.add_argument("--json", action="store_true", help="print one JSON object")
    gait_cmd.add_argument(
        "--config", type=Path, default=None, help="robot configuration (default: the thesis robot)"
    )
    gait_cmd.set_defaults(handler=_kin_gait)
