"""``whexar model --mjcf | --urdf`` from the command line."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import pytest

from whexar.cli import main
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, LEG_NAMES
from whexar.sim.terrain import TERRAIN_NAMES

NAMES = {f"{leg}_{joint}" for leg in LEG_NAMES for joint in JOINT_NAMES}


def test_mjcf_prints_a_model_mujoco_loads(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "--mjcf"]) == 0
    m = mujoco.MjModel.from_xml_string(capsys.readouterr().out)
    assert m.nu == 42
    assert m.joint("base").type[0] == mujoco.mjtJoint.mjJNT_FREE


def test_mjcf_with_a_terrain_to_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "whexar.xml"
    assert main(["model", "--mjcf", "--terrain", "course", "-o", str(out)]) == 0
    assert capsys.readouterr().out == ""
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.geom("ramp_0").id >= 0


def test_urdf_has_six_legs_of_seven_joints(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "--urdf"]) == 0
    robot = ET.fromstring(capsys.readouterr().out)
    assert robot.tag == "robot"
    joints = {j.get("name"): j for j in robot.iter("joint")}
    moving = {name: j for name, j in joints.items() if j.get("type") != "fixed"}
    assert set(moving) == NAMES
    cfg = RobotConfig()
    for name, joint in moving.items():
        spec = cfg.joints.by_name(str(name).split("_", 1)[1])
        if spec.endless:
            assert joint.get("type") == "continuous"
        else:
            assert joint.get("type") == "revolute"
            limit = joint.find("limit")
            assert limit is not None
            lo, hi = spec.limits_rad or (0.0, 0.0)
            assert math.isclose(float(limit.get("lower", "nan")), lo, abs_tol=1e-9)
            assert math.isclose(float(limit.get("upper", "nan")), hi, abs_tol=1e-9)
    links = {link.get("name") for link in robot.iter("link")}
    assert {"base", "imu", "ir_right", "ir_left"} <= links
    masses = [float(m.get("value", "0")) for m in robot.iter("mass")]
    assert sum(masses) == pytest.approx(cfg.robot.mass_kg, abs=1e-3)


def test_a_bad_terrain_is_bad_input(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "--mjcf", "--terrain", "moon"]) == 2
    err = capsys.readouterr().err
    assert "moon" in err
    for name in TERRAIN_NAMES:
        assert name in err


def test_terrain_is_for_the_mjcf_only(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "--urdf", "--terrain", "flat"]) == 2
    assert "--mjcf only" in capsys.readouterr().err


def test_one_of_mjcf_or_urdf_is_required() -> None:
    with pytest.raises(SystemExit) as info:
        main(["model"])
    assert info.value.code == 2
