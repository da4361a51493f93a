"""WebSocket ``/v1/stream``: batches in chunks and live sessions (docs/streaming.md)."""

from __future__ import annotations

from fastapi import APIRouter, WebSocket

from service import batch_ws
from service.state import state_of

router = APIRouter()


@router.websocket("/v1/stream")
async def stream_route(ws: WebSocket) -> None:
    """Batch streaming over WebSocket: binary msgpack messages, docs/streaming.md."""
    await batch_ws.session(ws, state_of(ws))
