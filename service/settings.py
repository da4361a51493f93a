"""Service limits, from the environment (``QUADSYNTH_<NAME>``), published at ``GET /v1/limits``."""

from __future__ import annotations

import os
from dataclasses import dataclass, fields

from api_schemas import Limits
from api_schemas.delta import MAX_ERROR_M as DELTA_MAX_ERROR_M
from api_schemas.wire import BYTES_PER_JOINT_FRAME, DELTA_BYTES_PER_JOINT_FRAME, ENCODING_ERROR


@dataclass(frozen=True)
class Settings:
    max_body_bytes: int = 8 * 1024 * 1024
    max_characters: int = 10_000
    max_frames: int = 20_000
    max_character_frames: int = 2_000_000  # s48 output: 480 MB for a 40-joint animal
    max_in_flight: int = 1  # synthesis already uses every core of the process
    max_queued: int = 4
    deadline_s: float = 60.0
    ws_chunk_frames: int = 30
    ws_window: int = 8
    ws_send_timeout_s: float = 10.0
    drain_grace_s: float = 20.0
    memory_budget_mb: int = 1024  # answers in flight x their estimated size, per worker (service.budget)
    answer_buffer_bytes: int = 16 * 1024 * 1024  # made and not yet sent, per answer (service.pipe)
    send_timeout_s: float = 10.0  # a client taking nothing for this long: its answer is cut short
    body_timeout_s: float = 30.0  # a request body not arriving whole within this: 408
    test_hooks: bool = False  # routes that hold the workers on an event (tests only)
    memory_tuning: bool = True  # freed memory kept, no huge pages for numpy: see service.memory

    @classmethod
    def from_env(cls) -> Settings:
        values: dict[str, object] = {}
        for f in fields(cls):
            raw = os.environ.get(f"QUADSYNTH_{f.name.upper()}")
            if raw is None:
                continue
            kind = type(getattr(cls, f.name))
            try:
                values[f.name] = raw.lower() in ("1", "true", "yes") if kind is bool else kind(raw)
            except ValueError:
                name = f"QUADSYNTH_{f.name.upper()}"
                raise SystemExit(f"{name}: expected a {kind.__name__}, got {raw!r}") from None
            if kind is not bool and values[f.name] <= 0:  # type: ignore[operator]
                raise SystemExit(f"QUADSYNTH_{f.name.upper()}: must be positive, got {raw!r}")
        return cls(**values)  # type: ignore[arg-type]

    def published(self) -> Limits:
        return Limits(
            max_body_bytes=self.max_body_bytes, max_characters=self.max_characters,
            max_frames=self.max_frames, max_character_frames=self.max_character_frames,
            max_in_flight=self.max_in_flight, max_queued=self.max_queued, deadline_s=self.deadline_s,
            ws_chunk_frames=self.ws_chunk_frames, ws_window=self.ws_window,
            ws_send_timeout_s=self.ws_send_timeout_s, memory_budget_mb=self.memory_budget_mb,
            send_timeout_s=self.send_timeout_s, body_timeout_s=self.body_timeout_s,
            encodings={e: {"bytes_per_joint_frame": BYTES_PER_JOINT_FRAME[e],
                           "max_error_deg": ENCODING_ERROR[e][0],
                           "max_error_mm_at_3cm": ENCODING_ERROR[e][1]} for e in BYTES_PER_JOINT_FRAME}
            | {"delta": {"bytes_per_joint_frame": DELTA_BYTES_PER_JOINT_FRAME,
                         "max_world_error_mm": DELTA_MAX_ERROR_M * 1000.0}})
