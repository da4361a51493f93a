"""Live synthesis: trajectory points arrive a few at a time (a crowd simulation as it runs) and
poses come back for every frame the plan can settle: the batch's planner
(:class:`synth_core.runtime.plan.Planner`, one state machine for both) advanced frame block by
frame block as the points arrive, its state carried between blocks.

Every step of the batch plan is causal but for a bounded look-ahead, which is the latency:

- smoothing reads ``radius`` points ahead (4 sigma);
- a frame's speed is interpolated between segment centres, so it waits for the segment after
  its own (up to 1.5 segments ahead), and a gait is chosen on the speed ``LOOKAHEAD`` segments
  ahead of its decision (decided once the speeds up to a stride past that are known, ``horizon``:
  so the windows come as they did when the entry phase was searched ahead; the planner, stepping
  frame by frame, no longer needs them);
- a transition ends where the character has covered its distance -- found as the path arrives.

So a frame is planned about ``horizon + 1.5 m + radius`` frames after its point arrived and
sent ``lock_lag`` frames later (:attr:`LiveSynth.latency_frames`; horse, 60 fps:
112 + 84 + 16 + 2 + 20 = 234 frames, 3.9 s), and then its plan is exactly the batch plan of the
whole trajectory's, bit for bit (tests/test_plan.py), but for:

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

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core import TEMPO_SPREAD
from synth_core.compiled import backend as backends
from synth_core.compiled import kernels, render_pool
from synth_core.compiled.foot_kernels import LEG_WIDTH, NOWHERE
from synth_core.compiled.scratch import Scratch
from synth_core.runtime import gaussian
from synth_core.runtime.bank import Bank
from synth_core.runtime.columns import Columns, PlannedColumns
from synth_core.runtime.draws import SCHEDULE_STREAM, character_keys, uniform
from synth_core.runtime.footlock import EASE_FRAMES, PAD
from synth_core.runtime.plan import (
    MARGIN,
    N_HUBS,
    Decisions,
    Floats,
    Headings,
    Planner,
    decision_step,
    lookahead,
    tables,
)
from synth_core.runtime.streaming import Window, lock_context
from synth_core.runtime.synthesis import character_scales, character_tempo, render
from synth_core.runtime.terrain import HeightField, on_ground
from synth_core.runtime.trajectory import DEFAULT_SIGMA, GROUND, TELEPORT_M, TrajectoryError

KEEP_PLANS = 1  # of the slowest cycle: planned frames kept as the foot lock's context
LOCK_LAG = 20  # frames planned but not yet sent, so that most plants a frame is in have ended


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
        self.compiled = backends.compiled(backend)
        # first: the index of these characters' first in the session (a shard of it: see
        # synth_core.runtime.live_shards), so each draws as it would among all of them.
        self.keys = character_keys(seed, C, seeds, first)
        self.scales = character_scales(self.keys, scales, scale_range)
        if not (np.isfinite(self.scales) & (self.scales > 0)).all():
            bad = int(np.flatnonzero(~(np.isfinite(self.scales) & (self.scales > 0)))[0])
            raise TrajectoryError(f"scale: must be a positive number, got {self.scales[bad]}", bad)
        self.tempo = character_tempo(self.keys, self.scales, size_matching, tempo_spread)
        self.pace = self.scales * self.tempo  # path speed over this: the library's (plan.plan)
        ratio = bank.fps / fps
        self.out_step = int(round(ratio)) if abs(ratio - round(ratio)) < 1e-9 else 1
        self.frames_of = tables(bank).frames  # of each piece kind
        self.m = bank.mean_cycle
        self.step = decision_step(self.m)
        # Speeds known before a decision is made: the one it reads, and those of every frame up to
        # its gait's entry phase (decided up to a step early, a stride at most) -- which the
        # planner, stepping frame by frame, no longer needs: kept so that windows are sent as
        # before (a shorter latency is a later change).
        self.horizon = max(lookahead(self.m), self.step + int(self.frames_of[1:N_HUBS].max()))
        self.pad = int(np.ceil(4 * sigma)) if sigma > 0 else 0
        self.radius = int(4.0 * sigma + 0.5) if sigma > 0 else 0
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
        self.path = Columns(C, [((3,), np.float64)], 2 * self.latency_frames + self._end_frames)
        self.n_path = 0
        self.seg = np.zeros((C, 0))  # segment speeds / (scale x tempo): the library's speeds
        self.seg_start = 0
        self.n_seg = 0
        # The plan and the heading, carried from block to block.
        self.planner = Planner(bank, self.scales, self.tempo, margin, backend)
        self.heading_state = Headings(C, backend)
        self.decisions = 0
        self.no_decision = Decisions(0, np.zeros((C, 0)), np.zeros((C, 0, N_HUBS)))  # a block without one
        self.planned = 0
        self.emitted = 0
        # Planned frames kept as the foot lock's context (see _emit).
        self.buffer = PlannedColumns(self.scales, -(-2 * (self.lock_lag + self.kept_frames + 2 * self.step)
                                              // self.out_step))
        # The feet of the frames sent and of those after them posed by the foot lock so far (frames
        # [0, known_feet) of each character's): see kernels.render_window.
        # One row of (frames, C, 4, 3): its views are C-contiguous, as the kernel takes them.
        self.feet = Columns(1, [((C, 4, 3), np.float64)],
                             self.buffer.arrays[0].shape[1] + self._end_frames // self.out_step + 1)
        self.known_feet = np.zeros(C, np.int64)
        # What the sink reads of the legs on the last PAD frames sent (see kernels.Posed).
        self.recent_legs = np.empty((C, PAD, 4, LEG_WIDTH))
        self.legs_at = np.full(C, NOWHERE)

    @property
    def window_frames(self) -> int:
        """Frames (sent) one segment settles: a window's usual size, a bound for larger ones."""
        return -(-self.m // self.out_step)

    @property
    def kept_frames(self) -> int:
        """Planned frames before the next to send kept for the foot lock: whole plants reaching
        back past PAD, at most KEEP_PLANS of the slowest cycle."""
        return PAD + EASE_FRAMES + KEEP_PLANS * int(self.frames_of[1:N_HUBS].max())

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
        if self.compiled:  # a fast pass (its numpy took a millisecond of a 2,000-horse tick's serial part)
            last = self.inputs[:, -1] if self.inputs.shape[1] else np.full((C, 3), np.nan)
            # Contiguous: one compiled signature for every call (none compiled mid-session).
            if self.planner.kernels.points_fine(np.ascontiguousarray(last), np.ascontiguousarray(arr),
                                                float(TELEPORT_M)):
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
            step = np.linalg.norm(np.diff(pts[..., GROUND], axis=1), axis=-1)
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
            decisions = self.no_decision
            if t0 == a:
                ahead = a + lookahead(self.m)
                if limit is not None:
                    ahead = min(ahead, limit - 1)  # the batch's decisions read its last frame there
                if a + self.horizon >= v_ready:
                    break
                decisions = self._decision(ahead)
            t1 = min(ready, (self.decisions) * self.step)
            self._plan_block(t0, t1, decisions)
        stop = self.planned if limit is not None else self.planned - self.lock_lag
        self.settled = max(self.settled, stop)

    def _decision(self, ahead: int) -> Decisions:
        """The next gait decision (at frame ``decisions * step``): on the speed at frame ``ahead``."""
        k = self.decisions
        self.decisions += 1
        draws = uniform(self.keys, SCHEDULE_STREAM + k, N_HUBS)[:, None]
        return Decisions(k, self._speeds(np.array([ahead])), draws)

    def _plan_block(self, t0: int, t1: int, decisions: Decisions) -> None:
        """Frames [t0, t1), with the decision made at t0 if there is one."""
        v = self._speeds(np.arange(t0, t1))
        pts = self._path(t0, t1 + 1)
        k = self.out_step
        sent = slice(-t0 % k, t1 - t0, k)  # the block's frames sent (multiples of k)
        block = self.buffer.reserve_plan(-(-t1 // k) - -(-t0 // k))  # written in place
        self.planner.advance(t0, v, pts, decisions, block, k)
        yaw, lean = self._headings(t0, t1)
        block.yaw[...], block.lean[...] = yaw[:, sent], lean[:, sent]
        block.path[...] = pts[:, sent]
        self.planned = t1

    def _headings(self, t0: int, t1: int) -> tuple[Floats, Floats]:
        """(C, n) yaw and lean of frames [t0, t1) (plan.Headings); a character standing until then
        faces where it will first go if that is known yet, else ``heading``."""
        lo = max(t0 - 1, 0)
        facing = np.full(len(self.scales), self.heading)
        ground = self._path(lo, t1 + 1)[..., GROUND]
        return self.heading_state.advance(ground, t0 - lo, t1 - t0, self.bank.fps, facing,
                                          ahead=lambda who: self._path(lo, self.n_path)[who][..., GROUND])

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
