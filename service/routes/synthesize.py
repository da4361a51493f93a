"""``POST /v1/synthesize``: a batch of trajectories in, its motion out (sent while it is made)."""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, Request
from fastapi.responses import Response

from api_schemas import SynthesizeRequest, SynthesizeResponse
from service import body, jobs
from service.errors import ApiError
from service.openapi import binary_body, errors
from service.packing import skeleton_id
from service.rest_answer import respond
from service.state import state_of

SMALL_BODY = 64 * 1024  # bodies below this are decoded on the event loop (a thread costs more)

router = APIRouter(tags=["synthesis"])


@router.post("/v1/synthesize",
             responses={200: binary_body(SynthesizeResponse, "motion per character"),
                        **errors(404, 408, 413, 415, 422, 503, 504)},
             openapi_extra={"requestBody": {"required": True, **binary_body(
                 SynthesizeRequest, "characters' trajectories and options")}})
async def synthesize(request: Request) -> Response:
    """Trajectories in, packed joint-rotation streams out (docs/wire-format.md).

    Body and answer in msgpack (``application/vnd.msgpack``, also ``application/x-msgpack``,
    ``application/msgpack``) or JSON, by Content-Type and Accept. The same body and seed
    give byte-identical answers."""
    state = state_of(request)
    settings, registry = state.settings, state.registry
    if not registry.loaded:
        raise ApiError(503, "", "libraries are still loading", headers={"Retry-After": "1"})
    raw = await body.read_body(request, settings.max_body_bytes, settings.body_timeout_s)
    content_type = request.headers.get("content-type")

    def parse() -> jobs.Job:
        return jobs.parse(body.decode(raw, content_type), settings, registry.banks)

    # A big body is decoded and validated in a thread of its own (one at a time): an 8 MiB
    # msgpack of empty arrays took 0.9 s, and on the event loop /livez waited for it.
    job = (parse() if len(raw) < SMALL_BODY
           else await asyncio.get_running_loop().run_in_executor(state.decoder, parse))
    req = job.request
    sk = registry.libraries[req.animal].skeleton
    meta = {"animal": req.animal, "skeleton_id": skeleton_id(req.animal, sk),
            "fps": registry.banks[req.animal].fps, "encoding": req.encoding}
    return await respond(state, job, meta, not body.wants_msgpack(request), len(raw))
