"""Recordings: every message and every byte of a run in one MCAP file, and using them.

* :mod:`~whexar.record.writer` — the recorder (the runtime's observer) and its MCAP writer;
* :mod:`~whexar.record.sidecar` — the same recorder in a process of its own, fed over a pipe;
* :mod:`~whexar.record.budget` — the recordings folder kept within its budget on the disk;
* :mod:`~whexar.record.encoding` — JSON and JSON Schemas of the message types, link bytes;
* :mod:`~whexar.record.reader` — reading back, cut files too; ``whexar log recover``;
* :mod:`~whexar.record.info` — ``whexar log info``;
* :mod:`~whexar.record.series` and :mod:`~whexar.record.plots` — ``whexar plot``: what a
  recording's plots need, read once, and the drawing;
* :mod:`~whexar.record.live` and :mod:`~whexar.record.foxglove` — the live view, Foxglove's
  schemas and the shipped layout;
* :mod:`~whexar.record.replay` — ``whexar replay``: the devices played back through the same
  actors, and ``--check``.

May import: :mod:`whexar.actors` and everything below them; never :mod:`whexar.testing`,
:mod:`whexar.sim`, :mod:`whexar.bench` or :mod:`whexar.cli`.
"""
