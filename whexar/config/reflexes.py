"""The reflexes the robot runs (``[[reflexes]]``): which class, its name, rank and
parameters. Each becomes one actor of the robot's graph
(:mod:`whexar.actors.reactive.layer`), where its class and parameters are checked."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Field, StringConstraints

from whexar.runtime.schema import Section

ReflexName = Annotated[str, StringConstraints(pattern=r"^[a-z][a-z0-9_-]*$", max_length=40)]
"""A reflex's name: lower case, digits, ``-`` and ``_`` (its actor is ``reflex-NAME``)."""


class ReflexEntry(Section):
    """One ``[[reflexes]]`` entry."""

    type: Annotated[str, StringConstraints(min_length=1)]
    """Its class: ``package.module:Class``, or its name in the ``whexar.reflexes`` entry
    points."""
    name: ReflexName | None = None
    """Its name (events, activity, the overrides' source); absent: its entry point's name,
    or its class's in lower case. An entry of the robot configuration replaces the
    graph's entry of the same name (``enabled = false`` leaves that reflex out)."""
    priority: int | None = None
    """Its rank when reflexes give one joint goals in one cycle; absent: the class's."""
    inhibits: tuple[ReflexName, ...] = ()
    """Reflexes it holds back while active, beside those its class names."""
    enabled: bool = True
    """``false`` keeps the entry written down but leaves the reflex out."""
    params: dict[str, Any] = Field(default_factory=dict)
    """Its parameters, checked against its class's ``Params``."""
