"""The ``whexar`` command line: one module per command group, assembled here.

* :mod:`~whexar.cli.config` — ``whexar config check | schema``;
* :mod:`~whexar.cli.kin` — ``whexar kin ik | fk | gait``;
* :mod:`~whexar.cli.run` — ``whexar run``: an actor graph from a wiring file;
* :mod:`~whexar.cli.bus` — ``whexar emulate``, ``whexar bus scan``;
* :mod:`~whexar.cli.sensors` — ``whexar sensors``: the sensor-board monitor;
* :mod:`~whexar.cli.bench` — ``whexar bench kin | runtime | bus | sensors | cycle | sim |
  record``;
* :mod:`~whexar.cli.model` — ``whexar model --mjcf | --urdf``: the simulation model;
* :mod:`~whexar.cli.sim` — ``whexar sim``: the simulated WHexaR on a scenario;
* :mod:`~whexar.cli.log` — ``whexar log info | recover``: recordings;
* :mod:`~whexar.cli.plot` — ``whexar plot``: plots from a recording;
* :mod:`~whexar.cli.replay` — ``whexar replay``: a recording played back, and checked;
* :mod:`~whexar.cli.service` — ``whexar service install | status | logs``: systemd;
* :mod:`~whexar.cli.doctor` — ``whexar doctor``: is the robot ready;
* :mod:`~whexar.cli.common` — what they share;
* :mod:`~whexar.cli.extras` — which extra a missing module comes with.

A group adds its commands with ``add_commands(commands)``; each command
imports what it needs when it runs, so ``whexar --help`` stays fast. The
top layer: it may import every other package of whexar.

Exit codes: 0 success; 1 a configuration with problems, a benchmark that
missed its target, a bus scan that found no servo (or could not open its
port), a replay that diverged from its recording, a doctor with a failed check,
or a command that needs an extra the install left out (:mod:`~whexar.cli.extras`);
2 bad input (an unknown leg, an unreachable target, a malformed option); 3 ``whexar run`` stopped
after an actor was escalated; 4 ``whexar run`` stopped because a device was missing, busy
or not permitted when its actor started (``whexar doctor`` says how to fix it).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from whexar import __version__
from whexar.cli import (
    bench,
    bus,
    campaign,
    config,
    doctor,
    kin,
    log,
    model,
    plot,
    replay,
    run,
    sensors,
    service,
    sim,
)
from whexar.cli.common import Handler
from whexar.cli.extras import missing_extra
from whexar.errors import ConfigError, UsageError


def build_parser() -> argparse.ArgumentParser:
    """The whole ``whexar`` command tree."""
    parser = argparse.ArgumentParser(
        prog="whexar", description="WHexaR, the wheeled hexapod: runtime and tools."
    )
    parser.add_argument("--version", action="version", version=f"whexar {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in (config, kin, bench, run, bus, sensors, model, sim, campaign, log, plot, replay):
        group.add_commands(commands)
    service.add_commands(commands)
    doctor.add_commands(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``whexar`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Handler = args.handler
    try:
        return handler(args)
    except ConfigError as exc:
        print(f"whexar: {exc}", file=sys.stderr)
        return 1
    except UsageError as exc:
        print(f"whexar: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        line = missing_extra(exc)
        if line is None:
            raise
        print(f"whexar: {line}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # The reader went away (``whexar log info … | head``): stop quietly, and keep
        # Python from complaining again when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
