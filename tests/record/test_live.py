"""The live view: a run served to a Foxglove client over the WebSocket protocol, publish
only; and the shipped layout is the one the code builds."""

from __future__ import annotations

import asyncio
import json
import threading
from typing import Any

import pytest
import websockets
from websockets.typing import Subprotocol

from whexar.cli.sim import Pace
from whexar.record.live import LAYOUT_FILE, LiveView, layout_json
from whexar.sim.run import simulate
from whexar.testing.walk import command

SUBPROTOCOL = Subprotocol("foxglove.sdk.v1")
COMMANDS = [(1.0, command(mode="ride", vx_m_s=0.1))]


def test_the_shipped_layout_is_the_one_the_code_builds() -> None:
    assert LAYOUT_FILE.read_text(encoding="utf-8") == layout_json()
    panels = LAYOUT_FILE.read_text(encoding="utf-8")
    for topic in ("/joint_states", "/robot_description", "/servo-state", "/goals", "/log"):
        assert topic in panels


class Client(threading.Thread):
    """A Foxglove client in its own thread: subscribes to every channel it is told of,
    tries to publish (which the server must refuse), counts what arrives."""

    def __init__(self, url: str) -> None:
        super().__init__(daemon=True)
        self.url = url
        self.info: dict[str, Any] = {}
        self.topics: dict[int, str] = {}
        self.received: dict[str, int] = {}
        self.statuses: list[dict[str, Any]] = []
        self.connected = threading.Event()
        self.stop = threading.Event()

    def run(self) -> None:
        asyncio.run(self._run())

    async def _run(self) -> None:
        # The app-side close: the server may leave the closing handshake unanswered, and a
        # client waiting out its 10 s default only slows the test (close_timeout).
        async with websockets.connect(
            self.url, subprotocols=[SUBPROTOCOL], close_timeout=1.0
        ) as ws:
            self.info = json.loads(await ws.recv())
            # A client that tries to command: advertise a channel and publish on it.
            await ws.send(
                json.dumps(
                    {
                        "op": "advertise",
                        "channels": [
                            {"id": 1, "topic": "/commands", "encoding": "json", "schemaName": "X"}
                        ],
                    }
                )
            )
            await ws.send(b"\x01\x01\x00\x00\x00" + b'{"vx_m_s": 1}')
            self.connected.set()
            sub = 0
            while not self.stop.is_set():
                try:
                    raw = await asyncio.wait_for(ws.recv(), 0.2)
                except TimeoutError:
                    continue
                if isinstance(raw, bytes):
                    if raw[0] == 1:  # message data: op, subscription id, log time, payload
                        topic = self.topics[int.from_bytes(raw[1:5], "little")]
                        self.received[topic] = self.received.get(topic, 0) + 1
                    continue
                msg = json.loads(raw)
                if msg["op"] == "advertise":
                    subs = []
                    for channel in msg["channels"]:
                        sub += 1
                        self.topics[sub] = channel["topic"]
                        subs.append({"id": sub, "channelId": channel["id"]})
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                elif msg["op"] == "status":
                    self.statuses.append(msg)


@pytest.mark.slow
@pytest.mark.serial  # paced to real time
def test_a_live_run_reaches_a_client_and_nothing_the_client_sends_reaches_the_run() -> None:
    plain = simulate(commands=COMMANDS, duration=2.0, keep_log=True)
    with LiveView(port=0) as live:
        client = Client(live.url)
        client.start()
        assert client.connected.wait(10)
        # Paced to real time, as `whexar sim --live` is: a client subscribes to a topic when
        # it is advertised, and what is published before that is not for it. Unpaced on a
        # busy machine, the whole run could be over before the client had subscribed.
        served = simulate(
            commands=COMMANDS, duration=2.0, live=live, on_sample=Pace(), keep_log=True
        )
        client.stop.set()
        client.join(10)
        assert not client.is_alive()
    assert client.info["op"] == "serverInfo"
    assert client.info["capabilities"] == []  # no client publishing, parameters, services
    assert served.world.state_hash() == plain.world.state_hash()
    assert served.run.digest == plain.run.digest
    assert set(client.topics.values()) >= {"/servo-state", "/joint_states", "/tf", "/log"}
    assert client.received.get("/joint_states", 0) > 10
    assert client.received.get("/servo-state", 0) > 10
