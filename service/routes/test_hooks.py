"""Routes that hold the workers on an event (``settings.test_hooks``; tests only): a worker about
to synthesize waits while held (:meth:`service.state.State.held_by_test`)."""

from __future__ import annotations

from fastapi import APIRouter, Request

from service.state import state_of

router = APIRouter(include_in_schema=False)


@router.post("/_test/hold")
async def hold(request: Request) -> dict[str, str]:
    state = state_of(request)
    state.held.clear()
    state.hold.clear()
    return {"status": "holding"}


@router.post("/_test/release")
async def release(request: Request) -> dict[str, str]:
    state_of(request).hold.set()
    return {"status": "released"}


@router.get("/_test/held")
async def held(request: Request) -> dict[str, bool]:
    return {"held": state_of(request).held.is_set()}
