"""What the service can synthesize with: the animal libraries, their meshes, the limits."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response

from api_schemas import GaitRange, LibrariesResponse, LibraryDetail, Limits
from service.errors import ApiError
from service.libraries import LibraryRegistry
from service.openapi import errors
from service.packing import skeleton_id
from service.state import state_of
from synth_core.build.motion_graph import HUBS

GLB = "model/gltf-binary"  # glTF 2.0 binary media type (IANA)

router = APIRouter(tags=["libraries"])


def _unknown(registry: LibraryRegistry, animal: str) -> ApiError:
    loaded = ", ".join(sorted(registry.libraries))
    return ApiError(404, "animal", f"unknown animal {animal!r}; loaded: {loaded}")


@router.get("/v1/libraries", response_model=LibrariesResponse)
async def libraries(request: Request) -> LibrariesResponse:
    """The animal libraries this service can synthesize with."""
    return LibrariesResponse(libraries=list(state_of(request).registry.summaries.values()))


@router.get("/v1/libraries/{animal}", response_model=LibraryDetail, responses=errors(404))
async def library(animal: str, request: Request) -> LibraryDetail:
    """What a client needs to play the streams: joints, parents, rest offsets, feet, gaits."""
    registry = state_of(request).registry
    if animal not in registry.libraries:
        raise _unknown(registry, animal)
    lib, bank = registry.libraries[animal], registry.banks[animal]
    sk = lib.skeleton
    gaits = [GaitRange(index=HUBS.index(g), name=g, min_speed=float(m.speeds[0]),
                       max_speed=float(m.speeds[-1])) for g, m in lib.maps.items()]
    mesh_url = f"/v1/libraries/{animal}/mesh.glb" if animal in registry.meshes else None
    return LibraryDetail(animal=animal, skeleton_id=skeleton_id(animal, sk), fps=bank.fps,
                         joint_names=list(sk.names), parents=[int(p) for p in sk.parents],
                         offsets=sk.offsets.astype(float).tolist(),
                         end_sites=[bool(e) for e in sk.end_site],
                         feet={f.name: sk.names[f.end_effector] for f in sk.feet}, gaits=gaits,
                         mesh_url=mesh_url)


@router.get("/v1/libraries/{animal}/mesh.glb", response_class=Response,
            responses={200: {"description": "glTF 2.0 binary: one skinned mesh on the animal's skeleton "
                                            "in its rest pose (synth_core.export.mesh)",
                             "content": {GLB: {"schema": {"type": "string", "format": "binary"}}}},
                       **errors(404)})
async def library_mesh(animal: str, request: Request) -> Response:
    """The animal's skinned mesh: a node per joint named and ordered as
    `GET /v1/libraries/{animal}` lists them, skin joints in that order, inverse bind
    matrices of the rest pose; Y up, metres, facing +Z."""
    registry = state_of(request).registry
    if animal in registry.mesh_errors:
        raise ApiError(404, "animal", f"no mesh for {animal!r}: {registry.mesh_errors[animal]}")
    if animal not in registry.meshes:
        raise _unknown(registry, animal)
    return Response(registry.meshes[animal], media_type=GLB)


@router.get("/v1/limits", response_model=Limits)
async def limits(request: Request) -> Limits:
    """The request limits of this service and each rotation encoding's size and error."""
    return state_of(request).settings.published()
