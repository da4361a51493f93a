"""Live synthesis: trajectory points arrive a few at a time (a crowd simulation as it runs) and
poses come back for every frame the plan can settle: the batch's planner
(:class:`synth_core.runtime.plan.Planner`, one state machine for both) advanced frame block by
frame block as the points arrive, its state carried between blocks.

Every step of the batch plan is causal but for a bounded look-ahead, which is the latency:

- smoothing reads ``radius`` points ahead (4 sigma);
- a frame's speed is interpolated between segment centres, so it waits for the segment after
  its own (up to 1.5 segments ahead), and a gait is chosen on the speed ``LOOKAHEAD`` segments
  ahead of its decision, decided once the speeds a stride past that are known (``horizon``);
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

**The low-latency mode** (``latency_ms``, issue 31) drops those look-aheads for a budget of
``latency_ms`` (library frames: ``latency_ms * fps / 1000``): the path is a causal local-linear
fit (:mod:`synth_core.runtime.causal`) reading a few points ahead, a frame's speed the slope of a
wider one (or the velocity the simulator sent with its point: its speed, and the way faced), each
gait decision reads the newest speed known (no stride horizon), and the foot lock gets the rest
of the budget, each plant pinned at the average of its frames known when its first frame is sent
(``plant_frames``), so no sent frame's plant moves later. A plant pinned at its first frames
leaves its whole drift (up to half a metre on a turn) to the IK at its end where the batch's
average leaves half; the swing after it eases that correction out over a step's frames
(``STEP_S``: docs/streaming.md).

The foot lock pins a plant at its average position, which needs the plant's end: frames are
sent ``lock_lag`` frames (``LOCK_LAG``, a third of a second) after they are planned, locked over
every frame planned so far; a plant still going on is pinned at its average so far and moves by
the difference in the next block (tests/test_live.py holds the skate near the batch's).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core import TEMPO_SPREAD
from synth_core.compiled import backend as backends
from synth_core.compiled import kernels, render_pool
from synth_core.compiled.foot_kernels import LEG_WIDTH, NOWHERE
from synth_core.compiled.scratch import Scratch
from synth_core.motion import quat
from synth_core.runtime.bank import Bank
from synth_core.runtime.columns import Columns, PlannedColumns
from synth_core.runtime.draws import SCHEDULE_STREAM, character_keys, uniform_streams
from synth_core.runtime.footlock import EASE_FRAMES, PAD
from synth_core.runtime.live_path import VELOCITY, LivePath
from synth_core.runtime.plan import (
    MARGIN,
    N_HUBS,
    TURN_S,
    Decisions,
    Floats,
    Headings,
    Plan,
    Planner,
    character_leads,
    decision_step,
    lookahead,
    tables,
)
from synth_core.runtime.streaming import Window
from synth_core.runtime.synthesis import character_scales, character_tempo
from synth_core.runtime.terrain import HeightField, on_ground
from synth_core.runtime.trajectory import DEFAULT_SIGMA, GROUND, TrajectoryError

KEEP_PLANS = 1  # of the slowest cycle: planned frames kept as the foot lock's context
LOCK_LAG = 20  # frames planned but not yet sent, so that most plants a frame is in have ended
# A new ground (set_ground) is faded in over this much of the frames rendered after it: a herd
# whose ground rises 20 cm under it is lifted over 0.4 s, not in one frame.
GROUND_BLEND_S = 0.4

# The low-latency mode (``latency_ms``): the budget's limits, and the default of its named profile.
LATENCY_MS = (50.0, 2000.0)
LOW_LATENCY_MS = 100.0
# Its velocity fit (causal.fit_weights) is this many segments wide (sigma): a gait's speed read
# over a fraction of a stride, not the point-to-point jitter of a simulator's path.
SPEED_SIGMA = 1 / 8


def _checked_fps(bank: Bank, n_characters: int, fps: float | None, sigma: float) -> float:
    """The session's input frame rate (default: the library's), its arguments checked."""
    if not (isinstance(n_characters, int) and n_characters >= 1):
        raise TrajectoryError(f"characters: need at least one, got {n_characters}")
    fps = bank.fps if fps is None else float(fps)
    if not (np.isfinite(fps) and 0 < fps <= bank.fps):
        raise TrajectoryError(f"fps: must be within (0, {bank.fps:g}] (the library's), got {fps}")
    if not (np.isfinite(sigma) and 0 <= sigma <= 100):
        raise TrajectoryError(f"sigma: must be within [0, 100] frames, got {sigma}")
    return fps


class LiveSynth(LivePath):
    """Characters whose trajectories grow: :meth:`append` points, get back the new frames.

    All characters advance together (a simulation steps every agent each tick): each ``append``
    brings the same number of points for every character, at ``fps``. Frames come back at the
    library's frame rate -- or at ``fps``, every k-th frame, where the library's rate is k times it.

    ``reuse_windows``: each window's rotations are rendered over the last's (the compiled render;
    on pages kept from window to window): a window's arrays then hold only until the next
    :meth:`append`, :meth:`take` or :meth:`finish` (fresh pages, zeroed by the OS as first
    written, are dear: :mod:`synth_core.compiled.scratch`). Without it, every window is new arrays.

    ``share_render``: each window's render is cut into parts that idle render-pool threads may
    take (:func:`synth_core.compiled.render_pool.shared`): for a session cut into shards, each advanced
    by a pool thread (see :mod:`synth_core.runtime.live_shards`).

    A call's kernels run on its thread alone (a tick's are small: ``render_pool.one_thread``).
    """

    # The session's options are keywords that callers pass through (service, live_shards, tests).
    def __init__(self, bank: Bank, n_characters: int, fps: float | None = None, *,  # noqa: PLR0913
                 scales: ArrayLike | None = None, seed: int = 0, seeds: ArrayLike | None = None,
                 scale_range: tuple[float, float] = (1.0, 1.0), sigma: float = DEFAULT_SIGMA,
                 margin: int = MARGIN, foot_lock: bool = True, backend: str = "auto",
                 heading: float = 0.0, lock_lag: int = LOCK_LAG, first: int = 0,
                 reuse_windows: bool = False, share_render: bool = False, size_matching: str = "froude",
                 tempo_spread: float = TEMPO_SPREAD, ground: HeightField | None = None,
                 latency_ms: float | None = None) -> None:
        fps = _checked_fps(bank, n_characters, fps, sigma)
        C = n_characters
        self.bank, self.fps, self.sigma, self.margin = bank, fps, float(sigma), margin
        self.foot_lock, self.heading = foot_lock, float(heading)
        self.ground = ground  # the terrain (synth_core.runtime.terrain), rendered on in _emit
        # The ground faded out since set_ground, from library frame blend_from on (see _emit).
        self.old_ground: HeightField | None = None
        self.blend_from: int | None = None
        self.scratch = Scratch() if reuse_windows else None
        self.share = render_pool.shared if share_render else None
        self.lock_lag = lock_lag if foot_lock else 0
        self.rendered = 0  # library frames rendered
        self.settled = 0  # library frames planned to send: [rendered, settled) wait for take()
        self.compiled = backends.compiled(backend)
        # first: the index of these characters' first in the session (a shard of it: see
        # synth_core.runtime.live_shards), so each draws as it would among all of them.
        self.keys = character_keys(seed, C, seeds, first)
        self._draw_characters(scales, scale_range, size_matching, tempo_spread)
        self._set_timing(sigma, latency_ms)
        self._start_input(C)
        self._start_plan(C, margin, backend)
        self._start_foot_lock(C)

    def _draw_characters(self, scales: ArrayLike | None, scale_range: tuple[float, float], size_matching: str,
                         tempo_spread: float) -> None:
        """Each character's scale, tempo and pace, drawn from its key."""
        self.scales = character_scales(self.keys, scales, scale_range)
        if not (np.isfinite(self.scales) & (self.scales > 0)).all():
            bad = int(np.flatnonzero(~(np.isfinite(self.scales) & (self.scales > 0)))[0])
            raise TrajectoryError(f"scale: must be a positive number, got {self.scales[bad]}", bad)
        self.tempo = character_tempo(self.keys, self.scales, size_matching, tempo_spread)
        self.leads = character_leads(self.bank, self.keys)  # rows on from the table's (plan.character_leads)
        self.pace = self.scales * self.tempo  # path speed over this: the library's (plan.plan)

    def _set_timing(self, sigma: float, latency_ms: float | None) -> None:
        """Frame steps, decision step, look-ahead and the smoothing's reach (``latency_ms``: the
        low-latency mode's, see :meth:`_low_latency`)."""
        bank, fps = self.bank, self.fps
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
        # Points read either side of a smoothed frame: the Gaussian's radius (exact mode).
        self.behind = self.ahead = self.radius
        self.latency_ms = None if latency_ms is None else float(latency_ms)
        self.plant_frames: int | None = None  # the exact mode's plants average all their frames
        if self.latency_ms is not None:
            self._low_latency(self.latency_ms)

    def _start_plan(self, C: int, margin: int, backend: str) -> None:
        """Smoothed path, segment speeds, and what the plan carries from block to block."""
        # Room for the path the finish adds too (see _end): growing at the finish moved it into
        # fresh memory, 20-30 ms of a 2,000-horse session's finish (page faults).
        # The path followed and the one whose way the body faces (trajectory.Prepared.facing).
        self.path = Columns(C, [((3,), np.float64), ((3,), np.float64)],
                            2 * self.latency_frames + self._end_frames)
        self.n_path = 0
        self.seg = np.zeros((C, 0))  # segment speeds / (scale x tempo): the library's speeds
        self.seg_start = self.n_seg = 0
        # The plan and the heading, carried from block to block. The exact mode's heading reads the
        # path as the batch's; the low-latency one's a step either side, its turn averaged (TURN_S).
        self.planner = Planner(self.bank, self.scales, self.tempo, self.leads, margin, backend,
                               0.0 if self.latency_ms is None else TURN_S, self.latency_ms is None)
        self.heading_state = Headings(C, backend) if self.latency_ms is None else Headings(C, backend, 1)
        self.decisions = self.planned = self.emitted = 0

    def _start_foot_lock(self, C: int) -> None:
        """Planned frames kept as the foot lock's context (see _emit), and the feet it has posed."""
        self.buffer = PlannedColumns(self.scales, -(-2 * (self.lock_lag + self.kept_frames + 2 * self.step)
                                              // self.out_step))
        # The feet of the frames sent and those after them the foot lock posed so far (frames [0,
        # known_feet) of each: kernels.render_window), a row of (frames, C, 4, 3): C-contiguous views.
        self.feet = Columns(1, [((C, 4, 3), np.float64)],
                            self.buffer.arrays[0].shape[1] + self._end_frames // self.out_step + 1)
        self.known_feet = np.zeros(C, np.int64)
        # What the sink reads of the legs on the last PAD frames sent (see kernels.Posed).
        self.recent_legs, self.legs_at = np.empty((C, PAD, 4, LEG_WIDTH)), np.full(C, NOWHERE)
        # The low-latency mode's plants as sent, each through the last frame sent (kernels.Posed):
        # a plant longer than the frames kept stays where its first frames put it. And the foot
        # targets of the last two frames sent (kernels.Posed): later windows ease from them; and
        # each ankle's bend side on the last frame sent: the next window keeps it.
        self.pins, self.pinned = np.zeros((C, 4, 3)), np.full((C, 4), NOWHERE)
        self.sent, self.sent_at, self.sides = np.zeros((C, 2, 4, 3)), np.full(C, NOWHERE), np.zeros((C, 4, 4))
        # The characters whose rotations are wanted (see set_posed); character-frames sent posed so far.
        self.pose, self.posed_frames = np.ones(C, bool), 0

    def _low_latency(self, latency_ms: float) -> None:
        """The low-latency mode: a frame is sent at most ``latency_ms`` after its point arrived
        (counted in library frames: see :attr:`latency_frames`). Its path is a causal fit
        (:mod:`synth_core.runtime.causal`) reading a few points ahead, its speed the fit's slope, its
        gait decided on the speed known when the decision is due, and the foot lock given what is
        left of the budget."""
        lo, hi = LATENCY_MS
        if not (np.isfinite(latency_ms) and lo <= latency_ms <= hi):
            raise TrajectoryError(f"latency_ms: must be within [{lo:g}, {hi:g}] ms, got {latency_ms}")
        budget = max(1, int(latency_ms * self.bank.fps / 1000 + 1e-9))  # library frames
        # Half of what is left after the heading's next point reads ahead (a fit over points on
        # both sides averages noise a one-sided one extrapolates), the rest waits for plants to end.
        self.ahead = min((budget - 1) // 2, self.radius) if self.foot_lock else min(budget - 1, self.radius)
        self.lock_lag = budget - 1 - self.ahead if self.foot_lock else 0
        self.speed_sigma = max(self.sigma, SPEED_SIGMA * self.m)
        self.behind = max(self.radius, int(4.0 * self.speed_sigma + 0.5))
        self.pad = self.behind  # the head: the first points' line, back (LivePath._raw)
        self.horizon = 0  # decided on what has arrived
        # A plant's target: its frames known (planned) when its first frame is sent, no later ones,
        # so each window pins it where the last did (frames sent; see _emit).
        self.plant_frames = max(self.lock_lag // self.out_step, 1)
        self.frame_speed = np.zeros((len(self.scales), 0))  # per frame, the library's (as seg)
        self.frame_speed_start = 0

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
        if self.latency_ms is not None:  # the smoothing's look-ahead, the heading's next point, the lock
            return self.ahead + 1 + self.lock_lag
        return int(self.horizon + 1.5 * self.m + self.radius + 2) + self.lock_lag

    # -- input -------------------------------------------------------------------------------

    def append(self, points: ArrayLike, frames: int | None = None,
               velocity: ArrayLike | None = None) -> Window | None:
        """Points ``(C, n, 3)`` (n >= 1) at ``fps``, the next of every character's trajectory;
        the frames this settles (None: none yet) -- at most ``frames`` of them, the rest left
        for :meth:`take`: so a caller bounds a window's memory (10,000 horses: 6.4 MB of float32
        rotations a frame). ``velocity (C, n, 2)``: each point's ground velocity (x, z, m/s) if
        the simulator knows it: the low-latency mode's speeds and headings then read it, not a fit
        of the points (the exact mode's frames are the batch's: it only checks it)."""
        return self.append_checked(self.check(points, velocity), frames)

    @render_pool.one_thread()
    def append_checked(self, arr: Floats, frames: int | None = None) -> Window | None:
        """:meth:`append` of points :meth:`check` returned (not checked again)."""
        self.inputs = np.concatenate([self.inputs, arr], axis=1)
        self.n_inputs += arr.shape[1]
        if self.width > 3 and not self.velocity_sent:
            self.velocity_sent = not np.isnan(arr[..., VELOCITY]).all()
        self._retime()
        self._advance()
        return self.take(frames)

    def set_ground(self, ground: HeightField | None) -> None:
        """The terrain the frames rendered from now on stand on (None: the points' y), faded in
        over ``GROUND_BLEND_S`` from the next frame rendered: those frames are the motion on the
        ground before crossfaded to the motion on this one (root and joint rotations). A ground
        set while one is fading in replaces it: the fade goes on from the one before."""
        if self.blend_from is None:
            self.old_ground = self.ground
        self.ground, self.blend_from = ground, self.rendered

    def set_posed(self, pose: ArrayLike) -> None:
        """``(C,)`` bool: the characters whose rotations the frames rendered from now on need
        (a client's level of detail: False for one at root_gait). The others are not posed --
        no pose, no foot lock: a fraction of the render -- and get the plan's root (without the
        foot lock's sink), their gait and contacts as before; their rows of a window's rotations
        are left unset (nobody is sent them)."""
        arr = np.asarray(pose, bool)
        if arr.shape != self.pose.shape:
            raise TrajectoryError(f"pose: expected {len(self.pose)} flags (one per character), "
                                  f"got shape {arr.shape}")
        self.pose = arr.copy()

    @render_pool.one_thread()
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

    @render_pool.one_thread()
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
            self.pad = self.made - 1 if self.latency_ms is None else self.pad
            self._raw(np.zeros((len(self.scales), 0, self.width)))
        # As the batch does at the end: the path goes on as it went (point reflection)...
        end = self.n_raw
        last = self.longer[:, -1:]
        k = min(self.pad, self.longer.shape[1] - 1)
        tail = 2 * last - self.longer[:, -2:-2 - k:-1] if k else last[:, :0]
        tail[..., 3:] = np.nan  # no velocity sent past the end: the fit's of the path as it went
        # ... and on, standing, until every decision that reads it is made.
        hold = np.repeat(tail[:, -1:] if tail.shape[1] else last, self.latency_frames + self.m, axis=1)
        self._raw(np.concatenate([tail, hold], axis=1))
        self._advance(limit=end)

    # -- planning ------------------------------------------------------------------------------

    def _advance(self, limit: int | None = None) -> None:
        """Plan every frame the points so far settle (up to ``limit``, the last, at the end): one
        block, with every gait decision due in it made first (a block per decision step was three
        times the numpy calls and kernel launches a tick; the plan is the same either way)."""
        self._smooth()
        t0 = self.planned
        v_ready = self._speed_ready()
        reads = self.heading_state.chord_frames if limit is None else 1  # the points a heading reads ahead
        ready = min(v_ready, self.n_path - reads)
        if limit is not None:
            ready = min(ready, limit)
        first, aheads = self.decisions, list[int]()
        t1 = ready
        while (a := (first + len(aheads)) * self.step) < ready:
            if a + self.horizon >= v_ready:  # its speed not known yet: planned up to it
                t1 = a
                break
            ahead = a + lookahead(self.m)
            if self.latency_ms is not None:  # the speed known now: the newest
                ahead = min(ahead, v_ready - 1)
            if limit is not None:
                ahead = min(ahead, limit - 1)  # the batch's decisions read its last frame there
            aheads.append(ahead)
        if t0 < t1:
            self.decisions += len(aheads)
            draws = uniform_streams(self.keys, SCHEDULE_STREAM + first, len(aheads), N_HUBS)
            self._plan_block(t0, t1, Decisions(first, self._speeds(np.array(aheads, np.int64)), draws))
        stop = self.planned if limit is not None else self.planned - self.lock_lag
        self.settled = max(self.settled, stop)

    def _plan_block(self, t0: int, t1: int, decisions: Decisions) -> None:
        """Frames [t0, t1), with the decision made at t0 if there is one."""
        v, pts = self._speeds(np.arange(t0, t1)), self._path(t0, t1 + 1)
        k = self.out_step
        sent = slice(-t0 % k, t1 - t0, k)  # the block's frames sent (multiples of k)
        block = self.buffer.reserve_plan(-(-t1 // k) - -(-t0 // k))  # written in place
        yaw, lean, way, turned = self._headings(t0, t1)
        self.planner.advance(t0, v, pts, turned, decisions, block, k)
        block.yaw[...], block.lean[...], block.way[...] = yaw[:, sent], lean[:, sent], way[:, sent]
        block.path[...] = pts[:, sent]
        self.planned = t1

    def _headings(self, t0: int, t1: int) -> tuple[Floats, Floats, Floats, Floats]:
        """(C, n) yaw, lean, way and turn of frames [t0, t1) (plan.Headings); a character standing
        until then faces where it will first go if that is known yet, else ``heading``."""
        lo = max(t0 - self.heading_state.chord_frames, 0)
        facing = np.full(len(self.scales), self.heading)
        ground = self._facing(lo, min(t1 + self.heading_state.chord_frames, self.n_path))[..., GROUND]
        return self.heading_state.advance(ground, t0 - lo, t1 - t0, self.bank.fps, facing,
                                          ahead=lambda who: self._facing(lo, self.n_path)[who][..., GROUND],
                                          moving=self._path(lo, t1 + 1)[..., GROUND])

    def _fade(self, start: int, stop: int) -> Floats | None:
        """``(n,)`` how far the new ground has faded in on each frame sent of [start, stop), or
        None where it has on all of them (then the old one is dropped)."""
        if self.blend_from is None:
            return None
        k = self.out_step
        t = np.arange(-(-start // k), -(-stop // k)) * k  # library frames sent
        x = np.clip((t - self.blend_from + 1) / (GROUND_BLEND_S * self.bank.fps), 0.0, 1.0)
        if x.size == 0 or x.min() >= 1.0:
            self.old_ground, self.blend_from = None, None
            return None
        return np.asarray(x * x * (3.0 - 2.0 * x))

    def _render(self, buf: Plan, lo: int, hi: int, begin: NDArray[np.int64], end: NDArray[np.int64],
                field: HeightField | None, keep: bool
                ) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.bool_]]:
        """Root and rotations of buffered frames [lo, hi) on ``field``; ``keep``: the feet posed are
        kept for the next windows (else they are not read either: a crossfade's other motion).
        No plant is stepped (render_window's ``steps``): one still going on at the last frame
        planned was split anew by each window, the feet of frames sent pinned back or stepped
        again (low-latency horse jitter_10hz: strict skate p95 0.003 -> 77 mm). And its contacts."""
        ground, contacts = None, np.empty((len(self.scales), hi - lo, 4), np.bool_)
        if field is not None:
            buf, ground = on_ground(self.bank, buf, field, int(begin.min()), int(end.max()))
        if not keep:
            return *kernels.render_window(self.bank, buf, lo, hi, begin, end, self.foot_lock, None, None,
                                          self.share, ground, self.pose, self.compiled, self.plant_frames,
                                          steps=False, contacts=contacts), contacts
        # The feet of frames posed by earlier windows, by frame sent (from 0), kept for later ones.
        o0, n = self.buffer.start, buf.yaw.shape[1]
        self.feet.reserve(max(o0 + n - self.feet.stop, 0))
        posed = kernels.Posed(self.feet.columns(o0, o0 + n)[0][0], self.known_feet - o0, self.recent_legs,
                              self.legs_at - o0, self.pins, self.pinned - o0, self.sent, self.sent_at - o0,
                              self.sides)
        # Not touched beforehand: the rows of characters not posed (far, at root_gait) are never
        # written, so their pages never are either (a 5,000-horse session at root_gait held 54 MB
        # of them; 100,000 horses in such sessions, a gigabyte).
        out = None if self.scratch is None else self.scratch.array(
            "live.rotations", (len(self.scales), hi - lo, self.bank.skeleton.n_joints, 4), np.float32,
            touch=False)
        root, rot = kernels.render_window(self.bank, buf, lo, hi, begin, end, self.foot_lock, posed, out,
                                          self.share, ground, self.pose, self.compiled, self.plant_frames,
                                          steps=False, contacts=contacts)
        self.known_feet, self.legs_at, self.pinned = posed.frames + o0, posed.legs_at + o0, posed.pinned + o0
        self.sent_at = posed.sent_at + o0
        return root, rot, contacts

    def _emit(self, start: int, stop: int) -> Window:
        """Render planned frames [start, stop) (every ``out_step``-th frame of the library's)."""
        # Only the frames sent are rendered -- the foot lock too works on them alone (a plant's
        # average over its frames sent), so 30 fps out costs half of 60; the buffer holds those.
        k, o0 = self.out_step, self.buffer.start  # o0: the first frame kept, by frame sent
        buf = self.buffer.plan()
        lo, hi = -(-start // k) - o0, -(-stop // k) - o0
        if self.foot_lock:
            begin, end = kernels.lock_context(buf.contacts, lo, hi, self.compiled)
            # An unposed character reads its window's frames alone (so does the copy of the plan
            # the kernel reads, when no posed character's lock reaches further).
            begin[~self.pose], end[~self.pose] = lo, hi
        else:
            C = len(self.scales)
            begin, end = np.full(C, lo), np.full(C, hi)
        if (fade := self._fade(start, stop)) is not None:  # the motion on the ground before, crossfaded to
            old_root, old_rot, _ = self._render(buf, lo, hi, begin, end, self.old_ground, keep=False)
        root, rot, contacts = self._render(buf, lo, hi, begin, end, self.ground, keep=True)  # this one's
        if fade is not None:
            a = fade[None, :, None]
            root = (old_root * (1.0 - a) + root * a).astype(np.float32)
            rot = quat.nlerp(old_rot, rot, np.broadcast_to(a, rot.shape[:3])).astype(np.float32)
        self.posed_frames += int(self.pose.sum()) * (hi - lo)
        # Copies: the buffer's columns are written over by later blocks.
        window = Window(self.emitted, root, rot, buf.gait[:, lo:hi].copy(), contacts)
        self.emitted += hi - lo
        if stop == self.settled:
            # The context the next frames' lock reads. Not before every frame settled is given:
            # a window bounded short of them leaves the rest as far a context as one window of
            # them all would have (a standing horse's plant, longer than what is kept, is
            # averaged over the same frames).
            self.buffer.drop_before(-(-(stop - self.kept_frames) // k))
            self.feet.drop_before(self.buffer.start)
        self.path.drop_before(self.planned - 1 - self.heading_state.chord_frames)  # what the next block reads
        if self.latency_ms is not None:  # the speeds still read: the next block's, on
            drop = self.planned - self.frame_speed_start
            self.frame_speed, self.frame_speed_start = self.frame_speed[:, drop:], self.planned
            return window
        first_seg = max(int(np.floor((self.planned - self.m / 2) / self.m)) - 1, 0)  # the speeds still read
        if first_seg > self.seg_start:
            self.seg = self.seg[:, first_seg - self.seg_start:]
            self.seg_start = first_seg
        return window
