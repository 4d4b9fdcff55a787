"""Every test: runs that record by default (``whexar sim``, ``whexar run``) write into the
test's own folder, never into the working tree."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _recordings_in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("WHEXAR_RECORDINGS", str(tmp_path / "recordings"))
