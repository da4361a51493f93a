"""Live synthesis: trajectory points arrive a few at a time (a crowd simulation as it runs) and
poses come back for every frame the plan can settle -- :func:`synth_core.runtime.synthesis.plan` made
incrementally, frame block by frame block, with its state carried between blocks.

Every step of the batch plan is causal but for a bounded look-ahead, which is the latency:

- smoothing reads ``radius`` points ahead (4 sigma);
- a frame's speed is interpolated between segment centres, so it waits for the segment after
  its own (up to 1.5 segments ahead), and a gait is chosen on the speed ``LOOKAHEAD`` segments
  ahead of its decision, waiting up to a stride for its entry phase (``horizon``: the larger);
- a transition ends where the character has covered its distance -- found as the path arrives.

So a frame is planned about ``horizon + 1.5 m + radius`` frames after its point arrived and
sent ``lock_lag`` frames later (:attr:`LiveSynth.latency_frames`; horse, 60 fps:
112 + 84 + 16 + 2 + 20 = 234 frames, 3.9 s), and then it is exactly the frame the batch plan of
the whole trajectory has (tested, foot lock off), but for:

- the heading of a character standing before it first moves: the batch turns it to where it
  will go; live does that only if the move is already known, else keeps ``heading``;
- the last two segments' frames, once :meth:`LiveSynth.finish` says the trajectory ends (the
  end is smoothed as the batch's is, but the batch's speeds there read its last, shorter segment);
- no resampling (r = 1): live cannot slow time down, so a character faster than the library's
  fastest gait plays it up to MAX_RATE times faster, as in a batch, and slides beyond that.

The foot lock pins a plant at its average position, which needs the plant's end: frames are
sent ``lock_lag`` frames after they are planned (``LOCK_LAG``, a third of a second) and locked over
every frame planned so far, so most plants a frame is in have ended; one still going on is pinned
at its average so far and moves by the difference in the next block. Measured on 24 horses
(tests/test_live.py): 95th-percentile skate as the batch's (0.01 mm), mean 1.6 mm against the
batch's 1.1 (no lag: 0.7 mm p95, 2.0 mm mean).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core import TEMPO_SPREAD
from synth_core.compiled import kernels, plan_kernels, render_pool
from synth_core.compiled.scratch import Scratch
from synth_core.runtime import gaussian
from synth_core.runtime.bank import Bank
from synth_core.runtime.draws import SCHEDULE_STREAM, character_keys, uniform
from synth_core.runtime.footlock import EASE_FRAMES, PAD
from synth_core.runtime.streaming import Window, lock_context
from synth_core.runtime.synthesis import (
    MARGIN,
    MAX_RATE,
    MIN_TURN_SPEED,
    N_HUBS,
    STAND_SHARE,
    Floats,
    Plan,
    _choose,
    _kinds,
    _plan_tables,
    blend_rows,
    character_scales,
    character_tempo,
    clip_range,
    decision_step,
    distance_since,
    entry_frame,
    hub_clocks,
    lookahead,
    render,
    stride_clocks,
    switch,
)
from synth_core.runtime.terrain import HeightField, on_ground
from synth_core.runtime.trajectory import _GROUND, DEFAULT_SIGMA, TELEPORT_M, TrajectoryError

NEVER = np.iinfo(np.int64).max // 4
SLOTS = 5  # pieces per character: the one before, the one playing, then up to a gait, a transition
# and the gait after it (a decision made for a transition ending before the next one)
KEEP_PLANS = 1  # of the slowest cycle: planned frames kept as the foot lock's context
LOCK_LAG = 20  # frames planned but not yet sent, so that most plants a frame is in have ended


@dataclass
class _Pieces:
    """Per character (C, SLOTS), chronological: start frame, kind, first clip frame, the clock of
    its kind at its start, the distance travelled (unscaled) at its start."""

    start: NDArray[np.int64]
    kind: NDArray[np.int64]
    first: NDArray[np.int64]
    clock0: Floats
    trav0: Floats
    before: NDArray[np.bool_]  # slot 0 holds a piece (the first piece has none before it)


class _Columns:
    """Frames ``[start, stop)`` of per-character arrays ``(C, frames, ...)`` with room to grow:
    new frames are written in place at the end and old ones dropped from the front (concatenating
    the whole of them for every block cost a tenth of a session's time)."""

    def __init__(self, C: int, layout: list[tuple[tuple[int, ...], type]], room: int = 0) -> None:
        self.C, self.layout = C, layout
        self.start = 0  # frame of the first kept
        self.lo = self.hi = 0  # the columns kept
        self.arrays = self._alloc(room)  # room: twice the frames usually kept, so moves are rare

    def _alloc(self, cap: int) -> list[NDArray[Any]]:
        return [np.empty((self.C, cap, *tail), dtype) for tail, dtype in self.layout]

    @property
    def frames(self) -> int:
        return self.hi - self.lo

    @property
    def stop(self) -> int:
        return self.start + self.frames

    def columns(self, a: int, b: int) -> list[NDArray[Any]]:
        """Frames ``[a, b)`` (within ``[start, stop)``) of each array: views."""
        i = self.lo - self.start
        return [x[:, a + i:b + i] for x in self.arrays]

    def reserve(self, n: int) -> list[NDArray[Any]]:
        """The next ``n`` frames, to be filled."""
        cap = self.arrays[0].shape[1]
        if self.hi + n > cap:  # move the kept frames to the front, into larger arrays if need be
            kept = self.hi - self.lo
            # In place when that leaves half the room free, or when the frames kept are no more
            # than those coming (a big block, as at the finish: the copy costs no more than the
            # writing; fresh arrays would cost page faults on top).
            in_place = kept + n <= cap // 2 or (kept + n <= cap and kept <= n)
            arrays = self.arrays if in_place else self._alloc(2 * (kept + n))
            for new, old in zip(arrays, self.arrays, strict=True):
                new[:, :kept] = old[:, self.lo:self.hi]
            self.arrays, self.lo, self.hi = arrays, 0, kept
        self.hi += n
        return self.columns(self.stop - n, self.stop)

    def drop_before(self, frame: int) -> None:
        frame = min(frame, self.stop)
        if frame > self.start:
            self.lo += frame - self.start
            self.start = frame


class _Planned(_Columns):
    """The planned frames kept (the foot lock's context): only those sent, every ``out_step``-th
    of the library's, its columns numbered by frame sent (library frame // out_step). Kept at
    the library's rate, each window's frames were a strided view, copied in strides for the
    render kernel (7% of a 30 fps session), and the plan's rows made for frames never read."""

    def __init__(self, scales: Floats, room: int) -> None:
        super().__init__(len(scales), [((4,), np.int32), ((3,), np.float32), ((), np.float64),
                                       ((3,), np.float64), ((4,), np.bool_), ((), np.bool_), ((), np.int8)],
                         room)
        self.scales = scales

    def _plan(self, arrays: list[NDArray[Any]]) -> Plan:
        rows, weights, yaw, path, contacts, stitches, gait = arrays
        return Plan(rows, weights, yaw, path, self.scales, contacts, stitches, gait)

    def plan(self) -> Plan:
        """The frames kept, ``[start, stop)``."""
        return self._plan(self.columns(self.start, self.stop))

    def reserve_plan(self, n: int) -> Plan:
        """The next ``n`` frames, to be filled."""
        return self._plan(self.reserve(n))


class LiveSynth:
    """Characters whose trajectories grow: :meth:`append` points, get back the new frames.

    All characters advance together (a simulation steps every agent each tick): each ``append``
    brings the same number of points for every character, at ``fps``. Frames come back at the
    library's frame rate -- or at ``fps``, every k-th frame, where the library's rate is k times it.

    ``reuse_windows``: each window's rotations are rendered over the last's (the compiled render;
    on pages kept from window to window): a window's arrays then hold only until the next
    :meth:`append`, :meth:`take` or :meth:`finish`. Fresh memory is dear
    (:mod:`synth_core.compiled.scratch`): the pages of a 2,000-horse window's 36 MB, zeroed by the OS as
    they were first written, were 6% of a live session's CPU here (perf). Without it, every
    window is new arrays.

    ``share_render``: each window's render is cut into parts that idle render-pool threads may
    take (:func:`synth_core.compiled.render_pool.shared`): for a session cut into shards, each advanced
    by a pool thread (see :mod:`synth_core.runtime.live_shards`).
    """

    def __init__(self, bank: Bank, n_characters: int, fps: float | None = None, *,
                 scales: ArrayLike | None = None, seed: int = 0, seeds: ArrayLike | None = None,
                 scale_range: tuple[float, float] = (1.0, 1.0), sigma: float = DEFAULT_SIGMA,
                 margin: int = MARGIN, foot_lock: bool = True, backend: str = "auto",
                 heading: float = 0.0, lock_lag: int = LOCK_LAG, first: int = 0,
                 reuse_windows: bool = False, share_render: bool = False, size_matching: str = "froude",
                 tempo_spread: float = TEMPO_SPREAD, ground: HeightField | None = None) -> None:
        if not (isinstance(n_characters, int) and n_characters >= 1):
            raise TrajectoryError(f"characters: need at least one, got {n_characters}")
        fps = bank.fps if fps is None else float(fps)
        if not (np.isfinite(fps) and 0 < fps <= bank.fps):
            raise TrajectoryError(f"fps: must be within (0, {bank.fps:g}] (the library's), got {fps}")
        if not (np.isfinite(sigma) and 0 <= sigma <= 100):
            raise TrajectoryError(f"sigma: must be within [0, 100] frames, got {sigma}")
        C = n_characters
        self.bank, self.fps, self.sigma, self.margin = bank, fps, float(sigma), margin
        self.foot_lock, self.heading = foot_lock, float(heading)
        self.ground = ground  # the terrain (synth_core.runtime.terrain), rendered on in _emit
        self.scratch = Scratch() if reuse_windows else None
        self.share = render_pool.shared if share_render else None
        self.lock_lag = lock_lag if foot_lock else 0
        self.rendered = 0  # library frames rendered
        self.settled = 0  # library frames planned to send: [rendered, settled) wait for take()
        self.compiled = backend == "numba" or (backend == "auto" and kernels.AVAILABLE)
        # The plan's blocks by plan_kernels.live_block (the same plan, bit for bit; False: the
        # numpy reference, which tests compare it with).
        self.plan_compiled = self.compiled
        # first: the index of these characters' first in the session (a shard of it: see
        # synth_core.runtime.live_shards), so each draws as it would among all of them.
        self.keys = character_keys(seed, C, seeds, first)
        self.scales = character_scales(self.keys, scales, scale_range)
        if not (np.isfinite(self.scales) & (self.scales > 0)).all():
            bad = int(np.flatnonzero(~(np.isfinite(self.scales) & (self.scales > 0)))[0])
            raise TrajectoryError(f"scale: must be a positive number, got {self.scales[bad]}", bad)
        self.tempo = character_tempo(self.keys, self.scales, size_matching, tempo_spread)
        self.pace = self.scales * self.tempo  # path speed over this: the library's (synthesis.plan)
        self.slow = clip_range(bank, min(bank.speeds))[0]  # the walk plays slower below this
        ratio = bank.fps / fps
        self.out_step = int(round(ratio)) if abs(ratio - round(ratio)) < 1e-9 else 1
        self.kinds = _kinds(bank)
        self.m = bank.mean_cycle
        self.step = decision_step(self.m)
        # Speeds a decision needs known: the one it reads, and those of every frame up to its
        # gait's entry phase (the stride clock; decided up to a step early, a stride at most).
        self.horizon = max(lookahead(self.m), self.step + int(self.kinds.frames[1:N_HUBS].max()))
        self.pad = int(np.ceil(4 * sigma)) if sigma > 0 else 0
        self.radius = int(4.0 * sigma + 0.5) if sigma > 0 else 0
        self.tables = _plan_tables(bank)  # the kinds' tables as the compiled blocks read them
        # Input (at fps) and the library-rate points made from it.
        self.inputs = np.zeros((C, 0, 3))
        self.inputs_start = 0  # global index of inputs[:, 0]
        self.n_inputs = 0
        self.made = 0  # library-rate points made from the inputs
        self.first_points = np.zeros((C, 0, 3))  # until the head can be made from them
        self.longer = np.zeros((C, 0, 3))  # head reflection + raw points at the library's rate
        self.longer_start = 0
        self.n_raw = 0  # raw points in `longer` (after its head)
        self.ended = False
        # Smoothed path, segment speeds, and what the plan carries from block to block.
        # Room for the path the finish adds too (see _end): growing at the finish moved it into
        # fresh memory, 20-30 ms of a 2,000-horse session's finish (page faults).
        self.path = _Columns(C, [((3,), np.float64)], 2 * self.latency_frames + self._end_frames)
        self.n_path = 0
        self.seg = np.zeros((C, 0))  # segment speeds / (scale x tempo): the library's speeds
        self.seg_start = 0
        self.n_seg = 0
        self.walked = np.zeros(C)  # unscaled distance along the path up to the next frame planned
        self.clock = np.zeros((N_HUBS + 1, C))  # each kind's clock at the next frame planned
        self.last_dir = np.zeros((C, 2))
        self.moved = np.zeros(C, bool)
        self.current = np.zeros(C, np.int64)
        self.busy = np.zeros(C, np.int64)
        self.decisions = 0
        self.planned = 0
        self.emitted = 0
        start = np.full((C, SLOTS), NEVER, np.int64)
        start[:, 1] = 0  # standing: the idle from frame 0
        self.pieces = _Pieces(start, np.zeros((C, SLOTS), np.int64), np.zeros((C, SLOTS), np.int64),
                              np.zeros((C, SLOTS)), np.zeros((C, SLOTS)), np.zeros(C, bool))
        # Planned frames kept as the foot lock's context (see _emit).
        self.buffer = _Planned(self.scales, -(-2 * (self.lock_lag + self.kept_frames + 2 * self.step)
                                              // self.out_step))
        # The feet of the frames sent and of those after them posed by the foot lock so far (frames
        # [0, known_feet) of each character's): see kernels.render_window.
        # One row of (frames, C, 4, 3): its views are C-contiguous, as the kernel takes them.
        self.feet = _Columns(1, [((C, 4, 3), np.float64)],
                             self.buffer.arrays[0].shape[1] + self._end_frames // self.out_step + 1)
        self.known_feet = np.zeros(C, np.int64)
        # What the sink reads of the legs on the last PAD frames sent (see kernels.Posed).
        self.recent_legs = np.empty((C, PAD, 4, kernels.LEG_WIDTH))
        self.legs_at = np.full(C, kernels.NOWHERE)

    @property
    def window_frames(self) -> int:
        """Frames (sent) one segment settles: a window's usual size, a bound for larger ones."""
        return -(-self.m // self.out_step)

    @property
    def kept_frames(self) -> int:
        """Planned frames before the next to send kept for the foot lock: whole plants reaching
        back past PAD, at most KEEP_PLANS of the slowest cycle."""
        return PAD + EASE_FRAMES + KEEP_PLANS * int(self.kinds.frames[1:N_HUBS].max())

    @property
    def latency_frames(self) -> int:
        """Library frames between a point arriving and its frame being sent, at most."""
        return int(self.horizon + 1.5 * self.m + self.radius + 2) + self.lock_lag

    # -- input -------------------------------------------------------------------------------

    def append(self, points: ArrayLike, frames: int | None = None) -> Window | None:
        """Points ``(C, n, 3)`` (n >= 1) at ``fps``, the next of every character's trajectory;
        the frames this settles (None: none yet) -- at most ``frames`` of them, the rest left
        for :meth:`take`: so a caller bounds a window's memory (10,000 horses: 6.4 MB of float32
        rotations a frame)."""
        return self.append_checked(self.check(points), frames)

    def append_checked(self, arr: Floats, frames: int | None = None) -> Window | None:
        """:meth:`append` of points :meth:`check` returned (not checked again)."""
        self.inputs = np.concatenate([self.inputs, arr], axis=1)
        self.n_inputs += arr.shape[1]
        self._retime()
        self._advance()
        return self.take(frames)

    def set_ground(self, ground: HeightField | None) -> None:
        """The terrain the frames rendered from now on stand on (None: the points' y)."""
        self.ground = ground

    def take(self, frames: int | None = None) -> Window | None:
        """The next frames settled and not yet given, at most ``frames`` of them (None: all);
        None when there are none."""
        if frames is not None and frames < 1:
            raise ValueError(f"frames: a window holds at least 1, got {frames}")
        start = self.rendered
        stop = self.settled if frames is None else min(self.settled, start + frames * self.out_step)
        if stop <= start:
            return None
        self.rendered = stop
        return self._emit(start, stop)

    def check(self, points: ArrayLike) -> Floats:
        """The points :meth:`append` would take, as float64 -- or :class:`TrajectoryError` for
        the first character they are unusable for; nothing is changed either way."""
        if self.ended:
            raise TrajectoryError("points: the trajectories have ended (finish was called)")
        arr = np.asarray(points, np.float64)
        C = len(self.scales)
        if arr.ndim != 3 or arr.shape[0] != C or arr.shape[2] != 3 or arr.shape[1] < 1:
            raise TrajectoryError(f"points: expected shape ({C}, n >= 1, 3), got {arr.shape}")
        if self.plan_compiled:
            last = self.inputs[:, -1] if self.inputs.shape[1] else np.full((C, 3), np.nan)
            if plan_kernels.live_points_fine(last, arr, TELEPORT_M):
                return arr  # else found and named below
        finite = np.isfinite(arr).all(axis=(1, 2))
        if not finite.all():
            c = int(np.flatnonzero(~finite)[0])
            frame = int(np.flatnonzero(~np.isfinite(arr[c]).all(axis=-1))[0])
            raise TrajectoryError(f"points: NaN or Inf at its point {frame} of this message", c)
        joined = np.concatenate([self.inputs[:, -1:], arr], axis=1)
        jump = np.linalg.norm(np.diff(joined, axis=1), axis=-1)
        if jump.size and jump.max() > TELEPORT_M:
            c = int(jump.max(axis=1).argmax())
            raise TrajectoryError(f"points: jumps {jump[c].max():.1f} m in one frame (limit {TELEPORT_M} m: "
                                  "a teleport, not locomotion)", c)
        return arr

    def finish(self, frames: int | None = None) -> Window | None:
        """The trajectories end with the points given: the rest of the frames (at most
        ``frames`` of them, the rest left for :meth:`take`: the rest of a 10,000-horse session,
        117 frames at 30 fps, is 750 MB of float32 rotations)."""
        if not self.ended:
            self._end()
        return self.take(frames)

    @property
    def _end_frames(self) -> int:
        """The most path :meth:`_end` adds: the reflected tail, then the hold."""
        return self.pad + self.latency_frames + self.m

    def _end(self) -> None:
        if self.made < 2:
            raise TrajectoryError(f"points: a trajectory needs at least 2 points, got {self.n_inputs}")
        self.ended = True
        if self.n_raw == 0:  # fewer points than the head needs: the batch's shorter head
            self.pad = self.made - 1
            self._raw(np.zeros((len(self.scales), 0, 3)))
        # As the batch does at the end: the path goes on as it went (point reflection)...
        end = self.n_raw
        last = self.longer[:, -1:]
        k = min(self.pad, self.longer.shape[1] - 1)
        tail = 2 * last - self.longer[:, -2:-2 - k:-1] if k else last[:, :0]
        # ... and on, standing, until every decision that reads it is made.
        hold = np.repeat(tail[:, -1:] if tail.shape[1] else last, self.latency_frames + self.m, axis=1)
        self._raw(np.concatenate([tail, hold], axis=1))
        self._advance(limit=end)

    def _retime(self) -> None:
        """Library-rate points from the inputs so far (linear, as :func:`trajectory.retime`)."""
        ratio = self.fps / self.bank.fps
        if ratio == 1.0:
            new = self.inputs[:, self.made - self.inputs_start:]
        else:
            last = int(np.floor((self.n_inputs - 1) / ratio + 1e-9))
            j = np.arange(self.made, last + 1)
            t = j * ratio
            i0 = np.clip(np.floor(t + 1e-9).astype(np.int64), 0, max(self.n_inputs - 2, 0))
            w = np.clip(t - i0, 0.0, 1.0)[None, :, None]
            base = self.inputs_start
            a = self.inputs[:, i0 - base]
            b = self.inputs[:, np.minimum(i0 + 1, self.n_inputs - 1) - base]
            new = a * (1 - w) + b * w
        self.made += new.shape[1]
        self._raw(new)
        keep = max(self.n_inputs - 2, 0)  # the inputs the next points may interpolate from
        self.inputs = self.inputs[:, keep - self.inputs_start:]
        self.inputs_start = keep

    def _raw(self, new: Floats) -> None:
        """Library-rate points into `longer`, behind the head the batch makes of the first ones."""
        if self.n_raw == 0:
            first = np.concatenate([self.first_points, new], axis=1)
            if first.shape[1] < self.pad + 1:
                self.first_points = first
                return
            head = 2 * first[:, :1] - first[:, self.pad:0:-1]
            self.longer = np.concatenate([head, first], axis=1)
            self.n_raw = first.shape[1]
            self.first_points = first[:, :0]
            return
        self.longer = np.concatenate([self.longer, new], axis=1)
        self.n_raw += new.shape[1]

    # -- planning ------------------------------------------------------------------------------

    def _smooth(self) -> None:
        """Smoothed path for every frame whose Gaussian window has arrived."""
        # Frame t reads `longer` (head first) up to t + pad + radius.
        ready = self.longer_start + self.longer.shape[1] - self.pad - self.radius if self.n_raw else 0
        if ready <= self.n_path:
            return
        if self.sigma > 0:
            lo = max(self.n_path + self.pad - self.radius, 0)  # in `longer` coordinates
            hi = ready + self.pad + self.radius
            part = self.longer[:, lo - self.longer_start:hi - self.longer_start]
            # Only the frames made (half of what scipy would filter); the same numbers.
            new = gaussian.smooth_frames(part, self.sigma, self.n_path + self.pad - lo, ready - self.n_path)
        else:
            new = self.longer[:, self.n_path - self.longer_start:ready - self.longer_start]
        self.path.reserve(new.shape[1])[0][...] = new
        self.n_path = ready
        drop = max(self.n_path + self.pad - self.radius - 1, 0) - self.longer_start
        if drop > 0:
            self.longer = self.longer[:, drop:]
            self.longer_start += drop
        # Segment speeds (m/s in each character's own unit), for every whole segment.
        m = self.m
        whole = (self.n_path - 1) // m
        if whole > self.n_seg:
            a, b = self.n_seg * m, whole * m + 1
            pts = self._path(a, b)
            step = np.linalg.norm(np.diff(pts[..., _GROUND], axis=1), axis=-1)
            counts = np.full(whole - self.n_seg, m)  # as segment_speeds divides, for the same bits
            speeds = step.reshape(len(step), -1, m).sum(axis=2) / counts * self.bank.fps
            self.seg = np.concatenate([self.seg, speeds / self.pace[:, None]], axis=1)
            self.n_seg = whole

    def _path(self, a: int, b: int) -> Floats:
        """The smoothed path's frames [a, b) (a view)."""
        return self.path.columns(a, b)[0]

    def _speeds(self, t: NDArray[np.int64], who: NDArray[np.int64] | None = None) -> Floats:
        """(C, len(t)) speed at frames t (interpolated between segment centres); of the
        characters ``who`` only, if given."""
        m = self.m
        pos = (t - (m - 1) / 2) / m
        k0 = np.maximum(np.floor(pos).astype(np.int64), 0)
        k1 = k0 + 1
        f = np.clip(pos - k0, 0.0, 1.0)
        s = self.seg_start
        seg = self.seg if who is None else self.seg[who]
        return np.asarray(seg[:, k0 - s] * (1 - f) + seg[:, k1 - s] * f)

    def _speed_ready(self) -> int:
        """Frames [0, n) whose speed is known."""
        # Frame t reads segment floor((t - (m-1)/2) / m) + 1 (and at least segment 1).
        m = self.m
        return int(np.ceil((self.n_seg - 1) * m + (m - 1) / 2)) if self.n_seg >= 2 else 0

    def _advance(self, limit: int | None = None) -> None:
        """Plan every frame the points so far settle (up to ``limit``, the last, at the end)."""
        self._smooth()
        while True:
            t0 = self.planned
            a = self.decisions * self.step
            v_ready = self._speed_ready()
            ready = min(v_ready, self.n_path - 1)  # a heading reads the next point
            if limit is not None:
                ready = min(ready, limit)
            if t0 >= ready:
                break
            if t0 == a:
                ahead = a + lookahead(self.m)
                if limit is not None:
                    ahead = min(ahead, limit - 1)  # the batch's decisions read its last frame there
                if a + self.horizon >= v_ready:
                    break
                self._decide(a, ahead)
            t1 = min(ready, (self.decisions) * self.step)
            if t1 <= t0:
                break
            self._plan_block(t0, t1)
        stop = self.planned if limit is not None else self.planned - self.lock_lag
        self.settled = max(self.settled, stop)

    def _decide(self, a: int, ahead: int) -> None:
        """Decision k at frame a on the speed at frame ``ahead`` (as :func:`synthesis.schedule`'s
        loop body: for the characters free now or before the next decision)."""
        k = self.decisions
        self.decisions += 1
        # The clocks and distance of the frames up to the next decision (known), so transitions
        # ending before it are found now (the batch knows every end beforehand).
        v = self._speeds(np.arange(a, a + self.step))
        pts = self._path(a, a + self.step + 1)
        if self.plan_compiled:
            self._compiled_block(a, v, pts, None)
        else:
            self._scan(a, v, pts)
        self._normalize(a)
        draws = uniform(self.keys, SCHEDULE_STREAM + k, N_HUBS)
        nxt = _choose(self.bank, self.current, self._speeds(np.array([ahead]))[:, 0], draws)
        go = np.flatnonzero((self.busy < a + self.step) & (nxt != self.current))
        if len(go) == 0:
            return
        P = self.pieces
        cur, new = self.current[go], nxt[go]
        d = np.maximum(a, self.busy[go])
        j = 1 + (self.busy[go] > a)  # the slot of the gait playing from d
        n = np.arange(len(go))
        # The gait's stride clock on to its entry phase (these characters only: a stride ahead).
        v = self._speeds(np.arange(a, a + self.horizon + 1), go)
        clock = hub_clocks(self.bank, cur, v, a, self.clock[:, go], self.tempo[go])
        wait, tr, resume = switch(self.kinds, cur, new, P.first[go, j], clock[n, d - a] - P.clock0[go, j])
        begin = entry_frame(clock, d - a, wait) + a
        assert (begin <= a + self.horizon).all(), "the horizon covers a stride from the decision on"
        P.start[go, j + 1], P.kind[go, j + 1], P.first[go, j + 1] = begin, tr, 0
        P.clock0[go, j + 1] = begin.astype(np.float64)  # a transition's clock is time
        P.start[go, j + 2], P.kind[go, j + 2], P.first[go, j + 2] = NEVER, new, resume
        self.busy[go] = NEVER
        self.current[go] = new

    def _scan(self, t0: int, v: Floats, pts: Floats) -> tuple[Floats, Floats]:
        """Frames [t0, t0 + n) (``v (C, n)``, ``pts (C, n + 1, 3)``): the clocks and distance at
        frames t0 .. t0 + n from the carried ones, and the pieces' starts and ends there
        (the numpy reference of :func:`plan_kernels.live_block`'s scan)."""
        n = v.shape[1]
        clocks = stride_clocks(self.bank, self.kinds, v, t0, self.clock, self.tempo)
        step = np.linalg.norm(np.diff(pts[..., _GROUND], axis=1), axis=-1)
        walked = np.cumsum(np.concatenate([self.walked[:, None], step], axis=1), axis=1)  # (C, n+1)
        self._start_distances(t0, n, walked)
        self._end_transitions(t0, n, walked, clocks)
        return clocks, walked

    def _start_distances(self, t0: int, n: int, walked: Floats) -> None:
        """The distance travelled at their start of the pieces starting within frames ``[t0, t0 + n)``
        (``walked (C, >= n)``: from frame t0 on)."""
        P = self.pieces
        sc, sj = np.nonzero((P.start[:, 1:] >= t0) & (P.start[:, 1:] < t0 + n))
        P.trav0[sc, sj + 1] = walked[sc, P.start[sc, sj + 1] - t0]

    def _end_transitions(self, t0: int, n: int, walked: Floats, clocks: Floats) -> None:
        """Transitions under way (their gait's start not found yet: the slot after the
        transition's holds it, not started) that end within frames ``[t0, t0 + n)``: at the first
        frame after its start where its distance is covered. ``walked (C, >= n)``,
        ``clocks (kinds, C, >= n)``: from frame t0 on."""
        P, h = self.pieces, self.scales
        pc = np.flatnonzero(self.busy == NEVER)
        j = (P.start[pc, 1:] == NEVER).argmax(axis=1)  # the slot before the gait not started
        b = P.start[pc, j]
        pc, j, b = pc[b < t0 + n], j[b < t0 + n], b[b < t0 + n]
        if len(pc) == 0:
            return
        dist = distance_since(walked[pc, :n] / h[pc, None], self.bank.creep, b, t0,
                              at=P.trav0[pc, j, None] / h[pc, None])
        covered = dist >= self.tables.total[P.kind[pc, j]][:, None]
        done = covered & (np.arange(t0, t0 + n)[None, :] > b[:, None])
        hit = done.any(axis=1)
        ec, ej, et = pc[hit], j[hit] + 1, done[hit].argmax(axis=1)
        P.start[ec, ej] = t0 + et
        P.clock0[ec, ej] = clocks[np.minimum(P.kind[ec, ej], N_HUBS), ec, et]
        P.trav0[ec, ej] = walked[ec, et]
        self.busy[ec] = t0 + et

    def _normalize(self, t: int) -> None:
        """Slots shifted so slot 1 is the piece playing at frame t."""
        P = self.pieces
        for _ in range(SLOTS - 2):
            shift = P.start[:, 2] <= t
            if not shift.any():
                return
            for arr in (P.start, P.kind, P.first, P.clock0, P.trav0):
                arr[shift, :-1] = arr[shift, 1:]
            P.start[shift, -1] = NEVER
            P.before[shift] = True

    def _plan_block(self, t0: int, t1: int) -> None:
        """Frames [t0, t1): no decision falls inside."""
        self._normalize(t0)
        n = t1 - t0
        v = self._speeds(np.arange(t0, t1))
        pts = self._path(t0, t1 + 1)
        k = self.out_step
        sent = slice(-t0 % k, n, k)  # the block's frames sent (multiples of k)
        block = self.buffer.reserve_plan(-(-t1 // k) - -(-t0 // k))  # written in place
        out: tuple[NDArray[Any], ...] = (block.rows, block.weights, block.gait, block.contacts,
                                         block.stitches)
        if self.plan_compiled:
            self._compiled_block(t0, v, pts, out)
        else:
            for dest, part in zip(out, self._block_rows(t0, t1, v, pts), strict=True):
                dest[...] = part[:, sent]
        block.yaw[...] = self._headings(t0, t1)[:, sent]
        block.path[...] = pts[:, sent]
        self.planned = t1

    def _compiled_block(self, t0: int, v: Floats, pts: Floats, out: tuple[NDArray[Any], ...] | None) -> None:
        """:func:`plan_kernels.live_block`: the scan of frames [t0, t0 + n) (as :meth:`_decide`
        makes it, ``out`` None) or the block's rows as :meth:`_block_rows` (into ``out``)."""
        P = self.pieces
        walked = plan_kernels.live_block(
            self.tables, self.bank.contacts, MAX_RATE, min(self.bank.speeds), self.slow, STAND_SHARE,
            self.margin, self.bank.creep, t0, v, pts, self.scales, self.tempo,
            self.clock, self.walked, (P.start, P.kind, P.first, P.clock0, P.trav0), P.before, self.busy, out,
            self.out_step)
        if out is not None:
            self.walked = walked

    def _block_rows(self, t0: int, t1: int, v: Floats, pts: Floats) -> tuple[NDArray[Any], ...]:
        """The numpy reference of a block's rows, weights, gait, contacts and stitches (the
        clocks and distance carried on to t1)."""
        bank, kinds, P = self.bank, self.kinds, self.pieces
        C, n = len(self.scales), t1 - t0
        t = np.arange(t0, t1)
        clocks, walked = self._scan(t0, v, pts)  # to t1: the next block starts from there
        h = self.scales[:, None]
        c_all = np.arange(C)
        # Which slot plays each frame, and the slot before it.
        e = 1 + (t[None, :, None] >= P.start[:, None, 2:]).sum(axis=2)
        cc = c_all[:, None]
        kind, first = P.kind[cc, e], P.first[cc, e]
        start, clock0, trav0 = P.start[cc, e], P.clock0[cc, e], P.trav0[cc, e]
        tt = np.broadcast_to(np.arange(n)[None, :], (C, n))
        local = np.floor(first + clocks[np.minimum(kind, N_HUBS), cc, tt] - clock0 + 0.5).astype(np.int64)
        walked_since = (walked[:, :n] / h - trav0 / h) + bank.creep * local
        since = t[None, :] - start
        fc, ft = np.nonzero(((e >= 2) | P.before[:, None]) & (since < self.margin))  # a piece before
        pe = e[fc, ft] - 1
        p_kind = P.kind[fc, pe]
        p_local = np.floor(P.first[fc, pe] + clocks[np.minimum(p_kind, N_HUBS), fc, ft]
                           - P.clock0[fc, pe] + 0.5).astype(np.int64)
        rows, weights, gait = blend_rows(bank, kinds, self.margin, kind, local, v, walked_since, since,
                                         (fc, ft), p_kind, p_local)
        stitches = (t[None, :] >= 1) & ((P.start[:, 1:, None] == t[None, None, :]).any(axis=1))
        self.clock = clocks[:, :, n].copy()
        self.walked = walked[:, n].copy()
        return rows, weights, gait, bank.contacts[rows[..., 0]], stitches

    def _headings(self, t0: int, t1: int) -> Floats:
        """(C, n) yaw as :func:`synthesis.headings` (gradient; held while slow; before the first
        move, the heading of the first move -- where it is known yet, else ``heading``)."""
        lo = max(t0 - 1, 0)
        hi = min(t1 + 1, self.n_path)
        pts = self._path(lo, hi)[..., _GROUND]
        if self.plan_compiled:  # the same, a character at a time (a tenth of a shard's tick in numpy)
            yaw, never = plan_kernels.live_headings(pts, t0 - lo, t1 - t0, self.bank.fps, MIN_TURN_SPEED,
                                                    self.last_dir, self.moved)
            if never.any():
                yaw[never] = self._first_move(never, t1)[:, None]
            return yaw
        d = np.gradient(pts, axis=1) if pts.shape[1] > 1 else np.zeros_like(pts)
        if lo == 0 and pts.shape[1] > 1:
            d[:, 0] = pts[:, 1] - pts[:, 0]
        d = d[:, t0 - lo:t0 - lo + (t1 - t0)]
        moving = np.linalg.norm(d, axis=-1) * self.bank.fps >= MIN_TURN_SPEED
        n = t1 - t0
        idx = np.maximum.accumulate(np.where(moving, np.arange(n), -1), axis=1)
        held = np.where(idx[..., None] >= 0, np.take_along_axis(d, np.maximum(idx, 0)[..., None], axis=1),
                        self.last_dir[:, None, :])
        yaw = np.arctan2(held[..., 0], held[..., 1])
        never = ~self.moved & ~moving.any(axis=1)  # not moved yet by t1: where will it go?
        if never.any():
            ahead = self._first_move(never, t1)
            yaw[never] = ahead[:, None]
        early = ~self.moved & moving.any(axis=1)  # starts moving in this block: before, face that way
        if early.any():
            ec = np.flatnonzero(early)
            f = moving[ec].argmax(axis=1)
            first_yaw = np.arctan2(d[ec, f, 0], d[ec, f, 1])
            before = np.arange(n)[None, :] < f[:, None]
            yaw[ec] = np.where(before, first_yaw[:, None], yaw[ec])
        last = moving.any(axis=1)
        self.last_dir[last] = d[last, n - 1 - moving[last, ::-1].argmax(axis=1)]
        self.moved |= last
        return np.asarray(yaw)

    def _first_move(self, who: NDArray[np.bool_], t1: int) -> Floats:
        """Yaw of each `who` character's first moving frame at or after t1 in the known path,
        else ``heading``."""
        pts = self._path(t1 - 1, self.n_path)[who][..., _GROUND]
        yaw = np.full(int(who.sum()), self.heading)
        if pts.shape[1] < 3:
            return yaw
        d = np.gradient(pts, axis=1)[:, 1:-1]  # frames t1 .. n_path - 2: central differences
        moving = np.linalg.norm(d, axis=-1) * self.bank.fps >= MIN_TURN_SPEED
        has = moving.any(axis=1)
        f = moving.argmax(axis=1)
        dd = d[np.arange(len(d)), f]
        yaw[has] = np.arctan2(dd[has, 0], dd[has, 1])
        return yaw

    def _emit(self, start: int, stop: int) -> Window:
        """Render planned frames [start, stop) (every ``out_step``-th frame of the library's)."""
        # Only the frames sent are rendered -- the foot lock too works on them alone (a plant's
        # average over its frames sent), so 30 fps out costs half of 60; the buffer holds those.
        k, o0 = self.out_step, self.buffer.start  # o0: the first frame kept, by frame sent
        buf = self.buffer.plan()
        lo, hi = -(-start // k) - o0, -(-stop // k) - o0
        if self.foot_lock:
            begin, end = (kernels.lock_context if self.compiled else lock_context)(buf.contacts, lo, hi)
        else:
            C = len(self.scales)
            begin, end = np.full(C, lo), np.full(C, hi)
        ground = None
        if self.ground is not None:
            buf, ground = on_ground(self.bank, buf, self.ground, int(begin.min()), int(end.max()))
        if self.compiled:
            # The feet of frames posed by earlier windows, by frame sent (from 0), kept for later ones.
            n = buf.yaw.shape[1]
            self.feet.reserve(max(o0 + n - self.feet.stop, 0))
            posed = kernels.Posed(self.feet.columns(o0, o0 + n)[0][0], self.known_feet - o0, self.recent_legs,
                                  self.legs_at - o0)
            out = None if self.scratch is None else self.scratch.array(
                "live.rotations", (len(self.scales), hi - lo, self.bank.skeleton.n_joints, 4), np.float32)
            root, rot = kernels.render_window(self.bank, buf, lo, hi, begin, end, self.foot_lock, posed, out,
                                              self.share, ground)
            self.known_feet, self.legs_at = posed.frames + o0, posed.legs_at + o0
        else:
            cb, ce = int(begin.min()), int(end.max())
            root, rot = render(self.bank, buf.window(cb, ce), self.foot_lock,
                               None if ground is None else ground.window(cb, ce))
            root, rot = root[:, lo - cb:hi - cb], rot[:, lo - cb:hi - cb]
        # Copies: the buffer's columns are written over by later blocks.
        window = Window(self.emitted, root, rot, buf.gait[:, lo:hi].copy(), buf.contacts[:, lo:hi].copy())
        self.emitted += hi - lo
        if stop == self.settled:
            # The context the next frames' lock reads. Not before every frame settled is given:
            # a window bounded short of them leaves the rest as far a context as one window of
            # them all would have (a standing horse's plant, longer than what is kept, is
            # averaged over the same frames).
            self.buffer.drop_before(-(-(stop - self.kept_frames) // k))
            self.feet.drop_before(self.buffer.start)
        self.path.drop_before(self.planned - 2)  # the path the next block and heading read
        first_seg = max(int(np.floor((self.planned - self.m / 2) / self.m)) - 1, 0)  # the speeds still read
        if first_seg > self.seg_start:
            self.seg = self.seg[:, first_seg - self.seg_start:]
            self.seg_start = first_seg
        return window
