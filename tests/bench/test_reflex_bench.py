"""The reflex bench's two graphs: the whole reactive layer against none of it."""

from __future__ import annotations

import math

from whexar.bench.reflex import bench_graph, contact_cost_ms
from whexar.runtime.wiring import build_graph


def test_without_the_layer_no_reflex_estimator_or_selector_remains() -> None:
    doc = bench_graph(reflexes=False, probe=False)
    names = {a["name"] for a in doc["actors"]}
    assert not {n for n in names if n.startswith("reflex-")}
    assert not names & {"terrain", "gait-selector"}
    assert not {"terrain", "gait-choice", "imu"} & set(doc["channels"])
    coordinator = next(a for a in doc["actors"] if a["name"] == "coordinator")
    assert "gait_choice" not in coordinator["inputs"]
    build_graph(doc, external={"commands": "bench"})


def test_with_the_layer_every_shipped_reflex_runs_and_the_legs_sense_no_ground() -> None:
    doc = bench_graph(reflexes=True, probe=True)
    names = {a["name"] for a in doc["actors"]}
    assert {
        "reflex-battery",
        "reflex-elevator",
        "reflex-heading-hold",
        "reflex-obstacle",
        "reflex-searching",
        "reflex-stepping",
        "reflex-trochanter",
        "reflex-probe",
        "terrain",
        "gait-selector",
    } <= names
    legs = [a for a in doc["actors"] if a["name"].startswith("leg-")]
    assert len(legs) == 6
    assert {a["params"]["contact"] for a in legs} == {"none"}
    build_graph(doc, external={"commands": "bench"})


def test_the_contact_estimate_is_timed_apart() -> None:
    cost = contact_cost_ms(cycles=200)  # a figure of the bench, not a target of a test
    assert math.isfinite(cost)
    assert cost > 0.0
