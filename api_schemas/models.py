"""Pydantic models for every request and response body (see docs/wire-format.md).

The same models describe msgpack and JSON bodies: a :class:`Blob`'s ``data`` is raw bytes in
msgpack (``bin``) and base64 text in JSON; it is accepted either way.
"""

from __future__ import annotations

import base64
import binascii
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    field_serializer,
    field_validator,
    model_validator,
)

from api_schemas.wire import DTYPES, ENCODINGS, Encoding

_STRICT = ConfigDict(extra="forbid")


class Health(BaseModel):
    status: str = Field(description="'ok' while the process serves requests")


class LibraryStatus(BaseModel):
    name: str = Field(description="the animal, or the library file's name when the file could not be read")
    state: str = Field(description="'loaded', 'missing' (configured, no file of it loaded) or 'failed'")
    reason: str = Field("", description="why it is missing or failed ('' when loaded)")


class Readiness(BaseModel):
    status: str = Field(description="'ready'; 'starting'; 'incomplete' (a configured library is missing "
                                    "or failed to load: see library_status); or 'draining'")
    libraries: int = Field(description="number of animal libraries loaded")
    library_status: list[LibraryStatus] = Field(
        default_factory=list,
        description="each configured library and each library file, once loading is done")


class ErrorDetail(BaseModel):
    status: int = Field(description="the HTTP status (or, on a WebSocket, the close code that follows)")
    field: str = Field(description="where the problem is, e.g. 'characters[3].points' "
                                   "('': the whole request)")
    message: str = Field(description="what is wrong, naming the limit where one was exceeded")


class ErrorResponse(BaseModel):
    error: ErrorDetail


class Blob(BaseModel):
    """A little-endian array: ``data`` holds ``prod(shape)`` items of ``dtype``, C order."""

    model_config = _STRICT
    dtype: str = Field(description=f"numpy dtype string, one of {', '.join(DTYPES)}", examples=["<f4"])
    shape: list[int] = Field(description="array shape", examples=[[2, 3]])
    data: bytes = Field(description="the array's bytes: msgpack bin, or base64 text in JSON",
                        json_schema_extra={"format": "base64"})

    @model_validator(mode="before")
    @classmethod
    def _a_map(cls, value: Any) -> Any:
        """Arrays never travel as lists of numbers: say what a blob is to a client that sent one."""
        if not isinstance(value, dict | BaseModel):
            raise ValueError(f"expected a blob, a map {{dtype: '<f4', shape: [n, 3], data: the array's bytes "
                             f"(msgpack bin, or base64 text in JSON)}}, got a {type(value).__name__} "
                             f"(docs/wire-format.md, Arrays; api_schemas.wire.blob makes one)")
        return value

    @field_validator("data", mode="before")
    @classmethod
    def _from_base64(cls, value: Any) -> Any:
        if isinstance(value, str):
            try:
                return base64.b64decode(value, validate=True)
            except (binascii.Error, ValueError) as exc:
                raise ValueError(f"not valid base64: {exc}") from None
        return value

    @field_serializer("data", when_used="json")
    def _to_base64(self, value: bytes) -> str:
        return base64.b64encode(value).decode("ascii")


class PackedRotations(Blob):
    """Local joint rotations ``(frames, joints, 4)`` (f32, i16), ``(frames, joints, 6)`` bytes
    (s48) or ``(nbytes,)`` bytes of delta blocks (decoding to ``decoded_shape``)."""

    encoding: Encoding = Field(description="f32, i16, s48 or delta (docs/wire-format.md)")
    decoded_shape: list[int] | None = Field(
        default=None, description="delta only: the shape the blocks decode to, (frames, joints, 4)")
    joints: list[int] | None = Field(
        default=None, description="level of detail: the joints sent, in order (absent: all); the "
                                  "others keep the identity rotation")


Detail = Literal["full", "legs_spine", "root_gait"]
DETAILS: tuple[Detail, ...] = ("full", "legs_spine", "root_gait")
DETAIL_DOC = ("level of detail: 'full' every joint; 'legs_spine' the root, spine and the four legs' "
              "joints (head, neck and tail keep the identity rotation); 'root_gait' no rotations at "
              "all: root, gait and contacts only (docs/wire-format.md)")


class Lod(BaseModel):
    """How much of the motion a client needs (docs/wire-format.md, level of detail)."""

    model_config = _STRICT
    detail: Detail = Field(default="full", description=DETAIL_DOC)
    frame_step: int = Field(default=1, ge=1, le=8,
                            description="send every frame_step-th frame (the output fps divided by it)")


SizeMatching = Literal["froude", "geometric"]
SIZE_MATCHING_DOC = ("how a character of scale h uses the library: 'froude' (dynamic similarity: the "
                     "gait of the same Froude number v^2/(g h), stride frequency ~ 1/sqrt(h)) or "
                     "'geometric' (the paper's s/h matching: every size steps at the library's "
                     "frequency)")
TEMPO_SPREAD_DOC = ("each character's own stride frequency varies by up to this share (seeded), so "
                    "equal animals started together do not step as one")


class CharacterIn(BaseModel):
    model_config = _STRICT
    id: str = Field(min_length=1, max_length=128, description="the caller's name for this character")
    points: Blob = Field(description="root trajectory (F, 3) float32 or float64, metres, Y up, "
                                     "one point per frame at the request's fps; F >= 2")
    scale: float | None = Field(default=None, gt=0, le=100,
                                description="size relative to the library animal (default: random "
                                            "in [scale_min, scale_max], seeded)")
    seed: int | None = Field(default=None, ge=0, le=2**63 - 1,
                             description="this character's own seed: its motion then depends on it "
                                         "alone (default: from the request's seed and its index)")
    detail: Detail | None = Field(default=None, description="this character's level of detail "
                                                            "(default: the request's lod.detail)")


class GroundIn(BaseModel):
    """A height field (docs/terrain.md): ``heights[i, j]`` is the ground's y at
    ``x = origin[0] + j * spacing``, ``z = origin[1] + i * spacing``; bilinear between points,
    the nearest edge's height outside the grid."""

    model_config = _STRICT
    heights: Blob = Field(description="(rows along z, columns along x) float32 or float64 metres, "
                                      "at least 2 x 2, at most 4,194,304 heights, all finite")
    origin: tuple[float, float] = Field(default=(0.0, 0.0), description="(x, z) of heights[0, 0], metres")
    spacing: float = Field(default=1.0, ge=0.001, le=10_000, description="metres between grid points")


GROUND_DOC = ("the terrain the herd walks on: planted feet on it, bodies pitched and rolled with it, "
              "the paths' y not read (docs/terrain.md); default: the ground is the paths' y")


class SynthesizeRequest(BaseModel):
    model_config = _STRICT
    animal: str = Field(default="horse", description="a library from GET /v1/libraries")
    fps: float = Field(default=60.0, gt=0, le=1000, description=(
        "frame rate of the trajectory points (the answer comes at the library's fps, lasting as long)"))
    seed: int = Field(default=0, ge=0, le=2**63 - 1, description="same input and seed: same bytes out")
    sigma: float = Field(default=4.0, ge=0, le=100, description=(
        "Gaussian smoothing, frames: of the timing along the points sent (the root stays on them) "
        "and of the positions the body faces and the gaits are chosen on"))
    encoding: Encoding = Field(default="s48", description=f"rotation encoding: {', '.join(ENCODINGS)}")
    lod: Lod = Field(default_factory=Lod, description="level of detail of every character (each may "
                                                      "override its detail)")
    skip_invalid: bool = Field(default=False, description="drop bad characters (reported in 'skipped') "
                                                          "instead of refusing the request")
    scale_min: float = Field(default=0.8, gt=0, le=100)
    scale_max: float = Field(default=1.2, gt=0, le=100)
    foot_lock: bool = Field(default=True, description="pin planted feet (synth_core.runtime.footlock)")
    first_index: int = Field(default=0, ge=0, le=2**53,
                             description="index of the first character in the whole herd: a herd sent "
                                         "in several requests, each with its own first_index, draws "
                                         "gaits and scales as one request would")
    min_resample_rate: float = Field(default=1.0, ge=1, le=8,
                                     description="resample the paths at least this much: send the "
                                                 "highest resample_rate of a herd's requests so all "
                                                 "keep the same frames (the formation)")
    resample: bool = Field(default=False,
                           description="the paper's global resampling: where a character is faster than "
                                       "the library, every path is resampled (more frames, the herd's "
                                       "clock slowed). Default: the clock is kept (the answer lasts as long "
                                       "as the points, at the library's fps) and a character too fast even "
                                       "at its fastest stride rate is listed in 'warnings'")
    size_matching: SizeMatching = Field(default="froude", description=SIZE_MATCHING_DOC)
    tempo_spread: float = Field(default=0.06, ge=0, le=0.25, description=TEMPO_SPREAD_DOC)
    ground: GroundIn | None = Field(default=None, description=GROUND_DOC)
    characters: list[CharacterIn] = Field(min_length=1)


LiveMode = Literal["exact", "low_latency"]
LATENCY_MS = (50.0, 2000.0)  # as synth_core.runtime.live.LATENCY_MS (api_schemas imports no core)
LOW_LATENCY_MS = 100.0  # the low_latency profile's budget (synth_core.runtime.live.LOW_LATENCY_MS)


class LiveCharacter(BaseModel):
    model_config = _STRICT
    id: str = Field(min_length=1, max_length=128)
    scale: float | None = Field(default=None, gt=0, le=100, description="as in SynthesizeRequest")
    seed: int | None = Field(default=None, ge=0, le=2**63 - 1, description="as in SynthesizeRequest")
    detail: Detail | None = Field(default=None, description="as in SynthesizeRequest's characters")


class LiveRequest(BaseModel):
    """Opens a live session on WebSocket /v1/stream (docs/streaming.md): the characters, then
    ``points`` messages with every character's next trajectory points (``points``, a blob
    (characters, n, 3)) and, optionally, each point's ground velocity (``velocity``, a blob
    (characters, n, 2): x and z, m/s, at most 5 m a point; the low-latency mode's speeds and
    headings read it instead of a fit of the points, the exact mode's frames stay the batch's)."""

    model_config = _STRICT
    type: str = Field(default="live", pattern="^live$")
    animal: str = Field(default="horse")
    fps: float = Field(default=60.0, gt=0, le=1000, description="rate of the points sent; frames come "
                                                                   "back at it where the library's rate "
                                                                   "is a whole multiple of it")
    seed: int = Field(default=0, ge=0, le=2**63 - 1)
    sigma: float = Field(default=4.0, ge=0, le=100)
    encoding: Encoding = Field(default="s48")
    lod: Lod = Field(default_factory=Lod, description="as in SynthesizeRequest")
    scale_min: float = Field(default=0.8, gt=0, le=100)
    scale_max: float = Field(default=1.2, gt=0, le=100)
    foot_lock: bool = Field(default=True)
    heading: float = Field(default=0.0, ge=-7, le=7, description="radians about +Y (0 = +Z) a character "
                                                                 "faces while it stands before its first "
                                                                 "move is known")
    size_matching: SizeMatching = Field(default="froude", description=SIZE_MATCHING_DOC)
    tempo_spread: float = Field(default=0.06, ge=0, le=0.25, description=TEMPO_SPREAD_DOC)
    ground: GroundIn | None = Field(default=None, description=GROUND_DOC + "; a `ground` message "
                                    "changes it during the session")
    mode: LiveMode | None = Field(default=None, description="exact (the default, unless latency_ms is "
                                  "given): every frame as the batch would make it (sent seconds after "
                                  "its point: see the start message's latency_s); low_latency: sent at "
                                  "most latency_ms after its point, its gait and heading from the points "
                                  "so far or from the velocity sent with each (docs/streaming.md)")
    latency_ms: float | None = Field(default=None, ge=LATENCY_MS[0], le=LATENCY_MS[1],
                                     description="low_latency: the most a frame's pose lags its point, "
                                                 f"ms (default {LOW_LATENCY_MS:g}); given alone, "
                                                 "it asks for low_latency")
    characters: list[LiveCharacter] = Field(min_length=1)

    @field_validator("latency_ms")
    @classmethod
    def _latency_is_low_latencys(cls, v: float | None, info: ValidationInfo) -> float | None:
        if v is not None and info.data.get("mode") == "exact":
            raise ValueError("only with mode low_latency (the exact mode's latency is the batch's)")
        return v

    @property
    def budget_ms(self) -> float | None:
        """The low-latency budget asked for (None: the exact mode)."""
        if self.latency_ms is not None:
            return self.latency_ms
        return LOW_LATENCY_MS if self.mode == "low_latency" else None


class CharacterOut(BaseModel):
    id: str
    scale: float = Field(description="the scale used (given or drawn)")
    frames: int = Field(description="frames of motion at the library's fps")
    root: Blob = Field(description="root position (frames, 3) float32, metres")
    rotations: PackedRotations
    gait: Blob = Field(description="(frames,) int8: 0 static, 1 walk, 2 trot, 3 canter, 4 gallop")
    contacts: Blob = Field(description="(frames,) uint8 bit mask of planted feet: 1 LF, 2 RF, 4 LH, 8 RH: "
                                       "the feet the motion sent stands on the ground (the foot lock's "
                                       "plants, its steps off; a far, unposed character's: its plan's). "
                                       "See docs/wire-format.md")


class Skipped(BaseModel):
    id: str
    index: int = Field(description="position in the request's characters")
    reason: str


class CharacterWarning(BaseModel):
    id: str
    index: int = Field(description="position in the request's characters")
    reason: str = Field(description="what its motion could not keep, where, and why")


class SynthesizeResponse(BaseModel):
    animal: str
    skeleton_id: str = Field(description="identifies the joint layout; GET /v1/libraries/{animal}")
    fps: float = Field(description="frame rate of the output (the library's)")
    encoding: Encoding
    frame_step: int = Field(default=1, description="lod.frame_step: fps is the library's divided by it")
    resample_rate: float = Field(description="r >= 1: every path was resampled to r times its frames "
                                             "('resample', or min_resample_rate, asked for it)")
    characters: list[CharacterOut]
    skipped: list[Skipped] = Field(default_factory=list)
    warnings: list[CharacterWarning] = Field(default_factory=list,
                                             description="characters made, but whose motion could not "
                                                         "keep up (e.g. too fast: feet slide)")


class LibrarySummary(BaseModel):
    animal: str = Field(description="library name, e.g. 'horse'")
    joints: int = Field(description="number of joints, end sites included")
    feet: dict[str, str] = Field(description="foot (LF, RF, LH, RH) -> end-effector joint name")
    fps: float = Field(description="frame rate of the library's clips")
    gaits: list[str] = Field(description="gaits the library can synthesize (empty until built)")
    source: str = Field(description="the name of the library file it was loaded from, in the service's "
                                    "library directory")


class LibrariesResponse(BaseModel):
    libraries: list[LibrarySummary]


class GaitRange(BaseModel):
    index: int = Field(description="the value in a character's gait stream")
    name: str
    min_speed: float = Field(description="m/s at scale 1 (a character of scale h: h times this)")
    max_speed: float


class LibraryDetail(BaseModel):
    animal: str
    skeleton_id: str
    fps: float
    joint_names: list[str]
    parents: list[int] = Field(description="parent joint index, -1 for the root; parents come first")
    offsets: list[list[float]] = Field(description="rest offset of each joint from its parent, metres")
    end_sites: list[bool] = Field(description="joints that are end sites (BVH 'End Site': no rotation "
                                              "of their own matters)")
    feet: dict[str, str] = Field(description="foot (LF, RF, LH, RH) -> end-effector joint name")
    gaits: list[GaitRange]
    mesh_url: str | None = Field(description="the animal's skinned mesh (glTF binary): one mesh bound to "
                                             "these joints (node per joint, same names and order), Y up, "
                                             "metres, facing +Z; null if none could be made")


class Limits(BaseModel):
    max_body_bytes: int = Field(description="request body, bytes (413 beyond)")
    max_characters: int = Field(description="characters per request (422 beyond)")
    max_frames: int = Field(description="trajectory points per character (422 beyond)")
    max_character_frames: int = Field(description="characters x output frames per request (422 beyond)")
    max_in_flight: int = Field(description="synthesis requests running per worker process")
    max_queued: int = Field(description="requests waiting per worker process; beyond: 503 + Retry-After")
    deadline_s: float = Field(description="a request still synthesizing after this gets 504")
    ws_chunk_frames: int = Field(description="frames per WebSocket chunk")
    ws_window: int = Field(description="unacknowledged WebSocket chunks before the server waits")
    ws_send_timeout_s: float = Field(description="a client not reading for this long is closed (1013)")
    memory_budget_mb: int = Field(description="per worker process: answers in flight x their estimated "
                                              "size; an answer that does not fit now: 503 + Retry-After, "
                                              "one that never could: 422")
    send_timeout_s: float = Field(description="an answer its client takes nothing of for this long "
                                              "is cut short")
    body_timeout_s: float = Field(description="a request body not received whole within this: 408")
    encodings: dict[str, dict[str, float]] = Field(
        description="per rotation encoding: bytes per joint-frame and measured worst-case error")


