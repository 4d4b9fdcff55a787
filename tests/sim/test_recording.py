"""A recorded simulation: the recording changes nothing in the run, and it holds every
message, the bus's and the sensor link's bytes, the body's pose and what made the run."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from whexar.actors.messages import ServoStates
from whexar.bus.protocol import PacketDecoder
from whexar.record.encoding import LinkBytes
from whexar.record.reader import Recording
from whexar.sim.run import simulate
from whexar.testing.walk import command

COMMANDS = [(2.5, command(mode="ride", vx_m_s=0.1))]


@pytest.mark.slow
def test_recording_changes_nothing_and_holds_every_message_and_byte(tmp_path: Path) -> None:
    plain = simulate(commands=COMMANDS, duration=3.0, keep_log=True)
    path = tmp_path / "run.mcap"
    recorded = simulate(commands=COMMANDS, duration=3.0, record=path, keep_log=True)
    assert recorded.world.state_hash() == plain.world.state_hash()
    assert recorded.run.digest == plain.run.digest
    assert recorded.recording == path
    stats = recorded.recorder_stats
    assert stats is not None
    assert stats.dropped == 0
    assert stats.errors == 0

    log = Recording(path)
    assert log.complete
    assert {"robot.urdf", "wiring.json"} <= set(log.attachments)
    records = list(log.records())
    topics = Counter(r.topic for r in records)
    # Every message of the run, channel by channel.
    published = Counter(f"/{e.channel}" for e in recorded.run.log.entries)
    for topic, count in published.items():
        assert topics[topic] == count, topic
    states = [r.value for r in records if r.topic == "/servo-state"]
    assert states == recorded.run.log.messages("servo-state", of=ServoStates)
    # The bus's bytes: requests out, one status packet per answer back, no CRC errors.
    sent, got = PacketDecoder(), PacketDecoder()
    bus = [r.value for r in records if r.topic == "/links/bus"]
    assert all(isinstance(b, LinkBytes) for b in bus)
    requests = [p for b in bus if b.direction == "tx" for p in sent.feed(b.data)]
    replies = [p for b in bus if b.direction == "rx" for p in got.feed(b.data)]
    assert requests
    assert replies
    assert sent.crc_errors == got.crc_errors == 0
    assert topics["/links/sensors"] > 0
    # The IMU's I²C transactions: address and register out, the registers' bytes back.
    imu = [r.value for r in records if r.topic == "/links/imu"]
    assert {b.direction for b in imu} == {"open", "tx", "rx"}
    assert imu[0].direction == "open"  # a replay opens the bus as the run did
    assert all(b.data[0] == 0x6B for b in imu if b.direction == "tx")  # the LSM9DS1's A/G
    # Foxglove's views: the joints, the body's pose, the events.
    # The 3D view's joints at about 27 Hz, not the servo states' 110 Hz.
    assert len(states) / 5 <= topics["/joint_states"] <= len(states) / 3
    assert topics["/tf"] >= 3.0 / 0.05 - 2
    assert topics["/log"] == len(recorded.events)
