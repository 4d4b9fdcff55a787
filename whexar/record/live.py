"""The live view: a run's messages served to the Foxglove app over its WebSocket protocol.

Theory of operation
-------------------
:class:`LiveView` is a :class:`~whexar.record.writer.LiveSink`: the recorder hands it
every channel it registers and every message it writes, already encoded (JSON with
JSON Schemas, :mod:`whexar.record.encoding`), and the view logs them on a foxglove-sdk
WebSocket server (the ``foxglove.sdk.v1`` protocol). What the app sees live is what the
recording holds, the same topics and schemas, so one layout (:func:`layout`, shipped as
``config/foxglove/whexar.json``) serves both.

The server listens on localhost unless told otherwise, and it only publishes: it
announces no capability (no client publishing, no parameters, no services), so
nothing a client sends reaches the runtime, let alone the robot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Final

import foxglove
import foxglove.layouts as fl

from whexar.record.writer import ROBOT_DESCRIPTION
from whexar.robot import JOINT_NAMES, LEG_NAMES

DEFAULT_PORT: Final = 8765
"""Foxglove's default WebSocket port."""
LAYOUT_FILE: Final = Path(__file__).resolve().parents[2] / "config" / "foxglove" / "whexar.json"
"""The shipped layout: :func:`layout` written out (``tests/record/test_live.py`` checks)."""


class LiveView:
    """A Foxglove WebSocket server for one run, publishing only (see the module doc).

    ``port`` 0 picks a free port (:attr:`port` tells which). Close it with
    :meth:`close`, or use it as a context manager.
    """

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1") -> None:
        self._context = foxglove.Context()
        self.host = host
        try:
            self._server = foxglove.start_server(
                name="whexar", host=host, port=port, capabilities=[], context=self._context
            )
        except Exception as exc:  # the SDK's own error types: a port in use, a bad host
            from whexar.errors import UsageError

            raise UsageError(f"live view: cannot listen on {host}:{port}: {exc}") from None
        self.port: int = self._server.port
        self._channels: dict[int, foxglove.Channel] = {}
        self._topics: set[str] = set()

    @property
    def url(self) -> str:
        """What to open in the Foxglove app (Open connection → Foxglove WebSocket)."""
        return f"ws://{self.host}:{self.port}"

    def add_channel(self, channel_id: int, topic: str, schema_name: str, schema: bytes) -> None:
        """Advertise ``topic`` with its JSON Schema to every client.

        A server's topics are unique (foxglove-sdk keeps the first channel of a topic):
        on a runtime channel that carries several types (``/events``) the first type
        keeps the topic, the others are ``{topic}/{type}``; ``/log`` has them all."""
        if topic in self._topics:
            topic = f"{topic}/{schema_name}"
        self._topics.add(topic)
        self._channels[channel_id] = foxglove.Channel(
            topic,
            schema=foxglove.Schema(name=schema_name, encoding="jsonschema", data=schema),
            message_encoding="json",
            context=self._context,
        )

    def log(self, channel_id: int, ns: int, data: bytes) -> None:
        """Send one message to the clients subscribed to its channel."""
        channel = self._channels.get(channel_id)
        if channel is not None:
            channel.log(data, log_time=ns)

    def close(self) -> None:
        """Stop the server (the clients are disconnected)."""
        self._server.stop()

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _joint_plot(leg: int) -> fl.PlotPanel:
    """Goal against present angle of each of one leg's six angle joints (thesis Fig. 6.2)."""
    paths: list[fl.PlotSeries] = []
    for joint in range(6):  # coxa … wheel direction: the wheel drive turns at a speed
        name = JOINT_NAMES[joint]
        paths += [
            fl.PlotSeries(
                value=f"/goals.goals[:]{{leg=={leg}}}{{joint=={joint}}}.position_rad",
                label=f"{name} goal",
                line_interpolation="step",
            ),
            fl.PlotSeries(
                value=f"/servo-state.joints[:]{{leg=={leg}}}{{joint=={joint}}}.position_rad",
                label=f"{name} present",
            ),
        ]
    return fl.PlotPanel(
        title=f"Leg {leg} ({LEG_NAMES[leg]}): goal and present angle, rad",
        config=fl.PlotConfig(paths=paths, show_legend=True),
    )


PHASE_COLORS: Final = {
    "swing": "#1f77b4",
    "stance": "#2ca02c",
    "move": "#ff7f0e",
    "hold": "#7f7f7f",
    "reflex": "#d62728",
}
"""A colour per leg phase (:class:`~whexar.actors.messages.LegState`) in the gait diagram."""


def _gait_diagram() -> fl.StateTransitionsPanel:
    """Each leg's phase over time (thesis Fig. 3.3): ``/legs`` filtered per leg."""
    states = fl.StateTransitionsDiscreteCustomStates(
        states=[
            fl.StateTransitionsDiscreteCustomState(value=phase, label=phase, color=color)
            for phase, color in PHASE_COLORS.items()
        ]
    )
    return fl.StateTransitionsPanel(
        title="Gait diagram: each leg's phase",
        config=fl.StateTransitionsConfig(
            paths=[
                fl.StateTransitionsSeries(
                    value=f"/legs{{leg=={leg}}}.phase", label=name, custom_states=states
                )
                for leg, name in enumerate(LEG_NAMES)
            ],
            show_legend=True,
        ),
    )


def layout() -> fl.Layout:
    """WHexaR's Foxglove layout: the robot in 3D (the URDF from ``/robot_description``,
    moved by ``/joint_states``, placed by ``/tf``), the gait diagram, goal against
    present angle, currents, the body's tilt and the event log."""
    three_d = fl.ThreeDeePanel(
        title="WHexaR",
        config=fl.ThreeDeeConfig(
            follow_tf="base",
            layers={
                "grid": fl.BaseRendererGridLayerSettings(layer_id="foxglove.Grid"),
                "urdf": fl.BaseRendererUrdfLayerSettings(
                    layer_id="foxglove.Urdf",
                    label="WHexaR",
                    source_type="topic",
                    topic=ROBOT_DESCRIPTION,
                    control_mode="jointStates",
                    joint_states_topic="/joint_states",
                ),
            },
        ),
    )
    currents = fl.PlotPanel(
        title="Servo currents, A",
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(
                    value=f"/servo-state.joints[:]{{leg=={leg}}}{{joint==2}}.current_a",
                    label=f"{LEG_NAMES[leg]} femur",
                )
                for leg in range(len(LEG_NAMES))
            ],
            show_legend=True,
        ),
    )
    tilt = fl.PlotPanel(
        title="Body tilt (IMU), rad",
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(value="/tilt.roll_rad", label="roll"),
                fl.PlotSeries(value="/tilt.pitch_rad", label="pitch"),
            ],
            show_legend=True,
        ),
    )
    events = fl.LogPanel(title="Events", config=fl.LogConfig(topic_to_render="/log"))
    gait = _gait_diagram()
    plots = fl.SplitContainer(
        direction="column",
        items=[
            fl.SplitItem(
                content=fl.TabContainer(
                    tabs=[
                        fl.TabItem(title=name, content=_joint_plot(leg))
                        for leg, name in enumerate(LEG_NAMES)
                    ]
                )
            ),
            fl.SplitItem(content=currents),
            fl.SplitItem(content=tilt),
        ],
    )
    return fl.Layout(
        content=fl.SplitContainer(
            direction="row",
            items=[
                fl.SplitItem(
                    proportion=3,
                    content=fl.SplitContainer(
                        direction="column",
                        items=[
                            fl.SplitItem(proportion=3, content=three_d),
                            fl.SplitItem(proportion=1, content=gait),
                            fl.SplitItem(proportion=1, content=events),
                        ],
                    ),
                ),
                fl.SplitItem(proportion=2, content=plots),
            ],
        )
    )


def layout_json() -> str:
    """:func:`layout` as the JSON the Foxglove app imports (Layouts → Import from file)."""
    import json

    data: Any = json.loads(layout().to_json())
    return json.dumps(data, indent=2) + "\n"
