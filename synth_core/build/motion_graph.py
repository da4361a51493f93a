"""The motion graph (Sung 2011, section 4): gait hubs, speed-map edges, transitions between hubs.

Hub nodes are ``static, walk, trot, canter, gallop`` (those the library has). Each gait hub's
edges are its speed-map clips (loops back to the hub: any clip of a gait may follow any other of
the same gait, as they share frames and contacts); the static hub's edge is the idle clip.
Transitions join adjacent hubs in both directions, ``static <-> walk <-> trot <-> canter <->
gallop``; a character starts standing and moves one hub at a time, as in the paper.

The queries the synthesis needs: the two clips of a gait bracketing a speed, the gaits whose
range covers a speed, the legal next gait toward a speed, and the route between two hubs.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from synth_core.build.speed_map import SpeedMap

HUBS = ("static", "walk", "trot", "canter", "gallop")
STILL_SPEED = 1e-3  # m/s: at or below this, standing


def transition_name(source: str, target: str) -> str:
    return f"{source}2{target}"


@dataclass(frozen=True)
class Transition:
    name: str
    source: str
    target: str
    generated: bool  # blended at build time because the data had no such clip


@dataclass(frozen=True, eq=False)
class MotionGraph:
    maps: Mapping[str, SpeedMap]  # gait -> its speed map
    transitions: Mapping[str, Transition]  # name -> transition

    def __post_init__(self) -> None:
        for gait in self.maps:
            if gait not in HUBS[1:]:
                raise ValueError(f"motion graph: unknown gait {gait!r}; gaits are {list(HUBS[1:])}")
        for name, t in self.transitions.items():
            if t.source not in self.nodes or t.target not in self.nodes:
                raise ValueError(f"motion graph: transition {name} joins a missing hub")
            if abs(HUBS.index(t.source) - HUBS.index(t.target)) != 1:
                raise ValueError(f"motion graph: transition {name} must join adjacent hubs")

    @property
    def nodes(self) -> list[str]:
        return [h for h in HUBS if h == "static" or h in self.maps]

    @property
    def n_edges(self) -> int:
        """Speed-map clips (one edge each), the idle loop, and the transitions."""
        return sum(m.n_clips for m in self.maps.values()) + 1 + len(self.transitions)

    def speed_range(self, gait: str) -> tuple[float, float]:
        if gait == "static":
            return (0.0, STILL_SPEED)
        speeds = self._map(gait).speeds
        return float(speeds[0]), float(speeds[-1])

    def bracket(self, gait: str, speed: float) -> tuple[int, int, float]:
        """Clips ``i <= j`` of ``gait`` around ``speed`` and the weight of ``j`` (clamped at the ends)."""
        return self._map(gait).bracket(speed)

    def gaits_covering(self, speed: float) -> list[str]:
        """Hubs whose speed range holds ``speed`` (m/s), slow to fast; several where ranges overlap."""
        return [g for g in self.nodes
                if self.speed_range(g)[0] - 1e-9 <= speed <= self.speed_range(g)[1] + 1e-9]

    def neighbours(self, hub: str) -> list[str]:
        return [t.target for t in self.transitions.values() if t.source == hub]

    def next_gait(self, current: str, speed: float) -> str:
        """The hub to be in next for ``speed``: stay while the current range covers it, else one
        hub toward it (only along a transition). Speeds beyond every range head for the end hub."""
        low, high = self.speed_range(current)
        if low - 1e-9 <= speed <= high + 1e-9:
            return current
        step = 1 if speed > high else -1
        i = HUBS.index(current) + step
        while 0 <= i < len(HUBS) and HUBS[i] not in self.nodes:
            i += step
        if not 0 <= i < len(HUBS) or HUBS[i] not in self.neighbours(current):
            return current
        return HUBS[i]

    def route(self, source: str, target: str) -> list[Transition]:
        """Transitions from one hub to another, one hub at a time; raises if the graph breaks."""
        path: list[Transition] = []
        here = source
        while here != target:
            step = 1 if HUBS.index(target) > HUBS.index(here) else -1
            there = next((h for h in self.neighbours(here)
                          if HUBS.index(h) - HUBS.index(here) == step), None)
            if there is None:
                raise ValueError(f"motion graph: no transition from {here} toward {target}")
            path.append(self.transitions[transition_name(here, there)])
            here = there
        return path

    def connected(self, source: str, target: str) -> bool:
        try:
            self.route(source, target)
        except ValueError:
            return False
        return True

    def _map(self, gait: str) -> SpeedMap:
        try:
            return self.maps[gait]
        except KeyError:
            raise KeyError(f"motion graph: no speed map for {gait!r}; have {list(self.maps)}") from None
