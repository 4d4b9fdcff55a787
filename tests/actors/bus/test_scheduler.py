"""The bus scheduler on virtual time against the in-process servo emulator (real dynamixel-sdk)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import pytest

from whexar.actors.messages import (
    BusStats,
    GoalClamped,
    JointGoal,
    JointGoals,
    ReadModeChanged,
    ServoHealth,
    ServoStates,
)
from whexar.bus import control_table as ct
from whexar.bus.emulator.chain import SERVO_CHAIN, ServoChain
from whexar.bus.protocol import Instruction, Packet
from whexar.config import RobotConfig
from whexar.robot import JOINT_NAMES, servo_id
from whexar.runtime.devices import DEVICES
from whexar.runtime.messages import ActorFailed
from whexar.runtime.wiring import WiringError
from whexar.testing import Harness, RunResult, run_actors
from whexar.testing.bus import bus_graph, servo_chain

CFG = RobotConfig()
FEMUR = JOINT_NAMES.index("femur")
TIBIA = JOINT_NAMES.index("tibia")
COXA = JOINT_NAMES.index("coxa")


def graph(
    params: dict[str, Any] | None = None, *, wiggle: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Scheduler on ``emulator:test``; goals fed by the harness, or by a GoalWiggle."""
    return bus_graph("emulator:test", params, wiggle=wiggle, max_restarts=0)


def goal_writes(chain: ServoChain) -> list[dict[int, int]]:
    """Record every Goal Position a Sync Write carries, as {id: ticks} per packet."""
    seen: list[dict[int, int]] = []

    def hook(_chain: ServoChain, _t: float, packets: Sequence[Packet]) -> None:
        for p in packets:
            if p.instruction != Instruction.SYNC_WRITE:
                continue
            start = int.from_bytes(p.params[0:2], "little")
            length = int.from_bytes(p.params[2:4], "little")
            if start != 116 or length != 4:
                continue
            body = p.params[4:]
            seen.append(
                {
                    body[k]: int.from_bytes(body[k + 1 : k + 5], "little", signed=True)
                    for k in range(0, len(body), 5)
                }
            )

    chain.hooks.append(hook)
    return seen


def table(chain: ServoChain, sid: int, name: str) -> int:
    return chain.servos[sid].register_value(name)


def goals(*items: tuple[int, int, float], t: float = 0.0, reflex: bool = False) -> JointGoals:
    return JointGoals(
        t=t,
        source="harness",
        reflex=reflex,
        goals=tuple(
            JointGoal(t=t, source="harness", leg=leg, joint=j, position_rad=q)
            for leg, j, q in items
        ),
    )


def run(
    g: dict[str, Any],
    scenario: Callable[[Harness], Any] | None = None,
    duration: float | None = None,
) -> RunResult:
    return run_actors(g, duration=duration, scenario=scenario, feeds=["goals"])


# --------------------------------------------------------------------------- start-up


def test_start_up_configures_every_servo_and_enables_torque(chain: ServoChain) -> None:
    result = run(graph(), duration=1.0)
    assert result.exit_code == 0
    assert not result.events(ActorFailed)
    for sid, servo in chain.servos.items():
        assert table(chain, sid, "return_delay_time") == 10  # 20 µs in 2 µs units
        mode = 1 if servo.model.name == "MX-28" and sid % 7 == 0 else 3
        assert table(chain, sid, "operating_mode") == mode
    # Stopped: torque off on every servo (bus.on_stop = torque_off).
    assert all(table(chain, sid, "torque_enable") == 0 for sid in chain.servos)
    modes = result.events(ReadModeChanged)
    assert [m.mode for m in modes] == ["sync_read"]  # MX: Fast Sync Read not answered
    assert result.messages("state", of=ServoStates)


def test_torque_is_on_while_running_and_held_with_on_stop_hold(chain: ServoChain) -> None:
    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        assert all(table(chain, sid, "torque_enable") == 1 for sid in chain.servos)

    path = _config_with(bus={"on_stop": "hold"})
    result = run(graph({"config": str(path)}), scenario)
    assert result.exit_code == 0
    assert all(table(chain, sid, "torque_enable") == 1 for sid in chain.servos)


def test_model_mismatch_names_the_servo_and_both_models() -> None:
    cfg = RobotConfig()
    made = servo_chain(cfg)
    wrong = servo_id(0, "coxa")
    made.servos[wrong].table[0:2] = (321).to_bytes(2, "little")  # an MX-106 where an MX-64 is
    DEVICES.register(SERVO_CHAIN, "test", made)
    try:
        result = run(graph(), duration=1.0)
    finally:
        DEVICES.unregister(SERVO_CHAIN, "test")
    failed = result.events(ActorFailed)
    assert failed
    assert f"servo {wrong} (RF coxa) is a MX-106 (model 321)" in failed[0].error
    assert "configuration says MX-64 (model 311)" in failed[0].error
    assert result.exit_code == 3


# --------------------------------------------------------------------------- plans


@pytest.mark.parametrize(
    ("plan", "count", "fields"),
    [
        ("full_feedback", 42, {"position_rad", "velocity_rad_s", "current_a"}),
        ("positioning", 24, {"position_rad"}),
        ("thesis", 42, {"position_rad", "current_a"}),
        ("default", 24, {"position_rad", "current_a"}),
    ],
)
def test_plan_decides_what_each_cycle_reads(
    chain: ServoChain, plan: str, count: int, fields: set[str]
) -> None:
    result = run(graph({"plan": plan}), duration=0.5)
    states = result.messages("state", of=ServoStates)
    assert len(states) > 10
    last = states[-1]
    assert len(last.joints) == count
    for js in last.joints:
        present = {
            f for f in ("position_rad", "velocity_rad_s", "current_a") if getattr(js, f) is not None
        }
        assert present == fields


def test_default_plan_reads_health_of_every_servo_round_robin(chain: ServoChain) -> None:
    chain.servos[5].input_voltage_v = 11.3
    result = run(graph({"plan": "default"}), duration=2.0)
    health = result.messages("health", of=ServoHealth)
    volts = {h.servo_id: h.voltage_v for h in health if h.voltage_v is not None}
    errors = {h.servo_id for h in health if h.hardware_error is not None}
    assert set(volts) == set(chain.servos)
    assert errors == set(chain.servos)
    assert volts[5] == pytest.approx(11.3)
    assert volts[6] == pytest.approx(12.0)


def test_cycle_rate_is_bus_bound(chain: ServoChain) -> None:
    result = run(graph({"plan": "full_feedback"}, wiggle={}), duration=2.0)
    stats = result.messages("stats", of=BusStats)
    assert stats
    timing = chain.timing
    rdt = 20e-6
    limit = 1 / (
        timing.sync_read_s(42, 10, rdt) + timing.sync_write_s(36, 4) + timing.sync_write_s(6, 4)
    )
    assert stats[-1].rate_hz == pytest.approx(limit, rel=0.03)


# --------------------------------------------------------------------------- goals


def test_latest_goal_per_joint_wins_and_goes_out_next_cycle(chain: ServoChain) -> None:
    writes = goal_writes(chain)
    femur = servo_id(2, "femur")

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        writes.clear()
        for q in (0.1, 0.2, 0.3):
            await h.feed("goals", goals((2, FEMUR, q)))
        await h.wait_for(ServoStates)
        await h.wait_for(ServoStates)

    run(graph(), scenario)
    sent = [w[femur] for w in writes if femur in w]
    assert sent == [ct.rad_to_ticks(0.3)]
    assert table(chain, femur, "goal_position") == ct.rad_to_ticks(0.3)


def test_goal_outside_limits_is_clamped_and_reported(chain: ServoChain) -> None:
    writes = goal_writes(chain)
    tibia = servo_id(1, "tibia")
    hi = (CFG.joints.by_name("tibia").limits_rad or (0.0, 0.0))[1]
    coxa = servo_id(0, "coxa")

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        await h.feed("goals", goals((1, TIBIA, 4.0), (0, COXA, -6.0), reflex=True))
        await h.wait_for(ServoStates)
        await h.wait_for(ServoStates)

    result = run(graph(), scenario)
    clamped = result.events(GoalClamped)
    assert {(c.servo_id, c.requested_rad) for c in clamped} == {(tibia, 4.0), (coxa, -6.0)}
    by_id = {c.servo_id: c.sent_rad for c in clamped}
    assert by_id[tibia] == pytest.approx(min(hi, ct.ticks_to_rad(4095)))
    assert by_id[coxa] == pytest.approx(max(math.radians(-135), ct.ticks_to_rad(0)))
    # Nothing outside a joint's limits reached the wire, and no servo refused a goal.
    for w in writes:
        for sid, ticks in w.items():
            joint = JOINT_NAMES[(sid - 1) % 7]
            lo_q, hi_q = CFG.joints.by_name(joint).limits_rad or (-math.pi, math.pi)
            assert lo_q <= ct.ticks_to_rad(ticks) <= hi_q  # no tolerance
            assert 0 <= ticks <= 4095
    assert all(s.rejected_goals == 0 for s in chain.servos.values())


# --------------------------------------------------------------------------- fast sync read


def test_fast_sync_read_is_used_when_the_servos_answer_it() -> None:
    made = servo_chain(CFG, fast_sync_read=True)
    DEVICES.register(SERVO_CHAIN, "test", made)
    try:
        result = run(graph({"plan": "default"}), duration=0.3)
    finally:
        DEVICES.unregister(SERVO_CHAIN, "test")
    assert [m.mode for m in result.events(ReadModeChanged)] == ["fast_sync_read"]
    assert len(result.messages("state", of=ServoStates)[-1].joints) == 24


def test_fast_sync_read_falls_back_when_it_stops_working() -> None:
    made = servo_chain(CFG, fast_sync_read=True)
    DEVICES.register(SERVO_CHAIN, "test", made)

    async def scenario(h: Harness) -> None:
        await h.wait_for(ServoStates)
        for servo in made.servos.values():
            servo.fast_sync_read = False
        change = await h.wait_for(ReadModeChanged)
        assert change.mode == "sync_read"
        after = await h.wait_for(ServoStates)
        assert len(after.joints) == 24

    try:
        result = run(graph({"plan": "default"}), scenario)
    finally:
        DEVICES.unregister(SERVO_CHAIN, "test")
    assert result.exit_code == 0


# --------------------------------------------------------------------------- determinism


def test_same_run_gives_the_same_log() -> None:
    digests = []
    for _ in range(2):
        made = servo_chain(CFG)
        DEVICES.register(SERVO_CHAIN, "test", made)
        try:
            digests.append(run(graph(wiggle={}), duration=0.5).log.digest())
        finally:
            DEVICES.unregister(SERVO_CHAIN, "test")
    assert digests[0] == digests[1]


def _config_with(**sections: dict[str, Any]) -> Any:
    """Write the default configuration with ``sections`` overridden to a temporary TOML file."""
    import tempfile
    from pathlib import Path

    lines = []
    for name, values in sections.items():
        lines.append(f"[{name}]")
        for key, value in values.items():
            shown = f'"{value}"' if isinstance(value, str) else str(value).lower()
            lines.append(f"{key} = {shown}")
    path = Path(tempfile.mkdtemp()) / "whexar.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("toml", "path", "says"),
    [
        (
            '[bus.plan]\nreads = [{registers = ["present_positon"]}]\n',
            "bus.plan.reads[0].registers",
            "does not exist",
        ),
        ('[bus]\nplan = "fastest"\n', "bus.plan", "a preset (thesis, full_feedback"),
        ("[bus.plan]\nreads = []\n", "bus.plan.reads", "at least one read"),
        ('[joints.coxa]\nmodel = "MX-12"\n', "joints.coxa.model", "'MX-28', 'MX-64' or 'MX-106'"),
    ],
)
def test_bad_bus_configuration_is_refused_before_any_byte(
    chain: ServoChain, toml: str, path: str, says: str
) -> None:
    import tempfile
    from pathlib import Path

    file = Path(tempfile.mkdtemp()) / "whexar.toml"
    file.write_text(toml)
    seen: list[int] = []
    chain.hooks.append(lambda _c, _t, packets: seen.append(len(packets)))
    # The file named in the params is checked with the wiring, before anything starts.
    with pytest.raises(WiringError) as caught:
        run(graph({"config": str(file)}), duration=1.0)
    assert "actors.bus.params.config" in str(caught.value)
    assert path in str(caught.value)
    assert says in str(caught.value)
    assert seen == []  # nothing reached the bus


# --------------------------------------------------------------------------- real ports


@pytest.mark.slow
@pytest.mark.serial  # real time, a pty
def test_scheduler_over_a_pty_in_real_time_runs_and_stops_cleanly() -> None:
    """The thread-owned port path: real SDK, real serial I/O, real time, clean stop."""
    from whexar.bus.emulator.pty import PtyEmulator

    made = servo_chain(CFG, return_delay_us=20)
    with PtyEmulator(made, realtime=False) as emulator:
        result = run_actors(
            graph({"port": emulator.path, "plan": "positioning"}),
            duration=1.5,
            virtual=False,
            feeds=["goals"],
        )
    assert result.exit_code == 0
    assert not result.events(ActorFailed)
    states = result.messages("state", of=ServoStates)
    assert len(states) > 10
    assert len(states[-1].joints) == 24
    stopped = [e for e in result.events() if getattr(e, "actor", None) == "bus"][-1]
    assert getattr(stopped, "timed_out", True) is False
    assert all(table(made, sid, "torque_enable") == 0 for sid in made.servos)


def test_latency_timer_is_read_from_sysfs(tmp_path: Any) -> None:
    from whexar.bus.sdk import latency_timer_ms

    (tmp_path / "ttyUSB0").mkdir()
    (tmp_path / "ttyUSB0" / "latency_timer").write_text("16\n")
    assert latency_timer_ms("/dev/ttyUSB0", tmp_path) == 16
    assert latency_timer_ms("/dev/pts/7", tmp_path) is None
