"""``whexar sensors``: how a frame and the sensor events read, in lines and in JSON."""

from __future__ import annotations

import json
import math

from whexar.actors.messages import AccelImplausible, AccelPlausible, SensorFrame
from whexar.cli.sensors import SENSOR_EVENTS, event_line, event_record, frame_line, frame_record


def frame(**kw: object) -> SensorFrame:
    values: dict[str, object] = {
        "t": 1.5,
        "source": "sensors",
        "seq": 7,
        "ir_counts": (300, 60),
        "ir_distances_m": (0.315, math.inf),
        "fsr_counts": None,
        "contacts": None,
        "acc_counts": None,
        "roll_rad": None,
        "pitch_rad": None,
    }
    values.update(kw)
    return SensorFrame(**values)  # type: ignore[arg-type]


def test_an_ir_sensor_reads_a_distance_clear_or_no_reading() -> None:
    seen = frame(ir_counts=(300, 0), ir_distances_m=(math.inf, None))
    assert "ir  300    0 (  -- ,  n/c  m)" in frame_line(seen)
    record = json.loads(json.dumps(frame_record(seen)))
    assert record["ir_distance_m"] == [None, None]
    assert record["ir_status"] == ["clear", "no_reading"]
    measured = frame_record(frame())
    assert measured["ir_status"] == ["range", "clear"]
    assert measured["ir_distance_m"] == [0.315, None]


def test_accelerometer_without_tilt_and_its_events() -> None:
    line = frame_line(frame(acc_counts=(0, 0, 0)))
    assert "acc    0    0    0 (no tilt)" in line
    assert "roll" not in line
    tilted = frame_line(frame(acc_counts=(338, 371, 396), roll_rad=0.0, pitch_rad=0.52))
    assert "pitch  +29.8°" in tilted
    bad = AccelImplausible(
        t=2.0,
        source="sensors",
        link="emulator",
        sensor="board",
        seq=9,
        accel_g=(-5.0, -5.0, -5.0),
        magnitude_g=8.66,
        tolerance_g=0.2,
    )
    good = AccelPlausible(
        t=3.0,
        source="sensors",
        link="emulator",
        sensor="board",
        seq=30,
        magnitude_g=1.0,
        withheld=21,
    )
    assert isinstance(bad, SENSOR_EVENTS)
    assert isinstance(good, SENSOR_EVENTS)
    assert "board accelerometer NOT GRAVITY: |a| = 8.66 g (1 ± 0.2 g expected)" in event_line(bad)
    assert "reads gravity again (|a| = 1.00 g) after 21 reading(s)" in event_line(good)
    assert event_record(bad)["event"] == "AccelImplausible"
    assert event_record(bad)["magnitude_g"] == 8.66
