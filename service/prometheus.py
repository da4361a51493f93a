"""Prometheus text metrics, kept per worker process, and the middleware that counts requests.

Each uvicorn worker process has its own counters (a scrape reaches one of them); the
``pid`` label tells them apart so a collector can sum.
"""

from __future__ import annotations

import gc
import os
from collections import Counter
from collections.abc import Collection
from dataclasses import dataclass, field
from typing import Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send


@dataclass
class Metrics:
    requests: Counter[tuple[str, str, int]] = field(default_factory=Counter)  # (method, route, status)
    rejected: Counter[str] = field(default_factory=Counter)  # reason -> count
    character_frames: int = 0
    synthesis_seconds: float = 0.0
    syntheses: int = 0
    cancelled: int = 0  # syntheses stopped before their end: the client left or the deadline passed
    in_flight: int = 0
    ws_sessions: int = 0
    memory_tuning: dict[str, bool] = field(default_factory=dict)  # service.memory.tune()'s, if run
    memory_reserved: int = 0  # bytes of the memory budget answers in flight hold (service.budget)
    pipes: Collection[Any] = ()  # answers going out (service.pipe.Pipe): produced, waiting, blocked
    answer_bytes: int = 0  # bytes of answers made, of the pipes gone

    def render(self) -> str:
        pid = os.getpid()
        lines = [
            "# HELP quadsynth_requests_total HTTP requests by method, route and status.",
            "# TYPE quadsynth_requests_total counter",
        ]
        for (method, route, status), n in sorted(self.requests.items()):
            lines.append(f'quadsynth_requests_total{{pid="{pid}",method="{method}",route="{route}",'
                         f'status="{status}"}} {n}')
        lines += ["# HELP quadsynth_rejected_total Requests refused before synthesis, by reason.",
                  "# TYPE quadsynth_rejected_total counter"]
        for reason, n in sorted(self.rejected.items()):
            lines.append(f'quadsynth_rejected_total{{pid="{pid}",reason="{reason}"}} {n}')
        lines += [
            "# HELP quadsynth_character_frames_total Character-frames synthesized.",
            "# TYPE quadsynth_character_frames_total counter",
            f'quadsynth_character_frames_total{{pid="{pid}"}} {self.character_frames}',
            "# HELP quadsynth_synthesis_seconds Time spent synthesizing (sum and count).",
            "# TYPE quadsynth_synthesis_seconds summary",
            f'quadsynth_synthesis_seconds_sum{{pid="{pid}"}} {self.synthesis_seconds:.6f}',
            f'quadsynth_synthesis_seconds_count{{pid="{pid}"}} {self.syntheses}',
            "# HELP quadsynth_cancelled_total Syntheses stopped before their end (client gone, deadline).",
            "# TYPE quadsynth_cancelled_total counter",
            f'quadsynth_cancelled_total{{pid="{pid}"}} {self.cancelled}',
            "# HELP quadsynth_in_flight Synthesis requests running or queued now.",
            "# TYPE quadsynth_in_flight gauge",
            f'quadsynth_in_flight{{pid="{pid}"}} {self.in_flight}',
            "# HELP quadsynth_websocket_sessions Open WebSocket sessions.",
            "# TYPE quadsynth_websocket_sessions gauge",
            f'quadsynth_websocket_sessions{{pid="{pid}"}} {self.ws_sessions}',
            "# HELP quadsynth_memory_reserved_bytes Memory budget held by answers in flight (estimated).",
            "# TYPE quadsynth_memory_reserved_bytes gauge",
            f'quadsynth_memory_reserved_bytes{{pid="{pid}"}} {self.memory_reserved}',
            "# HELP quadsynth_answer_bytes_produced_total Bytes of answers made (handed to their sockets).",
            "# TYPE quadsynth_answer_bytes_produced_total counter",
            f'quadsynth_answer_bytes_produced_total{{pid="{pid}"}} '
            f'{self.answer_bytes + sum(p.produced for p in self.pipes)}',
            "# HELP quadsynth_answer_bytes_waiting Bytes of answers made and not yet sent.",
            "# TYPE quadsynth_answer_bytes_waiting gauge",
            f'quadsynth_answer_bytes_waiting{{pid="{pid}"}} {sum(p.pending for p in self.pipes)}',
            "# HELP quadsynth_answers_blocked Answers whose making waits for a client to read.",
            "# TYPE quadsynth_answers_blocked gauge",
            f'quadsynth_answers_blocked{{pid="{pid}"}} {sum(p.blocked for p in self.pipes)}',
            "# HELP python_gc_collections_total Runs of the cyclic garbage collector, by generation "
            "(a full one, 2, pauses the process).",
            "# TYPE python_gc_collections_total counter",
            *(f'python_gc_collections_total{{pid="{pid}",generation="{g}"}} {stats["collections"]}'
              for g, stats in enumerate(gc.get_stats())),
            "# HELP quadsynth_gc_frozen_objects Objects start-up made, kept out of full collections.",
            "# TYPE quadsynth_gc_frozen_objects gauge",
            f'quadsynth_gc_frozen_objects{{pid="{pid}"}} {gc.get_freeze_count()}',
            "# HELP quadsynth_memory_tuning Allocation settings this worker took (service.memory).",
            "# TYPE quadsynth_memory_tuning gauge",
            *(f'quadsynth_memory_tuning{{pid="{pid}",setting="{name}"}} {int(took)}'
              for name, took in sorted(self.memory_tuning.items())),
        ]
        return "\n".join(lines) + "\n"


# Any other method is counted as "other": the label must not take whatever a client invents
# (20,000 made-up methods grew /metrics to 20,037 lines, issue 34).
METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})


def route_name(scope: Scope) -> str:
    """The route template of a request: an API route's own; a plain route's path (/docs,
    /openapi.json: FastAPI does not put those in the scope); else "unmatched"."""
    route = scope.get("route")
    name = getattr(route, "path", None)
    if name:
        return str(name)
    app = scope.get("app")
    plain = {getattr(r, "path", None) for r in getattr(app, "routes", ())
             if "{" not in str(getattr(r, "path", "{"))}
    return str(scope["path"]) if scope.get("path") in plain else "unmatched"


class MetricsMiddleware:
    """Counts every HTTP response by its route template (not the raw path: an unknown URL must
    not make a new series) and its method (one of ``METHODS``, else "other")."""

    def __init__(self, app: ASGIApp, metrics: Metrics) -> None:
        self.app, self.metrics = app, metrics

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        status = 500

        async def counted(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, counted)
        finally:
            method = scope["method"] if scope["method"] in METHODS else "other"
            self.metrics.requests[(method, route_name(scope), status)] += 1
