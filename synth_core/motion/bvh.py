"""BVH import and export.

Reading accepts any rotation channel order per joint, a root with any mix of position and
rotation channels, End Sites (kept as joints named ``<parent>_end`` and flagged as end sites),
CRLF or LF line endings, and a unit (BVH has none of its own; most files are centimetres).
The root OFFSET is ignored by default: root position channels are taken as absolute world
coordinates, which is what the MANN dog files need (see ``../shared/mocap/mann_dog/SOURCE.md``)
and what most exporters mean. Position channels on other joints are accepted only when they do
not change over the clip (they then replace the joint's offset); QuadSynth skeletons have fixed
bone lengths.

A malformed file raises :class:`BVHError` naming the file and line.

Writing emits centimetres by default, the root as ``Xposition Yposition Zposition`` plus the
rotation order (default ``Zrotation Xrotation Yrotation``), Euler angles unwrapped over time so
curves in animation tools stay continuous.
"""

from __future__ import annotations

import io
import math
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from synth_core.motion.clip import Motion
from synth_core.motion.skeleton import Skeleton, guess_feet

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
_ROT = {"Xrotation": "X", "Yrotation": "Y", "Zrotation": "Z"}
_POS = {"Xposition": 0, "Yposition": 1, "Zposition": 2}


class BVHError(ValueError):
    """A malformed BVH file; the message names the file and line."""

    def __init__(self, source: str, line: int | None, message: str) -> None:
        where = f"{source}:{line}" if line is not None else source
        super().__init__(f"{where}: {message}")
        self.source, self.line = source, line


def unit_scale(unit: str | float) -> float:
    """Metres per file unit: a name from UNITS or a positive number."""
    if isinstance(unit, str):
        if unit not in UNITS:
            raise ValueError(f"unit: expected one of {sorted(UNITS)} or a number, got {unit!r}")
        return UNITS[unit]
    if not (math.isfinite(unit) and unit > 0):
        raise ValueError(f"unit: a numeric scale must be positive and finite, got {unit}")
    return float(unit)


@dataclass
class _Joint:
    name: str
    parent: int
    offset: tuple[float, float, float]
    channels: list[str] = field(default_factory=list)
    end_site: bool = False


class _Tokens:
    """Whitespace tokens of the hierarchy with their 1-based line numbers."""

    def __init__(self, lines: list[str], source: str) -> None:
        self.source = source
        self._items = [(tok, i + 1) for i, line in enumerate(lines) for tok in line.split()]
        self._pos = 0

    @property
    def line(self) -> int | None:
        if self._pos < len(self._items):
            return self._items[self._pos][1]
        return self._items[-1][1] if self._items else None

    def error(self, message: str) -> BVHError:
        return BVHError(self.source, self.line, message)

    def peek(self) -> str | None:
        return self._items[self._pos][0] if self._pos < len(self._items) else None

    def next(self, what: str) -> str:
        if self._pos >= len(self._items):
            raise self.error(f"unexpected end of file, expected {what}")
        tok = self._items[self._pos][0]
        self._pos += 1
        return tok

    def expect(self, literal: str) -> None:
        line = self.line
        tok = self.next(repr(literal))
        if tok != literal:
            raise BVHError(self.source, line, f"expected {literal!r}, got {tok!r}")

    def number(self, what: str) -> float:
        line = self.line
        tok = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            raise BVHError(self.source, line, f"expected a number for {what}, got {tok!r}") from None
        if not math.isfinite(value):
            raise BVHError(self.source, line, f"{what} must be finite, got {tok!r}")
        return value

    def integer(self, what: str) -> int:
        line = self.line
        tok = self.next(what)
        if not tok.isdigit():
            raise BVHError(self.source, line, f"expected a non-negative integer for {what}, got {tok!r}")
        return int(tok)


def _parse_joint(tokens: _Tokens, name: str, parent: int, end_site: bool) -> _Joint:
    """A joint's (or End Site's) opening brace, offset and channels."""
    tokens.expect("{")
    tokens.expect("OFFSET")
    offset = tuple(tokens.number(f"{name} OFFSET") for _ in range(3))
    joint = _Joint(name, parent, offset, end_site=end_site)  # type: ignore[arg-type]
    if not end_site:
        _parse_channels(tokens, joint)
    return joint


def _parse_channels(tokens: _Tokens, joint: _Joint) -> None:
    name = joint.name
    tokens.expect("CHANNELS")
    line = tokens.line
    count = tokens.integer(f"{name} CHANNELS count")
    if count > 6:
        raise BVHError(tokens.source, line, f"{name}: at most 6 channels, got {count}")
    for _ in range(count):
        line = tokens.line
        channel = tokens.next(f"{name} channel name")
        if channel not in _ROT and channel not in _POS:
            raise BVHError(tokens.source, line, f"{name}: unknown channel {channel!r}")
        if channel in joint.channels:
            raise BVHError(tokens.source, line, f"{name}: channel {channel} repeated")
        joint.channels.append(channel)


def _parse_hierarchy(tokens: _Tokens) -> list[_Joint]:
    tokens.expect("HIERARCHY")
    tokens.expect("ROOT")
    joints: list[_Joint] = []
    # Iterative descent (no recursion limit on deep files): a stack of open joints.
    stack: list[int] = []
    name = tokens.next("the root joint's name")
    pending: tuple[str, int, bool] | None = (name, -1, False)
    while True:
        if pending is not None:
            joints.append(_parse_joint(tokens, *pending))
            pending = None
            stack.append(len(joints) - 1)
            continue
        tok = tokens.peek()
        if tok == "}":
            tokens.next("}")
            stack.pop()
            if not stack:
                return joints
        elif tok == "JOINT":
            if joints[stack[-1]].end_site:
                raise tokens.error("an End Site cannot have children")
            tokens.next("JOINT")
            pending = (tokens.next("a joint name"), stack[-1], False)
        elif tok == "End":
            if joints[stack[-1]].end_site:
                raise tokens.error("an End Site cannot have children")
            tokens.next("End")
            tokens.expect("Site")
            pending = (f"{joints[stack[-1]].name}_end", stack[-1], True)
        else:
            raise tokens.error(f"expected JOINT, End Site or '}}', got {tok!r}" if tok
                               else "unexpected end of file inside the hierarchy")


def _unique_names(joints: list[_Joint]) -> None:
    seen: set[str] = set()
    for joint in joints:
        base, k = joint.name, 1
        while joint.name in seen:
            k += 1
            joint.name = f"{base}_{k}"
        seen.add(joint.name)


def _parse_header(lines: list[str], start: int, source: str) -> tuple[int, float, int]:
    """Frames and frame time after MOTION; returns (frames, frame_time, first data line index)."""
    def field_value(index: int, label: str) -> str:
        if index >= len(lines):
            raise BVHError(source, index, f"unexpected end of file, expected '{label}'")
        text = lines[index].strip()
        if not text.startswith(label):
            raise BVHError(source, index + 1, f"expected '{label}', got {text[:40]!r}")
        return text[len(label):].strip()

    i = start
    while i < len(lines) and not lines[i].strip():
        i += 1
    frames_text = field_value(i, "Frames:")
    if not frames_text.isdigit():
        raise BVHError(source, i + 1, f"Frames: expected a non-negative integer, got {frames_text!r}")
    i += 1
    frame_time_text = field_value(i, "Frame Time:")
    try:
        frame_time = float(frame_time_text)
    except ValueError:
        frame_time = float("nan")
    if not (math.isfinite(frame_time) and frame_time > 0):
        raise BVHError(source, i + 1, f"Frame Time: expected a positive number, got {frame_time_text!r}")
    return int(frames_text), frame_time, i + 1


def _parse_frames(lines: list[str], first: int, frames: int, n_channels: int,
                  source: str) -> NDArray[np.float64]:
    body = [(i, line) for i, line in enumerate(lines[first:], start=first + 1) if line.strip()]
    if frames == 0:
        raise BVHError(source, first, "the file has no frames (Frames: 0)")
    try:
        values = np.array(" ".join(line for _, line in body).split(), dtype=np.float64)
    except ValueError:
        values = None
    if values is None or values.size != frames * n_channels or not np.all(np.isfinite(values)):
        # Slow path, only to name the first bad line.
        for lineno, line in body:
            parts = line.split()
            for tok in parts:
                try:
                    if not math.isfinite(float(tok)):
                        raise ValueError
                except ValueError:
                    raise BVHError(source, lineno, f"frame data: {tok!r} is not a finite number") from None
            if len(parts) != n_channels:
                raise BVHError(source, lineno, f"frame data: expected {n_channels} values "
                               f"(one per channel), got {len(parts)}")
        raise BVHError(source, first, f"Frames: says {frames} but the file has {len(body)} frame lines")
    return values.reshape(frames, n_channels)


def parse(text: str, *, source: str = "<bvh>", unit: str | float = "cm",
          feet: Mapping[str, str] | str | None = "auto", root_offset: str = "ignore",
          name: str = "") -> Motion:
    """Parse BVH text into a :class:`Motion` (metres, xyzw quaternions).

    ``feet``: a mapping foot -> end-effector joint name, ``"auto"`` to guess from joint names
    (left without feet when the names do not tell), or None. ``root_offset``: ``"ignore"``
    (root channels are absolute) or ``"add"`` (root OFFSET plus channels).
    """
    scale = unit_scale(unit)
    if root_offset not in ("ignore", "add"):
        raise ValueError(f"root_offset: expected 'ignore' or 'add', got {root_offset!r}")
    lines = text.splitlines()
    motion_at = next((i for i, line in enumerate(lines) if line.strip() == "MOTION"), None)
    if motion_at is None:
        raise BVHError(source, None, "no MOTION section")
    tokens = _Tokens(lines[:motion_at], source)
    joints = _parse_hierarchy(tokens)
    if tokens.peek() is not None:
        raise tokens.error(f"unexpected {tokens.peek()!r} after the hierarchy (one ROOT only)")
    _unique_names(joints)
    frames, frame_time, first = _parse_header(lines, motion_at + 1, source)
    n_channels = sum(len(j.channels) for j in joints)
    data = _parse_frames(lines, first, frames, n_channels, source)
    return _to_motion(joints, data, frame_time, scale, root_offset, feet, name, source)


def _to_motion(joints: list[_Joint], data: NDArray[np.float64], frame_time: float, scale: float,
               root_offset: str, feet: Mapping[str, str] | str | None, name: str,
               source: str) -> Motion:
    F, J = data.shape[0], len(joints)
    offsets = np.array([j.offset for j in joints], dtype=np.float64) * scale
    rotations = np.zeros((F, J, 4))
    rotations[..., 3] = 1.0
    root_pos = np.broadcast_to(offsets[0], (F, 3)).copy()
    if root_offset == "ignore":
        has_pos = [c in joints[0].channels for c in _POS]
        root_pos[:, has_pos] = 0.0
    col = 0
    for index, joint in enumerate(joints):
        cols = {c: col + k for k, c in enumerate(joint.channels)}
        col += len(joint.channels)
        rot_channels = [c for c in joint.channels if c in _ROT]
        if rot_channels:
            order = "".join(_ROT[c] for c in rot_channels)  # uppercase: intrinsic, as BVH means
            angles = data[:, [cols[c] for c in rot_channels]]
            rotations[:, index] = Rotation.from_euler(order, angles, degrees=True).as_quat()
        pos_channels = [c for c in joint.channels if c in _POS]
        if not pos_channels:
            continue
        axes = [_POS[c] for c in pos_channels]
        values = data[:, [cols[c] for c in pos_channels]] * scale
        if index == 0:
            root_pos[:, axes] += values
        elif np.ptp(values, axis=0).max() > 1e-6:
            raise BVHError(source, None, f"joint {joint.name} has animated position channels; "
                           "only the root may translate")
        else:
            offsets[index, axes] = values[0]
    fps = 1.0 / frame_time
    if abs(fps - round(fps)) < 0.01:  # "0.0166667" means 60 fps
        fps = float(round(fps))
    skeleton = Skeleton(
        names=tuple(j.name for j in joints),
        parents=np.array([j.parent for j in joints]),
        offsets=offsets.astype(np.float32),
        end_site=np.array([j.end_site for j in joints]),
        name=name,
    )
    if feet == "auto":
        try:
            skeleton = skeleton.with_feet(guess_feet(skeleton))
        except ValueError:
            pass
    elif feet is not None:
        if isinstance(feet, str):
            raise ValueError(f"feet: expected a mapping, 'auto' or None, got {feet!r}")
        skeleton = skeleton.with_feet(feet)
    return Motion(skeleton, root_pos.astype(np.float32), rotations.astype(np.float32), fps, name=name)


def read(path: str | Path, *, unit: str | float = "cm", feet: Mapping[str, str] | str | None = "auto",
         root_offset: str = "ignore") -> Motion:
    """Read a BVH file (see :func:`parse`); the motion is named after the file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except UnicodeDecodeError as exc:
        raise BVHError(str(path), None, f"not a text file ({exc.reason} at byte {exc.start})") from None
    return parse(text, source=str(path), unit=unit, feet=feet, root_offset=root_offset,
                 name=path.stem)


def _preorder(skeleton: Skeleton) -> Iterator[tuple[int, int]]:
    """(joint, depth) in depth-first preorder, the order BVH lists joints and channels."""
    stack = [(0, 0)]
    while stack:
        joint, depth = stack.pop()
        yield joint, depth
        stack.extend((c, depth + 1) for c in reversed(skeleton.children(joint)))


def dumps(motion: Motion, *, unit: str | float = "cm", order: str = "ZXY") -> str:
    """BVH text of a motion; see :func:`write`."""
    if sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"order: expected a permutation of 'XYZ', got {order!r}")
    scale = unit_scale(unit)
    skel = motion.skeleton
    rot_names = " ".join(f"{axis}rotation" for axis in order)
    out = io.StringIO()
    out.write("HIERARCHY\n")
    animated: list[int] = []
    depth_prev = -1
    for joint, depth in _preorder(skel):
        for d in range(depth_prev, depth - 1, -1):
            out.write("  " * d + "}\n")
        depth_prev = depth
        pad = "  " * depth
        off = skel.offsets[joint].astype(np.float64) / scale if joint else np.zeros(3)
        leaf_site = bool(skel.end_site[joint]) and not skel.children(joint)
        head = "ROOT" if joint == 0 else ("End Site" if leaf_site else "JOINT")
        out.write(f"{pad}{head}{'' if leaf_site else ' ' + skel.names[joint]}\n{pad}{{\n")
        out.write(f"{pad}  OFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}\n")
        if joint == 0:
            out.write(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rot_names}\n")
        elif not leaf_site:
            out.write(f"{pad}  CHANNELS 3 {rot_names}\n")
        if not leaf_site:
            animated.append(joint)
    for d in range(depth_prev, -1, -1):
        out.write("  " * d + "}\n")
    F = motion.n_frames
    quats = motion.rotations[:, animated].astype(np.float64).reshape(-1, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # gimbal lock: scipy still returns a valid triple
        euler = Rotation.from_quat(quats).as_euler(order, degrees=True).reshape(F, -1, 3)
    euler = np.unwrap(euler, period=360.0, axis=0)
    data = np.concatenate([motion.root_pos.astype(np.float64) / scale, euler.reshape(F, -1)], axis=1)
    out.write(f"MOTION\nFrames: {F}\nFrame Time: {1.0 / motion.fps:.8g}\n")
    np.savetxt(out, data, fmt="%.6f")
    return out.getvalue()


def write(motion: Motion, path: str | Path, *, unit: str | float = "cm", order: str = "ZXY") -> None:
    """Write a motion as BVH (centimetres by default). End-site joints become End Sites."""
    Path(path).write_text(dumps(motion, unit=unit, order=order), encoding="utf-8")
