"""The robot's plain install: its graph runs, records and replays without any extra,
and a command that needs one says in one line which to install (issue: light install).

Each process here starts with the extras' modules made unimportable, as on a robot
where ``pip install whexar`` left them out: a ``sitecustomize`` on ``PYTHONPATH``
installs an import hook that refuses them, in every process the commands start.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from whexar.cli.extras import EXTRAS
from whexar.testing.field import ROOT, record_field_log, write_script

BLOCKER = f"""
import os, sys

BLOCKED = {tuple(sorted(EXTRAS))!r}


class _PlainInstall:
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
        return None


sys.meta_path.insert(0, _PlainInstall())
with open(os.environ["WHEXAR_TEST_MARKER"], "a") as marker:
    marker.write(f"{{os.getpid()}}\\n")
"""


@pytest.fixture
def plain_install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Every process started from here on lacks the extras; returns the file where each
    such process writes its PID, which proves the hook ran."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(BLOCKER)
    marker = tmp_path / "pids"
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(hook), str(ROOT)]))
    monkeypatch.setenv("WHEXAR_TEST_MARKER", str(marker))
    return marker


def _whexar(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "whexar.cli", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
        check=False,
    )


def test_the_hook_refuses_every_extra(plain_install: Path) -> None:
    code = "import importlib\n" + "".join(
        f"try:\n    importlib.import_module({m!r})\n    print('imported', {m!r})\n"
        f"except ModuleNotFoundError:\n    pass\n"
        for m in EXTRAS
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    assert plain_install.read_text().count("\n") == 1


@pytest.mark.slow  # records on the wall clock, against the emulator over a pty
@pytest.mark.serial  # a log of real time: the emulator must keep pace
def test_the_robots_graph_runs_records_and_replays_with_the_plain_install(
    plain_install: Path, tmp_path: Path
) -> None:
    script = write_script(tmp_path / "walk.jsonl", [{"t": 2.0, "vx_m_s": 0.08}])
    log = record_field_log(tmp_path / "walk.mcap", script=script, duration_s=4.0)
    # The emulator, the runtime and the recorder's own process: each one had the hook.
    assert plain_install.read_text().count("\n") >= 3
    info = _whexar("log", "info", str(log))
    assert info.returncode == 0, info.stderr
    assert "servo_states" in info.stdout or "/servo" in info.stdout, info.stdout
    checked = _whexar("replay", str(log), "--check", "--fast")
    assert checked.returncode == 0, checked.stdout + checked.stderr
    # Plots are an extra: the one line, not a traceback.
    plot = _whexar("plot", str(log), "-o", str(tmp_path / "plot.png"))
    assert plot.returncode == 1
    assert plot.stderr.strip() == (
        "whexar: this command needs matplotlib, which the plain install leaves out: "
        "pip install 'whexar[plots]' (or 'whexar[all]')"
    )


@pytest.mark.parametrize(
    ("args", "extra"),
    [
        (("sim", "--duration", "1", "--no-record"), "sim"),
        (("bench", "sim"), "sim"),
        (("run", str(ROOT / "config" / "graphs" / "walk.toml"), "--live"), "live"),
    ],
)
def test_a_command_needing_an_extra_names_it_in_one_line(
    plain_install: Path, args: tuple[str, ...], extra: str
) -> None:
    done = _whexar(*args)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert f"pip install 'whexar[{extra}]'" in lines[0]
