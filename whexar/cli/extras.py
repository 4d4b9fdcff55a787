"""Which extra of the package brings a module: the one line a command prints when it
needs what the plain install (the robot's) leaves out.

The extras are declared in ``pyproject.toml``; :data:`EXTRAS` names, for each module
they bring, the extra to install.
"""

from __future__ import annotations

__all__ = ["EXTRAS", "missing_extra"]

#: Top-level module → the extra that installs it (``pip install 'whexar[EXTRA]'``).
EXTRAS: dict[str, str] = {
    "mujoco": "sim",
    "imageio": "sim",
    "imageio_ffmpeg": "sim",
    "matplotlib": "plots",
    "foxglove": "live",
    "ray": "cluster",
}


def missing_extra(exc: ModuleNotFoundError) -> str | None:
    """The line to print for ``exc`` if the missing module is an extra's, else ``None``
    (a module missing for another reason is a bug, with its traceback)."""
    top = (exc.name or "").partition(".")[0]
    extra = EXTRAS.get(top)
    if extra is None:
        return None
    return (
        f"this command needs {top}, which the plain install leaves out: "
        f"pip install 'whexar[{extra}]' (or 'whexar[all]')"
    )
