"""The sensor reader: the only owner of the sensor board's serial line.

Theory of operation
-------------------
The ATmega2560 board sends a text frame every 1/frame-rate seconds
(``firmware/PROTOCOL.md``; Žák 2023, 5.4). The reader feeds whatever bytes
arrive to the sans-IO :class:`~whexar.sensors.frame.FrameDecoder` and,
for each frame, publishes in the same loop iteration:

* :class:`SensorFrame` — everything in the frame, raw and converted;
* :class:`ObstacleRanges` — the IR distances by eq. 5.5 (calibration from
  ``[ir]``): ``inf`` beyond ``ir.max_distance_mm``, ``None`` for an input at
  0 counts — no reading: a rangefinder outputs about 0.4 V with nothing in
  range, so 0 V is an unplugged or unpowered sensor, and the space in front
  of it is unknown, not free;
* :class:`LegLoads` — the FSR counts and per-leg contact flags, with the
  hysteresis of ``[fsr]`` (on at ``contact_on_counts``, off below
  ``contact_off_counts``);
* :class:`BodyTilt` — roll and pitch from the board's analog accelerometer
  (eq. 5.6–5.7), when ``sensor_board.accelerometer.fitted`` says there is one,
  the frame carries it, and its reading is gravity: a magnitude within
  ``gravity_tolerance_g`` of 1 g (:mod:`whexar.sensors.gravity`).

Each is stamped with the time the frame was decoded and its sequence
number. What goes wrong becomes an event, never an exception:

* a rejected frame (garbage, bad checksum, out-of-range value) is
  :class:`SensorFrameRejected` and nothing of it is published;
* a jump in ``seq`` is :class:`SensorFrameGap` (lost frames or a board reset);
* an accelerometer reading that is not gravity gives no tilt and, when the
  readings turn so, one :class:`AccelImplausible`; the first plausible one
  after them is :class:`AccelPlausible`;
* no valid frame for ``sensor_board.stale_after_frames`` frame periods is
  :class:`SensorLinkStale`, and the first valid frame after it
  :class:`SensorLinkFresh`. The watch starts with the first valid frame of
  each connection: opening the port resets an Arduino Mega (DTR) and its
  bootloader keeps it silent for about a second, which is no staleness (a
  link that went down was reported :class:`SensorLinkDown` already);
* the device vanishing is :class:`SensorLinkDown`; the reader looks for it
  every ``reconnect_period_s`` and reports :class:`SensorLinkUp` when it is
  back. The reset on opening also means the first frame of a connection
  never counts as a gap.

The board starts at its build's frame rate and forgets ``rate=N#`` when it
resets. So after the first valid frame of each connection (when the
bootloader has handed over to the sketch), and again after every restart
the sequence numbers show on the same connection (a :class:`SensorFrameGap`
with ``restarted``: a brown-out, the watchdog), the reader sends ``rate=N#``
so that the board's frame rate is the configured one.

The port is a device or a pty (pyserial-asyncio, :mod:`whexar.sensors.serial_link`),
or ``emulator`` / ``emulator:NAME`` for the in-process board of
:mod:`whexar.sensors.board_emulator` on virtual time.
"""

from __future__ import annotations

import math
from typing import Final

import anyio
from pydantic import Field

from whexar.actors.messages import (
    AccelImplausible,
    AccelPlausible,
    BodyTilt,
    LegLoads,
    ObstacleRanges,
    SensorFrame,
    SensorFrameGap,
    SensorFrameRejected,
    SensorLinkDown,
    SensorLinkFresh,
    SensorLinkStale,
    SensorLinkUp,
    SensorStats,
)
from whexar.config import BoardBaudrate, ConfigFile, RobotConfig, SensorBoardSpec, load_config
from whexar.errors import DeviceGoneError
from whexar.kinematics.sensing import ir_distance
from whexar.runtime.actor import Actor, ActorParams, Output
from whexar.runtime.devices import DEVICES
from whexar.sensors.board_emulator import SENSOR_BOARD, SensorBoardEmulator
from whexar.sensors.frame import Frame, FrameDecoder, Mode, Rejected
from whexar.sensors.gravity import GravityCheck, GravityVerdict
from whexar.sensors.replay import REPLAYED_BOARD
from whexar.sensors.serial_link import ByteLink, SerialLink, TappedLink

EMULATOR: Final = SENSOR_BOARD.scheme
"""The port name of the in-process board; ``emulator:NAME`` opens the board registered as
NAME (:data:`~whexar.sensors.board_emulator.SENSOR_BOARD`)."""


def emulated_board(spec: SensorBoardSpec, baudrate: int | None = None) -> SensorBoardEmulator:
    """The board ``spec`` describes, emulated: its frame rate, its serial rate (``baudrate``
    overrides it) and an accelerometer if one is fitted."""
    return SensorBoardEmulator(
        frame_rate_hz=spec.frame_rate_hz,
        baudrate=spec.baudrate if baudrate is None else baudrate,
        accelerometer=spec.accelerometer.fitted,
    )


def gravity_event(
    verdict: GravityVerdict,
    accel_g: tuple[float, float, float],
    tolerance_g: float,
    *,
    t: float,
    source: str,
    link: str,
    sensor: str,
    seq: int | None,
) -> AccelImplausible | AccelPlausible | None:
    """The event a gravity check's verdict calls for, if its readings changed kind."""
    if verdict.change == "implausible":
        return AccelImplausible(
            t=t,
            source=source,
            link=link,
            sensor=sensor,
            seq=seq,
            accel_g=accel_g,
            magnitude_g=verdict.magnitude_g,
            tolerance_g=tolerance_g,
        )
    if verdict.change == "plausible":
        return AccelPlausible(
            t=t,
            source=source,
            link=link,
            sensor=sensor,
            seq=seq,
            magnitude_g=verdict.magnitude_g,
            withheld=verdict.withheld,
        )
    return None


class SensorReader(Actor):
    """Reads the sensor board's frames and publishes typed sensor messages."""

    class Params(ActorParams):
        config: ConfigFile | None = None
        """Robot configuration file; absent: the built-in defaults (= config/whexar.toml)."""
        port: str | None = None
        """Overrides ``sensor_board.port``: a device, a pty, ``emulator`` or ``emulator:NAME``,
        or ``replay:NAME`` for a recorded link played back (:mod:`whexar.sensors.replay`)."""
        baudrate: BoardBaudrate | None = None
        """Overrides ``sensor_board.baudrate`` (a rate the board's firmware can run at)."""
        protocol: Mode | None = None
        """Overrides ``sensor_board.protocol``: ``checked`` or ``thesis``."""
        stats_period_s: float = Field(1.0, gt=0)
        """How often :class:`SensorStats` is published."""

    params: Params
    frames = Output(SensorFrame, optional=True)
    ranges = Output(ObstacleRanges, optional=True)
    loads = Output(LegLoads, optional=True)
    tilt = Output(BodyTilt, optional=True)
    stats = Output(SensorStats, optional=True)

    # ----------------------------------------------------------------- set-up

    def _setup(self) -> None:
        p = self.params
        self.cfg: RobotConfig = load_config(p.config) if p.config else RobotConfig()
        board = self.cfg.sensor_board
        self.port = p.port if p.port is not None else board.port
        self.baudrate = p.baudrate if p.baudrate is not None else board.baudrate
        self.decoder = FrameDecoder(mode=p.protocol if p.protocol is not None else board.protocol)
        self.frame_period_s = 1.0 / board.frame_rate_hz
        self.stale_after_s = board.stale_after_frames * self.frame_period_s
        self.rate_command = f"rate={round(board.frame_rate_hz)}#".encode()
        ir = self.cfg.ir
        self._ir = (ir.k_cm, ir.exponent, ir.min_distance_mm / 1000, ir.max_distance_mm / 1000)
        self._fsr_on = self.cfg.fsr.contact_on_counts
        self._fsr_off = self.cfg.fsr.contact_off_counts
        acc = board.accelerometer
        self._acc_fitted = acc.fitted
        self._acc = tuple(zip(acc.zero_g_counts, acc.counts_per_g, strict=True))
        self.gravity = GravityCheck(acc.gravity_tolerance_g, acc.implausible_hold_s)
        self.contacts = [False] * 6
        self.last_valid = 0.0
        self.last_seq: int | None = None
        self.stale = False
        self.watching = False
        """Staleness is watched: a valid frame arrived on this connection."""
        self.reconnects = 0
        self._valid = anyio.Event()
        if self.port.startswith(f"{EMULATOR}:"):
            self._board()  # an unknown emulator name is a configuration error: fail now

    def _board(self) -> SensorBoardEmulator:
        if self.port == EMULATOR and (SENSOR_BOARD, EMULATOR) not in DEVICES:
            board = emulated_board(self.cfg.sensor_board, self.baudrate)
            DEVICES.register(SENSOR_BOARD, EMULATOR, board)
        name = self.port.removeprefix(f"{EMULATOR}:")
        return DEVICES.get(SENSOR_BOARD, name, setting=f"port = {self.port!r}")

    async def _open(self) -> ByteLink:
        tap = self.tap()
        try:
            link = await self._open_link()
        except DeviceGoneError as exc:
            if tap is not None:  # a replay opens as the recording did
                tap("gone", self.now(), str(exc).encode())
            raise
        if tap is None:
            return link
        tap("open", self.now(), b"")
        return TappedLink(link, tap, self.clock.now)

    async def _open_link(self) -> ByteLink:
        if self.port == EMULATOR or self.port.startswith(f"{EMULATOR}:"):
            return self._board().open(self.clock)
        if self.port.startswith(f"{REPLAYED_BOARD.scheme}:"):
            name = self.port.split(":", 1)[1]
            return DEVICES.get(REPLAYED_BOARD, name, setting=f"port = {self.port!r}").open(
                self.clock
            )
        self.clock.uses_real_io(f"sensor board port {self.port}")  # refused on virtual time
        return await SerialLink.open(self.port, self.baudrate)

    # ----------------------------------------------------------------- running

    async def run(self) -> None:
        self._setup()
        self.last_valid = self.now()
        async with anyio.create_task_group() as tg:
            tg.start_soon(self._watch_staleness)
            if self.stats.connected:
                tg.start_soon(self._report_stats)
            # Ready once the first attempt to open the port is over, whether
            # or not it succeeded: a missing board is an event, not a failure.
            await self._serve()

    async def _serve(self) -> None:
        first = True
        while True:
            link: ByteLink | None = None
            try:
                link = await self._open()
            except DeviceGoneError as exc:
                if first:
                    self._down(str(exc))
            if first:
                self.ready()
                first = False
            if link is not None:
                self.watching = False  # the board resets: silent until its first frame
                self.emit(SensorLinkUp(t=self.now(), source=self.name, link=self.port))
                try:
                    await self._read(link)
                except DeviceGoneError as exc:
                    self._down(str(exc))
                finally:
                    with self.shielded():
                        await link.aclose()
                self.reconnects += 1
            await self.clock.sleep(self.cfg.sensor_board.reconnect_period_s)

    def _down(self, reason: str) -> None:
        self.emit(SensorLinkDown(t=self.now(), source=self.name, link=self.port, reason=reason))

    async def _read(self, link: ByteLink) -> None:
        decoder = self.decoder
        decoder.clear(tail_expected=True)  # a board that did not reset may be mid-frame
        told_rate = False
        while True:
            data = await link.receive()
            for item in decoder.feed(data):
                if isinstance(item, Rejected):
                    self.emit(
                        SensorFrameRejected(
                            t=self.now(),
                            source=self.name,
                            link=self.port,
                            reason=item.reason,
                            size=item.size,
                            excerpt=item.excerpt,
                        )
                    )
                    continue
                if item.restarted:
                    told_rate = False  # a reset board is back at its build's rate
                await self._publish(item)
                if not told_rate:
                    told_rate = True
                    await link.send(self.rate_command)

    async def _publish(self, frame: Frame) -> None:
        t = self.now()
        if self.stale:
            self.stale = False
            self.emit(
                SensorLinkFresh(t=t, source=self.name, link=self.port, silent_s=t - self.last_valid)
            )
        self.last_valid = t
        self.last_seq = frame.seq
        self.watching = True
        self._valid.set()
        if frame.expected_seq is not None and (frame.missed or frame.restarted):
            self.emit(
                SensorFrameGap(
                    t=t,
                    source=self.name,
                    link=self.port,
                    expected=frame.expected_seq,
                    seq=frame.seq if frame.seq is not None else -1,
                    missed=frame.missed,
                    restarted=frame.restarted,
                )
            )
        distances = self._distances(frame.ir) if frame.ir is not None else None
        contacts = self._contacts(frame.fsr) if frame.fsr is not None else None
        tilt = self._tilt(frame.acc, frame.seq) if frame.acc is not None else None
        name, seq = self.name, frame.seq
        if self.frames.connected:
            await self.frames.send(
                SensorFrame(
                    t=t,
                    source=name,
                    seq=seq,
                    ir_counts=frame.ir,
                    ir_distances_m=distances,
                    fsr_counts=frame.fsr,
                    contacts=contacts,
                    acc_counts=frame.acc,
                    roll_rad=tilt[0] if tilt else None,
                    pitch_rad=tilt[1] if tilt else None,
                    missed=frame.missed,
                )
            )
        if frame.ir is not None and distances is not None:
            await self.ranges.send(
                ObstacleRanges(t=t, source=name, seq=seq, counts=frame.ir, distances_m=distances)
            )
        if frame.fsr is not None and contacts is not None:
            await self.loads.send(
                LegLoads(t=t, source=name, seq=seq, counts=frame.fsr, contacts=contacts)
            )
        if tilt is not None:
            roll, pitch, accel = tilt
            await self.tilt.send(
                BodyTilt(
                    t=t,
                    source=name,
                    seq=seq,
                    sensor="board",
                    roll_rad=roll,
                    pitch_rad=pitch,
                    accel_g=accel,
                )
            )

    # ----------------------------------------------------------------- conversions

    def _distances(self, counts: tuple[int, int]) -> tuple[float | None, float | None]:
        k, e, nearest, farthest = self._ir
        out: list[float | None] = []
        for c in counts:
            if c == 0:
                out.append(None)  # 0 V: no sensor output at all, so no reading
                continue
            d = ir_distance(float(c), k, e)
            out.append(math.inf if d > farthest else max(d, nearest))
        return out[0], out[1]

    def _contacts(self, counts: tuple[int, ...]) -> tuple[bool, bool, bool, bool, bool, bool]:
        flags = self.contacts
        for leg, c in enumerate(counts):
            if c >= self._fsr_on:
                flags[leg] = True
            elif c < self._fsr_off:
                flags[leg] = False
        return flags[0], flags[1], flags[2], flags[3], flags[4], flags[5]

    def _tilt(
        self, counts: tuple[int, int, int], seq: int | None
    ) -> tuple[float, float, tuple[float, float, float]] | None:
        if not self._acc_fitted:
            return None  # counts from an unfitted sensor's open inputs mean nothing
        (zx, gx), (zy, gy), (zz, gz) = self._acc
        accel = ((counts[0] - zx) / gx, (counts[1] - zy) / gy, (counts[2] - zz) / gz)
        verdict = self.gravity.check(accel, self.now())
        event = gravity_event(
            verdict,
            accel,
            self.gravity.tolerance_g,
            t=self.now(),
            source=self.name,
            link=self.port,
            sensor="board",
            seq=seq,
        )
        if event is not None:
            self.emit(event)
        if verdict.tilt is None:
            return None
        return verdict.tilt[0], verdict.tilt[1], accel

    # ----------------------------------------------------------------- watchdogs

    async def _watch_staleness(self) -> None:
        # Armed by a valid frame (``watching``), disarmed when a connection
        # opens and when it has said stale; a frame re-arms it.
        while True:
            if self.watching and not self.stale:
                deadline = self.last_valid + self.stale_after_s
                if self.now() < deadline:
                    await self.clock.sleep_until(deadline)
                    continue
                self.stale = True
                self.emit(
                    SensorLinkStale(
                        t=self.now(),
                        source=self.name,
                        link=self.port,
                        silent_s=self.now() - self.last_valid,
                        last_seq=self.last_seq,
                    )
                )
            self._valid = anyio.Event()
            await self._valid.wait()

    async def _report_stats(self) -> None:
        period = self.params.stats_period_s
        next_t = self.now() + period
        while True:
            await self.clock.sleep_until(next_t)
            next_t += period
            s = self.decoder.stats
            await self.stats.send(
                SensorStats(
                    t=self.now(),
                    source=self.name,
                    link=self.port,
                    frames=s.frames,
                    rejected=s.rejected,
                    missed=s.missed,
                    unknown_keys=s.unknown_keys,
                    garbage_bytes=s.garbage_bytes,
                    reconnects=self.reconnects,
                )
            )
