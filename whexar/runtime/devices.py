"""In-process devices: emulators and fakes that edge actors open by name instead of a port.

Theory of operation
-------------------
An actor that owns a device link (a servo bus, a sensor board's serial line,
an I²C adapter) is told where the device is by a string in its
configuration: a device path on the robot, or ``SCHEME:NAME`` for a device
that lives in this process — a servo emulator, an emulated sensor board, a
fake I²C bus — made by a test, a benchmark or the simulator. This registry
is where such devices are found: one table for every kind, keyed by the
kind and the name, with one error text for a name nobody registered.

A device registered here outlives the actor that opens it (it is the
hardware), so a restarted actor finds the device as its predecessor left it.
The registry holds no robot knowledge: each device package declares its
own :class:`DeviceKind`, typed with the class it registers::

    SERVO_CHAIN: Final = DeviceKind[ServoChain]("emulated servo chain", "emulator")

    DEVICES.register(SERVO_CHAIN, "test", chain)    # port = "emulator:test"
    chain = DEVICES.get(SERVO_CHAIN, "test", setting="port = 'emulator:test'")
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Final, Generic, TypeVar, cast

from whexar.runtime.errors import UsageError

D = TypeVar("D")


@dataclass(frozen=True)
class DeviceKind(Generic[D]):
    """One kind of in-process device, named in words (errors quote it) and by its port scheme."""

    name: str
    """What it is, as an error says it: ``"emulated servo chain"``."""
    scheme: str
    """The prefix of its port string: ``"emulator"`` for ``"emulator:NAME"``."""

    def port(self, name: str) -> str:
        """The port string that opens the device registered as ``name``."""
        return f"{self.scheme}:{name}"


class DeviceRegistry:
    """In-process devices by kind and name (see the module docstring)."""

    def __init__(self) -> None:
        self._devices: dict[tuple[DeviceKind[Any], str], object] = {}

    def register(self, kind: DeviceKind[D], name: str, device: D) -> None:
        """Make ``device`` the one opened as ``kind.scheme:name`` (replacing any before it)."""
        self._devices[(kind, name)] = device

    def unregister(self, kind: DeviceKind[Any], name: str) -> None:
        """Forget the device registered as ``name`` (nothing happens if there is none)."""
        self._devices.pop((kind, name), None)

    def clear(self, kind: DeviceKind[Any]) -> None:
        """Forget every device of ``kind``."""
        for key in [key for key in self._devices if key[0] == kind]:
            del self._devices[key]

    def names(self, kind: DeviceKind[Any]) -> list[str]:
        """The names registered for ``kind``, sorted."""
        return sorted(name for k, name in self._devices if k == kind)

    def __contains__(self, key: tuple[DeviceKind[Any], str]) -> bool:
        return key in self._devices

    def get(self, kind: DeviceKind[D], name: str, *, setting: str) -> D:
        """The device registered as ``name``; ``setting`` is what asked for it, for the error.

        An unknown name is a :class:`~whexar.runtime.errors.UsageError` naming
        the setting, the kind, the names registered and how to register one.
        """
        try:
            return cast(D, self._devices[(kind, name)])
        except KeyError:
            known = ", ".join(self.names(kind)) or "none"
            raise UsageError(
                f"{setting}: no {kind.name} registered as {name!r} (registered: {known}); "
                f"register one with whexar.runtime.devices.DEVICES.register()"
            ) from None

    @contextmanager
    def registered(self, kind: DeviceKind[D], name: str, device: D) -> Iterator[D]:
        """Register ``device`` for the ``with`` block, then forget it."""
        self.register(kind, name, device)
        try:
            yield device
        finally:
            self.unregister(kind, name)


DEVICES: Final = DeviceRegistry()
"""The process's one registry of in-process devices."""
