"""What the reflexes ask of the coordinator, by reflex (:class:`ReflexRequest`).

The operator's command is what the robot wants (:mod:`.intent`); the reflexes'
requests bend it while they last: a step at least as high as the highest
asked for, raised by the largest raise asked (never above
``locomotion.max_step_height_mm``), the body held still
while any reflex halts it, no forward translation while any blocks the way ahead, the
turn rate corrected by the sum of the heading
corrections while the body translates, swings that search as deep as the deepest
search asked, the trochanters at the largest angle asked, and one leg stepped again at
a time (the latest request). Each
reflex's request replaces its own
earlier one, field by field, and is withdrawn the same way (0, ``False``), so
two reflexes never undo each other. A plain class: the planner asks it.
"""

from __future__ import annotations

import math

from whexar.actors.messages import ReflexRequest, Vec3


class Asks:
    """The reflexes' standing requests (module docstring)."""

    def __init__(self, max_step_height_m: float) -> None:
        self.max_step_height_m = max_step_height_m
        self.step_heights: dict[str, float] = {}
        self.raises: dict[str, float] = {}
        self.halts: dict[str, str] = {}
        """reflex → why it halts the body."""
        self.blocks: dict[str, str] = {}
        """reflex → why nothing goes forward."""
        self.turns: dict[str, float] = {}
        self.sit: tuple[str, str] | None = None
        """(reflex, why) of the first request to sit down, once made."""
        self.depths: dict[str, float] = {}
        """reflex → how deep its swings search."""
        self.reaches: dict[str, float] = {}
        """reflex → how far its stance feet reach down for ground they lost."""
        self.trochanters: dict[str, float] = {}
        """reflex → the trochanter angle it asks for (rad)."""
        self.restep: ReflexRequest | None = None
        """The request to step a leg again, until the planner takes it."""

    def take(self, req: ReflexRequest) -> bool:
        """Merge one request; True if it asks to sit down for the first time."""
        who = req.reflex
        if req.step_height_m is not None and math.isfinite(req.step_height_m):
            if req.step_height_m > 0.0:
                self.step_heights[who] = req.step_height_m
            else:
                self.step_heights.pop(who, None)
        if req.step_raise_m is not None and math.isfinite(req.step_raise_m):
            if req.step_raise_m > 0.0:
                self.raises[who] = req.step_raise_m
            else:
                self.raises.pop(who, None)
        if req.halt is not None:
            if req.halt:
                self.halts[who] = req.reason
            else:
                self.halts.pop(who, None)
        if req.block_ahead is not None:
            if req.block_ahead:
                self.blocks[who] = req.reason
            else:
                self.blocks.pop(who, None)
        if req.yaw_rate_rad_s is not None and math.isfinite(req.yaw_rate_rad_s):
            if req.yaw_rate_rad_s != 0.0:
                self.turns[who] = req.yaw_rate_rad_s
            else:
                self.turns.pop(who, None)
        if req.search_depth_m is not None and math.isfinite(req.search_depth_m):
            if req.search_depth_m > 0.0:
                self.depths[who] = req.search_depth_m
            else:
                self.depths.pop(who, None)
        if req.reach_depth_m is not None and math.isfinite(req.reach_depth_m):
            if req.reach_depth_m > 0.0:
                self.reaches[who] = req.reach_depth_m
            else:
                self.reaches.pop(who, None)
        if req.trochanter_rad is not None and math.isfinite(req.trochanter_rad):
            if req.trochanter_rad != 0.0:
                self.trochanters[who] = req.trochanter_rad
            else:
                self.trochanters.pop(who, None)
        if req.restep_leg is not None:
            self.restep = req
        if req.sit_down and self.sit is None:
            self.sit = (who, req.reason)
            return True
        return False

    def twist(self, wanted: Vec3) -> Vec3:
        """The twist to move toward: ``wanted`` halted or its turn corrected."""
        if self.halts:
            return (0.0, 0.0, 0.0)
        vx, vy, w = wanted
        if self.blocks:
            vx = min(vx, 0.0)
        if self.turns and (vx or vy):
            w += sum(self.turns.values())
        return (vx, vy, w)

    def trochanter(self) -> float | None:
        """The trochanter angle asked for: the largest in magnitude; None: none asked."""
        return max(self.trochanters.values(), key=abs, default=None)

    def search_depth(self) -> float:
        """How deep a swing searches for ground it does not find: the deepest asked."""
        return max(self.depths.values(), default=0.0)

    def reach_depth(self) -> float:
        """How far a stance foot reaches down for ground it lost: the deepest asked."""
        return max(self.reaches.values(), default=0.0)

    def step_height(self, wanted: float) -> float:
        """The step height to swing with: at least the highest asked, raised by the largest
        raise asked, within the limit."""
        if not self.step_heights and not self.raises:
            return wanted
        base = max([wanted, *self.step_heights.values()])
        return min(base + max(self.raises.values(), default=0.0), self.max_step_height_m)
