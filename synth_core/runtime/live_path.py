"""A live session's input side: points arriving a few at a time, retimed to the library's frame
rate, smoothed into the path the planner follows, and that path's speeds -- the exact mode's as
the batch makes them (Gaussian, segment speeds), the low-latency mode's by causal fits
(:mod:`synth_core.runtime.causal`) or, where the simulator sends them, its velocities.
:class:`synth_core.runtime.live.LiveSynth` is one of these with the planner and the render on top;
the attributes declared here are set by it."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core.runtime import causal, gaussian
from synth_core.runtime.bank import Bank
from synth_core.runtime.columns import Columns
from synth_core.runtime.plan import Floats, Planner
from synth_core.runtime.terrain import HeightField, laid
from synth_core.runtime.trajectory import GROUND, TELEPORT_M, TrajectoryError

# A low-latency session's input columns after each point's (x, y, z): the ground velocity (x, z,
# m/s) the simulator sent with it, NaN where it sent none (then the fit's is used).
VELOCITY = slice(3, 5)


class LivePath:
    """Points in, the smoothed path and its speeds out (see the module doc)."""

    bank: Bank
    fps: float
    scales: Floats
    pace: Floats
    compiled: bool
    planner: Planner
    ground: HeightField | None
    m: int
    sigma: float
    speed_sigma: float
    latency_ms: float | None
    pad: int
    radius: int
    behind: int
    ahead: int
    path: Columns
    n_path: int
    seg: Floats
    n_seg: int
    seg_start: int
    frame_speed: Floats
    frame_speed_start: int

    def _start_input(self, C: int) -> None:
        """Input (at fps) and the library-rate points made from it, none yet."""
        # The exact mode's frames are the batch's, which has no velocities: only the points kept.
        self.width = 3 if self.latency_ms is None else VELOCITY.stop
        self.inputs = np.zeros((C, 0, self.width))
        self.inputs_start = 0  # global index of inputs[:, 0]
        self.n_inputs = 0
        self.made = 0  # library-rate points made from the inputs
        self.first_points = np.zeros((C, 0, self.width))  # until the head can be made from them
        self.longer = np.zeros((C, 0, self.width))  # head reflection + raw points at the library's rate
        self.longer_start = 0
        self.n_raw = 0  # raw points in `longer` (after its head)
        self.face_apart = False  # the faced path stepped by a velocity sent (see _fit)
        self.velocity_sent = False  # any point appended with its velocity (see _fit)
        self.ended = False

    def check(self, points: ArrayLike, velocity: ArrayLike | None = None) -> Floats:
        """The points :meth:`append` would take, as float64 (a low-latency session's with the
        ``velocity`` columns after them, NaN if none) -- or :class:`TrajectoryError` for the first
        character they or the velocities are unusable for; nothing is changed either way."""
        arr = self._checked_points(points)
        v = None if velocity is None else self._checked_velocity(velocity, arr.shape[1])
        if self.latency_ms is None:  # checked all the same: a client's error is one in either mode
            return arr
        out = np.full(arr.shape[:2] + (self.width,), np.nan)
        out[..., :3] = arr
        if v is not None:
            out[..., VELOCITY] = v
        return out

    def _checked_velocity(self, velocity: ArrayLike, n: int) -> Floats:
        """``velocity (C, n, 2)``: each point's ground velocity (x, z), m/s, as float64."""
        v = np.asarray(velocity, np.float64)
        C = len(self.scales)
        if v.shape != (C, n, 2):
            raise TrajectoryError(f"velocity: expected shape ({C}, {n}, 2) (x and z, m/s, of every "
                                  f"point sent), got {v.shape}")
        finite = np.isfinite(v).all(axis=(1, 2))
        if not finite.all():
            c = int(np.flatnonzero(~finite)[0])
            frame = int(np.flatnonzero(~np.isfinite(v[c]).all(axis=-1))[0])
            raise TrajectoryError(f"velocity: NaN or Inf at its point {frame} of this message", c)
        speed = np.hypot(v[..., 0], v[..., 1])
        limit = TELEPORT_M * self.fps  # the points' own: a teleport a frame
        if speed.max() > limit:
            c = int(speed.max(axis=1).argmax())
            raise TrajectoryError(f"velocity: {speed[c].max():.1f} m/s is over the limit of {limit:g} m/s "
                                  f"({TELEPORT_M:g} m a point at {self.fps:g} fps: a teleport, not "
                                  "locomotion)", c)
        return v

    def _checked_points(self, points: ArrayLike) -> Floats:
        """:meth:`check`'s points."""
        if self.ended:
            raise TrajectoryError("points: the trajectories have ended (finish was called)")
        arr = np.asarray(points, np.float64)
        C = len(self.scales)
        if arr.ndim != 3 or arr.shape[0] != C or arr.shape[2] != 3 or arr.shape[1] < 1:
            raise TrajectoryError(f"points: expected shape ({C}, n >= 1, 3), got {arr.shape}")
        if self.compiled:  # a fast pass (its numpy took a millisecond of a 2,000-horse tick's serial part)
            last = self.inputs[:, -1, :3] if self.inputs.shape[1] else np.full((C, 3), np.nan)
            # Contiguous: one compiled signature for every call (none compiled mid-session).
            if self.planner.kernels.points_fine(np.ascontiguousarray(last), np.ascontiguousarray(arr),
                                                float(TELEPORT_M)):
                return arr  # else found and named below
        finite = np.isfinite(arr).all(axis=(1, 2))
        if not finite.all():
            c = int(np.flatnonzero(~finite)[0])
            frame = int(np.flatnonzero(~np.isfinite(arr[c]).all(axis=-1))[0])
            raise TrajectoryError(f"points: NaN or Inf at its point {frame} of this message", c)
        joined = np.concatenate([self.inputs[:, -1:, :3], arr], axis=1)
        jump = np.linalg.norm(np.diff(joined, axis=1), axis=-1)
        if jump.size and jump.max() > TELEPORT_M:
            c = int(jump.max(axis=1).argmax())
            raise TrajectoryError(f"points: jumps {jump[c].max():.1f} m in one frame (limit {TELEPORT_M} m: "
                                  "a teleport, not locomotion)", c)
        return arr

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
            # np.take: in C order (a slice-then-index result is laid out frames first, and
            # `longer`, joined from these, would be copied whole by each smoothing kernel every
            # tick); the products in place: a * (1 - w) + b * w, the same numbers, no temporaries.
            new = np.take(self.inputs, i0 - base, axis=1)
            new *= 1 - w
            b = np.take(self.inputs, np.minimum(i0 + 1, self.n_inputs - 1) - base, axis=1)
            b *= w
            new += b
        self.made += new.shape[1]
        self._raw(new)
        keep = max(self.n_inputs - 2, 0)  # the inputs the next points may interpolate from
        self.inputs = self.inputs[:, keep - self.inputs_start:]
        self.inputs_start = keep

    def _raw(self, new: Floats) -> None:
        """Library-rate points into `longer`, behind the head the batch makes of the first ones."""
        if self.n_raw == 0:
            first = np.concatenate([self.first_points, new], axis=1)
            # The low-latency mode's first frame reads `ahead` points past it: as many wait here.
            wanted = self.pad + 1 if self.latency_ms is None else 1 if self.ended else self.ahead + 1
            if first.shape[1] < wanted:
                self.first_points = first
                return
            if self.latency_ms is None:
                head = 2 * first[:, :1] - first[:, self.pad:0:-1]
            else:  # the line of the points so far, back: a path moving at once starts moving
                head = first[:, :1] - _mean_step(first) * np.arange(self.pad, 0, -1)[None, :, None]
            self.longer = np.concatenate([head, first], axis=1)
            self.n_raw = first.shape[1]
            self.first_points = first[:, :0]
            return
        self.longer = np.concatenate([self.longer, new], axis=1)
        self.n_raw += new.shape[1]

    def _smooth(self) -> None:
        """Smoothed path for every frame whose Gaussian window has arrived."""
        # Frame t reads `longer` (head first) up to t + pad + ahead.
        ready = self.longer_start + self.longer.shape[1] - self.pad - self.ahead if self.n_raw else 0
        if ready <= self.n_path:
            return
        if self.latency_ms is not None:
            self._fit(ready)
            return
        if self.sigma > 0:
            # Only the frames made (half of what scipy would filter); the same numbers. The root
            # follows the points (their timing smoothed); the body faces the way of them smoothed.
            # `longer` itself, not a slice of it: both read only the Gaussian's radius around the
            # frames made, and `longer` ends where their windows do (exact mode: ahead == radius),
            # so a slice changed nothing but cost a copy of every character's window per tick.
            # The followed path written into its columns at once (no copy of every character's
            # frames a tick).
            first, n = self.n_path + self.pad - self.longer_start, ready - self.n_path
            path, face = self.path.reserve(n)
            gaussian.along_frames(self.longer, self.sigma, first, n, out=path)
            face[...] = gaussian.smooth_frames(self.longer, self.sigma, first, n)
        else:
            path, face = self.path.reserve(ready - self.n_path)
            path[...] = face[...] = self.longer[:, self.n_path - self.longer_start:ready - self.longer_start]
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
            pts = self._facing(a, b)  # the positions smoothed, as the batch's (trajectory, step 2)
            # With a terrain, the speed along the ground, as the batch's (terrain.along_ground).
            on = pts[..., GROUND] if self.ground is None else laid(pts, self.ground)
            step = np.linalg.norm(np.diff(on, axis=1), axis=-1)
            counts = np.full(whole - self.n_seg, m)  # as segment_speeds divides, for the same bits
            speeds = step.reshape(len(step), -1, m).sum(axis=2) / counts * self.bank.fps
            self.seg = np.concatenate([self.seg, speeds / self.pace[:, None]], axis=1)
            self.n_seg = whole

    def _fit(self, ready: int) -> None:
        """The low-latency mode's path and speeds of frames [n_path, ready): causal fits."""
        lo = self.n_path + self.pad - self.behind  # in `longer` coordinates
        part = self.longer[:, lo - self.longer_start:ready + self.pad + self.ahead - self.longer_start]
        n = ready - self.n_path
        value, _ = causal.fit_weights(self.sigma, self.behind, self.ahead)
        _, slope = causal.fit_weights(self.speed_sigma, self.behind, self.ahead)
        path, face = self.path.reserve(n)
        # Contiguous (the velocity columns left out): the fit's dot products sum as they did
        # before there were any, so a session sent no velocity makes the same frames, bit for bit.
        points = np.ascontiguousarray(part[..., :3])
        path[...] = face[...] = causal.apply(points, value, self.behind, self.behind, n)
        velocity = causal.apply(part[..., GROUND], slope, self.behind, self.behind, n)
        speed = np.hypot(velocity[..., 0], velocity[..., 1]) * self.bank.fps / self.pace[:, None]
        # The simulator's velocity where it sent one (smoothed as the path is; NaN where a point
        # read has none): its speed and way, not a fit's reading of held ticks and noise.
        # Not fitted at all until a velocity has been sent: its columns are NaN till then.
        if self.velocity_sent:
            sent = causal.apply(part[..., VELOCITY], value, self.behind, self.behind, n)
            given = ~np.isnan(sent[..., 0])
            if given.any():
                speed = np.where(given, np.hypot(sent[..., 0], sent[..., 1]) / self.pace[:, None], speed)
            # Once a velocity was sent, the faced path is apart from the followed one: stepped on
            # from its own last frame, by the path's steps where no velocity comes (not back to the
            # path: the headings would read the jump).
            self.face_apart = self.face_apart or bool(given.any())
            if self.face_apart:
                self._face_sent(face, path, sent, given)
        self.frame_speed = np.concatenate([self.frame_speed, speed], axis=1)
        self.n_path = ready
        drop = self.n_path + self.pad - self.behind - 1 - self.longer_start
        if drop > 0:
            self.longer = self.longer[:, drop:]
            self.longer_start += drop

    def _face_sent(self, face: Floats, path: Floats, sent: Floats, given: NDArray[np.bool_]) -> None:
        """The path the body faces the way of, over the new frames ``face (C, n, 3)``: stepping
        by the velocity ``sent (C, n, 2)`` where ``given``, by the followed ``path``'s steps
        elsewhere, on from the last frame's (the headings read its steps only)."""
        before = self._facing(self.n_path - 1, self.n_path) if self.n_path else path[:, :1]
        steps = np.diff(np.concatenate([self._path(self.n_path - 1, self.n_path) if self.n_path
                                        else path[:, :1], path], axis=1)[..., GROUND], axis=1)
        steps = np.where(given[..., None], sent / self.bank.fps, steps)
        face[..., GROUND] = before[..., GROUND] + np.cumsum(steps, axis=1)

    def _path(self, a: int, b: int) -> Floats:
        """The followed path's frames [a, b) (a view)."""
        return self.path.columns(a, b)[0]

    def _facing(self, a: int, b: int) -> Floats:
        """The frames [a, b) of the path whose way the body faces (a view)."""
        return self.path.columns(a, b)[1]

    def _speeds(self, t: NDArray[np.int64], who: NDArray[np.int64] | None = None) -> Floats:
        """(C, len(t)) speed at frames t (interpolated between segment centres); of the
        characters ``who`` only, if given."""
        if self.latency_ms is not None:
            fs = self.frame_speed if who is None else self.frame_speed[who]
            return np.asarray(fs[:, t - self.frame_speed_start])
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
        if self.latency_ms is not None:
            return self.n_path
        # Frame t reads segment floor((t - (m-1)/2) / m) + 1 (and at least segment 1).
        m = self.m
        return int(np.ceil((self.n_seg - 1) * m + (m - 1) / 2)) if self.n_seg >= 2 else 0


def _mean_step(points: Floats) -> Floats:
    """``(C, 1, K)``: the mean step a frame of ``points (C, n, K)`` over their positions (the
    velocity columns' step 0: the first one sent goes back with the head)."""
    n = points.shape[1] - 1
    step = np.zeros_like(points[:, :1])
    if n > 0:
        step[..., :3] = (points[:, -1:, :3] - points[:, :1, :3]) / n
    return step
