"""Run-time synthesis for crowds (Sung 2011, section 6): trajectories in, joint rotations out.

For a batch of characters at once, all array operations over (characters, frames[, joints]):

1. **Plan** (:mod:`synth_core.runtime.plan`, steps 1-2 of the paper's synthesis): each
   character's gaits, transitions and stride phase, and so the clips every frame blends.
   A segment's speed ``s / (h k)`` (scale h, stride tempo k: :func:`character_tempo`, Froude
   similarity by default) picks the gait, and the stride runs at the character's tempo.
2. **Stitch.** Where a piece starts (transition in or out), the piece before it carries on and
   fades out over ``margin`` frames (smoothstep).
3. **Warp.** The root's ground position is the (smoothed) trajectory point of that frame plus
   the clip's own in-stride surge along the path (heading_kernels.turn) -- so it keeps time with the
   trajectory and never drifts from it -- and its heading follows the trajectory's tangent; its
   height is the clip's times h. Sideways sway of the clips is dropped: the path is the caller's.
4. **Foot lock** (:mod:`synth_core.runtime.footlock`) pins each planted foot where it lands.

Steps 2-4 are the render, written once in :mod:`synth_core.compiled.kernels`;
:func:`synthesize` plans and renders a batch ``CHUNK`` characters at a time, compiled unless
``Options.backend`` asks for the references (the same source interpreted:
:mod:`synth_core.compiled.backend`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core import SIZE_MATCHING, TEMPO_SPREAD
from synth_core.compiled import backend, kernels
from synth_core.compiled.scratch import Scratch
from synth_core.runtime.bank import Bank
from synth_core.runtime.draws import SCALE_STREAM, TEMPO_STREAM, character_keys, uniform
from synth_core.runtime.plan import MARGIN, MAX_RATE, N_HUBS, Plan, character_leads, headings, plan
from synth_core.runtime.terrain import HeightField, along_ground, ground_plan
from synth_core.runtime.trajectory import DEFAULT_SIGMA, Prepared, TrajectoryError, prepare

__all__ = ["CHUNK", "MARGIN", "N_HUBS", "Options", "Plan", "Rendered", "Result", "character_scales",
           "character_tempo", "compiled_backend", "headings", "plan", "prepare_batch", "render_chunk",
           "render_chunks", "synthesize"]
# (the plan's names too: callers import them from here)

Floats = NDArray[np.float64]
CHUNK = 256  # characters planned and rendered at a time (the working set stays in cache)
BACKENDS = backend.BACKENDS


@dataclass(frozen=True)
class Options:
    sigma: float = DEFAULT_SIGMA  # trajectory smoothing, frames
    seed: int = 0
    scale_range: tuple[float, float] = (1.0, 1.0)  # scales drawn for characters given none
    margin: int = MARGIN
    foot_lock: bool = True
    skip_invalid: bool = False
    backend: str = "auto"  # "numba" (compiled kernels), "numpy" (the reference), "auto": numba if installed
    first_index: int = 0  # the batch's first character's index in the herd (its draws' counter)
    min_resample_rate: float = 1.0  # resample at least this much (a herd split into batches: the
    # rate of the batch with the fastest character, so every batch keeps the same frames)
    resample: bool = False  # the paper's global resampling where a character is too fast (default:
    # the caller's clock is kept, and a character too fast even at MAX_RATE gets a warning)
    size_matching: str = "froude"  # how a character of scale h uses the library (character_tempo)
    tempo_spread: float = TEMPO_SPREAD  # each character's own stride tempo, +- this share
    max_character_frames: int | None = None  # refuse (FrameLimitError) a batch that would make more
    ground: HeightField | None = None  # the terrain the herd walks on (None: the paths' y is the ground)
    posed: NDArray[np.bool_] | None = field(default=None, compare=False)  # (C,) per input character:
    # its rotations are wanted (None: all's). The others (far characters, at root_gait detail) get
    # the plan's root, gait and contacts alone: no pose, no foot lock, their rotations left unwritten
    # (what ``out`` held; a fresh output's zeros): a caller exporting them fills in what it wants

    def posed_rows(self, kept: NDArray[np.int64]) -> NDArray[np.bool_] | None:
        """:attr:`posed` of the characters ``kept`` (a prepared batch's rows: input indices)."""
        return None if self.posed is None else np.asarray(self.posed, np.bool_)[kept]


@dataclass(frozen=True, eq=False)
class Result:
    root_pos: NDArray[np.float32]  # (C, T, 3) world, metres
    rotations: NDArray[np.float32]  # (C, T, J, 4) local, xyzw
    gait: NDArray[np.int8]  # (C, T) hub index (static 0 ... gallop 4); a transition: the hub it
    # leaves over its first half, the one it reaches over its second
    contacts: NDArray[np.bool_]  # (C, T, 4) the feet planted as posed (kernels.render: the foot
    # lock's, each on the ground within footlock.PLANTED_SLACK; far characters': the plan's)
    stitches: NDArray[np.bool_]  # (C, T) frames where a new piece starts (transitions in/out)
    scales: Floats  # (C,)
    path: Floats  # (C, T, 3) the path followed: the points sent, their timing smoothed
    resample_rate: float
    kept: NDArray[np.int64]  # input characters synthesized
    rejected: dict[int, str] = field(default_factory=dict)
    warnings: dict[int, str] = field(default_factory=dict)  # input index -> what its motion could not keep
    mirrored: NDArray[np.bool_] | None = None  # (C,) on the other lead: the clips' mirror images
    # (plan.character_leads; its feet's contacts are the library's with left and right swapped)


def character_tempo(keys: NDArray[np.uint64], h: Floats, matching: str = "froude",
                    spread: float = TEMPO_SPREAD) -> Floats:
    """Each character's stride tempo k: clip frames per output frame. A character of scale h
    (its lengths h times the library's) at speed s plays the library's motion of speed
    ``s / (h k)`` -- stride length h times the clip's, frequency k times -- so its feet keep pace.

    ``froude`` (dynamic similarity, the default): k = 1 / sqrt(h), so a character asks for the
    library's motion at the same Froude number v^2 / (g h) -- the same gait, duty factor and
    relative stride -- and steps with frequency ~ 1 / sqrt(h) (Alexander & Jayes 1983;
    Pennycuick 1975: stepping frequency ~ size^-0.5 in walk, trot and canter). ``geometric``
    (the paper's s / h matching): k = 1, every size steps at the library's frequency. Either
    way times ``1 + spread u``, u uniform in [-1, 1) from the character's key."""
    if matching not in SIZE_MATCHING:
        raise TrajectoryError(f"size_matching: must be one of {SIZE_MATCHING}, got {matching!r}")
    if not (np.isfinite(spread) and 0 <= spread <= 0.25):
        raise TrajectoryError(f"tempo_spread: must be within [0, 0.25], got {spread}")
    fine = np.isfinite(h) & (h > 0)  # others are refused with the trajectory checks
    froude = np.where(fine, 1 / np.sqrt(np.where(fine, h, 1.0)), 1.0)
    base = froude if matching == "froude" else np.ones(len(h))
    if spread == 0:
        return np.asarray(base, np.float64)
    u = 2 * uniform(keys, TEMPO_STREAM)[:, 0] - 1
    return np.asarray(base * (1 + spread * u), np.float64)


def character_scales(keys: NDArray[np.uint64], scales: ArrayLike | None,
                     scale_range: tuple[float, float]) -> Floats:
    """Each character's scale: given, or (None, NaN) drawn from its key in ``scale_range``."""
    n = len(keys)
    h_min, h_max = scale_range
    if not (0 < h_min <= h_max and np.isfinite(h_max)):
        raise TrajectoryError(f"scale_range: need 0 < min <= max, got {scale_range}")
    drawn = h_min + (h_max - h_min) * uniform(keys, SCALE_STREAM)[:, 0]
    if scales is None:
        return np.asarray(drawn)
    given = np.asarray(scales, dtype=np.float64)
    if given.shape != (n,):
        raise TrajectoryError(f"scales: expected {n} values (one per character), got shape {given.shape}")
    return np.where(np.isnan(given), drawn, given)  # NaN: "draw one for me"


def prepare_batch(bank: Bank, positions: ArrayLike, fps: float | None, scales: ArrayLike | None,
                  options: Options, ids: list[str] | None, seeds: ArrayLike | None = None
                  ) -> tuple[Prepared, Floats, NDArray[np.uint64]]:
    """Checked options, prepared trajectories, and each kept character's scale (given, or
    drawn) and random key (from its own seed, ``-1``: none, else from ``options.seed``)."""
    fps = bank.fps if fps is None else fps
    n = np.shape(positions)[0] if np.ndim(positions) >= 1 else 0
    if seeds is not None and np.shape(seeds) != (n,):
        raise TrajectoryError(f"seeds: expected {n} values (one per character), got shape {np.shape(seeds)}")
    if not (isinstance(options.first_index, int) and 0 <= options.first_index < 2**62):
        raise TrajectoryError(f"first_index: must be an integer >= 0, got {options.first_index}")
    keys = character_keys(options.seed, n, seeds, options.first_index)
    all_scales = character_scales(keys, scales, options.scale_range)
    if not (isinstance(options.margin, int) and 0 <= options.margin <= 60):
        raise TrajectoryError(f"margin: must be an integer within [0, 60] frames, got {options.margin}")
    if options.backend not in BACKENDS:
        raise TrajectoryError(f"backend: must be one of {BACKENDS}, got {options.backend!r}")
    if options.posed is not None and np.shape(options.posed) != (n,):
        raise TrajectoryError(f"posed: expected {n} flags (one per character), "
                              f"got shape {np.shape(options.posed)}")
    tempo = character_tempo(keys, all_scales, options.size_matching, options.tempo_spread)
    prep = prepare(positions, fps, bank.fps, bank.top_speed, bank.mean_cycle, all_scales,
                   options.sigma, options.skip_invalid, ids, options.min_resample_rate, options.resample,
                   MAX_RATE, tempo, options.max_character_frames)
    return prep, all_scales[prep.kept], keys[prep.kept]


def compiled_backend(options: Options) -> bool:
    """Whether ``options`` render with the numba kernels (else the reference: their source interpreted)."""
    return backend.compiled(options.backend)


@dataclass(frozen=True, eq=False)
class Rendered:
    """One chunk of a batch: its characters' motion and plan (:func:`render_chunks`)."""

    characters: slice  # rows of the prepared (kept) characters
    root: NDArray[np.float32]  # (n, T, 3)
    rotations: NDArray[np.float32]  # (n, T, J, 4)
    plan: Plan
    contacts: NDArray[np.bool_]  # (n, T, 4) the feet planted as posed (kernels.render), not the plan's


def render_chunk(bank: Bank, prep: Prepared, h: Floats, keys: NDArray[np.uint64], options: Options,
                 characters: slice, scratch: Scratch,
                 out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None) -> Rendered:
    """Plan and render rows ``characters`` of a prepared batch: one chunk of
    :func:`render_chunks` (callers running chunks side by side call it for each). Root and
    rotations go into ``out`` (those characters' rows) or else ``scratch``'s arrays, which then
    hold until it renders again; the render kernel's working sets are kept in ``scratch``."""
    sl = characters
    part = prep.rows(sl)
    if options.ground is not None:
        part = along_ground(part, options.ground, bank.fps)
    compiled = compiled_backend(options)
    p = plan(bank, part, h[sl], keys[sl], options.margin, compiled=compiled)
    ground = None
    if options.ground is not None:
        p, ground = ground_plan(bank, p, options.ground)
    if out is None:
        n, T = p.yaw.shape
        out = (scratch.array("root", (n, T, 3), np.float32),
               scratch.array("rotations", (n, T, bank.skeleton.n_joints, 4), np.float32))
    root, rotations = out
    contacts = scratch.array("contacts", p.contacts.shape, np.bool_)
    kernels.render(bank, p, options.foot_lock, out=(root, rotations), scratch=scratch, ground=ground,
                   compiled=compiled, pose=options.posed_rows(prep.kept[sl]), contacts=contacts)
    return Rendered(sl, root, rotations, p, contacts)


def render_chunks(bank: Bank, prep: Prepared, h: Floats, keys: NDArray[np.uint64], options: Options,
                  chunk: int = CHUNK, out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
                  fresh: bool = False, scratch: Scratch | None = None) -> Iterator[Rendered]:
    """Plan and render a prepared batch ``chunk`` characters at a time (the working set stays in
    cache, so the cost per character-frame does not grow with the crowd).

    Each chunk's root and rotations go into its rows of ``out`` (``fresh``: just allocated, not
    yet touched) or else into ``scratch`` (a new one if none), reused from chunk to chunk: a
    chunk's arrays then hold until the next is asked for. The render kernel's working sets are
    kept in ``scratch`` either way."""
    C = prep.positions.shape[0]
    scratch = Scratch() if scratch is None else scratch
    for a in range(0, C, chunk):
        sl = slice(a, min(a + chunk, C))
        rows = None
        if out is not None:
            rows = out[0][sl], out[1][sl]
            if fresh and compiled_backend(options):
                # Touch the chunk's output pages here, in one thread, before the kernel's workers
                # write them: first-touch page faults taken by parallel workers contend for the
                # process's memory map and cost as much as the render itself (measured: 0.9 ->
                # 0.48 s per 1,000 characters x 500 frames; the memset is ~5% of that).
                rows[0].fill(0)
                rows[1].fill(0)
        yield render_chunk(bank, prep, h, keys, options, sl, scratch, rows)


def synthesize(bank: Bank, positions: ArrayLike, fps: float | None = None,
               scales: ArrayLike | None = None, options: Options = Options(),
               ids: list[str] | None = None,
               progress: Callable[[int, int], None] | None = None,
               out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
               seeds: ArrayLike | None = None, scratch: Scratch | None = None) -> Result:
    """Motion for every trajectory ``positions (C, F, 3)`` sampled at ``fps`` (default: the library's).

    ``seeds (C,)``: a character's own seed (``-1``: none, it draws from ``options.seed`` and its
    index); a character's motion depends on its seed, not on the rest of the batch (save for the
    batch's resampling rate, when ``options.resample`` and some character is too fast for the
    library).

    The batch is checked and resampled as a whole, then planned and rendered ``CHUNK`` characters
    at a time (:func:`render_chunks`); ``progress(done, total)`` is called after each chunk.

    ``out``: ``(root (C, T, 3), rotations (C, T, J, 4))`` float32 arrays to write into, e.g. a
    previous result's, as a caller synthesizing batch after batch would keep them (T: the frame
    count after resampling). Fresh memory is dear: its first touch costs up to 1.8 ms per MB on
    a VM (measured here), 5.7 s for 10,000 characters x 500 frames. ``scratch``: the render
    kernel's working sets (a few MB), which such a caller can keep too, as the service's worker
    threads do (default: fresh ones, kept for this call's chunks)."""
    prep, h, keys = prepare_batch(bank, positions, fps, scales, options, ids, seeds)
    C, T = prep.positions.shape[:2]
    J = bank.skeleton.n_joints
    if out is None:
        out = (np.empty((C, T, 3), np.float32), np.empty((C, T, J, 4), np.float32))
        fresh = True
    else:
        for name, given, shape in (("root", out[0], (C, T, 3)), ("rotations", out[1], (C, T, J, 4))):
            if given.shape != shape or given.dtype != np.float32 or not given.flags.c_contiguous:
                raise ValueError(f"out {name}: need a C-contiguous float32 array of shape {shape}, "
                                 f"got {given.dtype} {given.shape}")
        fresh = False
    gait = np.empty((C, T), np.int8)
    contacts = np.empty((C, T, 4), bool)
    stitches = np.empty((C, T), bool)
    for chunk in render_chunks(bank, prep, h, keys, options, out=out, fresh=fresh, scratch=scratch):
        sl, p = chunk.characters, chunk.plan
        gait[sl], contacts[sl], stitches[sl] = p.gait, chunk.contacts, p.stitches
        if progress:
            progress(sl.stop, C)
    return Result(out[0], out[1], gait, contacts, stitches, h, prep.positions, prep.resample_rate,
                  prep.kept, prep.rejected, prep.warnings, character_leads(bank, keys) > 0)
