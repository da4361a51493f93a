"""The library artifact: one versioned ``.npz`` holding an animal's skeleton, speed maps, motion
graph, clips with their contacts, and metadata.

Plain arrays only, read with ``allow_pickle=False``: opening an untrusted file cannot run code.
Loading checks the format name and version, every array's presence, dtype and shape against the
skeleton and the metadata, and that values are finite, and names the offending key.

Layout (``J`` joints, ``N`` clips, ``F`` frames)::

    format                  "quadsynth-library"
    version                 1
    meta                    JSON: animal, fps, source, gaits, transitions, generated, ...
    skeleton/names          (J,) str        skeleton/parents   (J,) int32
    skeleton/offsets        (J, 3) float32  skeleton/end_site  (J,) bool
    skeleton/chains         (4, C) int32    each foot's limb chain, toe last, -1 padded
    map/<gait>/speeds       (N,) float64    map/<gait>/root_pos  (N, F, 3) float32
    map/<gait>/rotations    (N, F, J, 4)    map/<gait>/contacts  (F, 4) bool
    map/<gait>/stretch      (N, F, 4)       map/<gait>/source_speed  ()
    clip/<name>/root_pos    (F, 3)          clip/<name>/rotations (F, J, 4)
    clip/<name>/contacts    (F, 4) bool     (idle and every transition)
"""

from __future__ import annotations

import json
import os
import tempfile
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from synth_core import FOOT_NAMES
from synth_core.build.motion_graph import HUBS, MotionGraph, Transition
from synth_core.build.speed_map import SpeedMap
from synth_core.motion.clip import Motion
from synth_core.motion.skeleton import Foot, Skeleton

FORMAT = "quadsynth-library"
VERSION = 1
SUFFIX = ".qslib.npz"


class LibraryFileError(ValueError):
    """A library file that cannot be used: not one, truncated, tampered with, or a newer version."""


@dataclass(frozen=True, eq=False)
class Library:
    animal: str
    skeleton: Skeleton
    fps: float
    maps: dict[str, SpeedMap]  # gait -> speed map, slow to fast
    idle: Motion
    transitions: dict[str, Motion]  # name -> clip
    generated: frozenset[str] = frozenset()  # transitions blended at build time
    source: str = ""  # what it was built from
    extra: dict[str, Any] = field(default_factory=dict)  # more metadata (ranges, build time, ...)

    @property
    def graph(self) -> MotionGraph:
        transitions = {}
        for name in self.transitions:
            source, target = name.split("2")
            transitions[name] = Transition(name, source, target, name in self.generated)
        return MotionGraph(self.maps, transitions)


def save_library(library: Library, path: str | Path) -> Path:
    """Write atomically (a temporary file renamed into place): a failed write loses nothing."""
    path = Path(path)
    sk = library.skeleton
    arrays: dict[str, NDArray[Any]] = {
        "format": np.array(FORMAT), "version": np.array(VERSION),
        "skeleton/names": np.array(sk.names), "skeleton/parents": sk.parents.astype(np.int32),
        "skeleton/offsets": sk.offsets.astype(np.float32), "skeleton/end_site": sk.end_site,
        "skeleton/chains": _chains(sk),
    }
    for gait, m in library.maps.items():
        arrays.update({f"map/{gait}/speeds": m.speeds.astype(np.float64),
                       f"map/{gait}/root_pos": m.root_pos, f"map/{gait}/rotations": m.rotations,
                       f"map/{gait}/contacts": m.contacts, f"map/{gait}/stretch": m.stretch,
                       f"map/{gait}/source_speed": np.array(m.source_speed)})
    for name, clip in {"idle": library.idle, **library.transitions}.items():
        arrays.update({f"clip/{name}/root_pos": clip.root_pos, f"clip/{name}/rotations": clip.rotations,
                       f"clip/{name}/contacts": clip.contacts})
    meta = {"animal": library.animal, "fps": library.fps, "source": library.source,
            "skeleton": sk.name, "gaits": list(library.maps), "transitions": list(library.transitions),
            "generated": sorted(library.generated), **library.extra}
    arrays["meta"] = np.array(json.dumps(meta))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        # mkstemp makes the file 0600: a library built by root (an image's build) must stay
        # readable by the service's own user, as any file open() makes would be.
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, **arrays)  # type: ignore[arg-type]
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    """The process's umask, read without changing it where Linux tells it (``os.umask`` can only
    be read by setting it, which another thread could observe)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _chains(skeleton: Skeleton) -> NDArray[np.int32]:
    width = max(len(f.chain) for f in skeleton.feet)
    chains = np.full((len(skeleton.feet), width), -1, np.int32)
    for k, foot in enumerate(skeleton.feet):
        chains[k, :len(foot.chain)] = foot.chain
    return chains


class _Reader:
    """Typed, checked access to the arrays of an open npz."""

    def __init__(self, path: Path, data: Mapping[str, NDArray[Any]]) -> None:
        self.path, self.data = path, data

    def fail(self, key: str, message: str) -> LibraryFileError:
        return LibraryFileError(f"{self.path}: {key}: {message}")

    def get(self, key: str, kind: str, shape: tuple[int | None, ...]) -> NDArray[Any]:
        if key not in self.data:
            raise self.fail(key, "missing")
        try:
            a = self.data[key]
        except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
            raise self.fail(key, f"unreadable ({exc}); the file is truncated or corrupt") from None
        if a.dtype.kind != kind:
            raise self.fail(key, f"expected dtype kind {kind!r}, got {a.dtype}")
        if a.ndim != len(shape) or any(w is not None and w != s for w, s in zip(shape, a.shape, strict=True)):
            want = "(" + ", ".join("*" if w is None else str(w) for w in shape) + ")"
            raise self.fail(key, f"expected shape {want}, got {a.shape}")
        if kind == "f" and not np.all(np.isfinite(a)):
            raise self.fail(key, "holds NaN or infinite values")
        return a


def load_library(path: str | Path) -> Library:
    """Read and validate a library file; any problem raises :class:`LibraryFileError`."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            return _read(_Reader(path, npz))
    except LibraryFileError:
        raise
    except FileNotFoundError:
        raise LibraryFileError(f"{path}: no such file") from None
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError) as exc:
        raise LibraryFileError(f"{path}: not a readable QuadSynth library file "
                               f"(truncated or corrupt?): {exc}") from None


def _read(r: _Reader) -> Library:
    fmt = r.get("format", "U", ())
    if str(fmt) != FORMAT:
        raise r.fail("format", f"expected {FORMAT!r}, got {str(fmt)!r}")
    version = int(r.get("version", "i", ()))
    if version != VERSION:
        raise r.fail("version", f"this QuadSynth reads version {VERSION}, the file is version {version}; "
                                "rebuild it with `quadsynth build`")
    try:
        meta = json.loads(str(r.get("meta", "U", ())))
        animal, fps = str(meta["animal"]), float(meta["fps"])
        gaits, transitions = list(meta["gaits"]), list(meta["transitions"])
        generated = frozenset(meta.get("generated", []))
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise r.fail("meta", f"not the expected JSON metadata ({exc})") from None
    if not (np.isfinite(fps) and fps > 0):
        raise r.fail("meta", f"fps must be positive, got {fps}")
    names = r.get("skeleton/names", "U", (None,))
    J = len(names)
    chains = r.get("skeleton/chains", "i", (len(FOOT_NAMES), None))
    try:
        feet = tuple(Foot(f, int(c[c >= 0][-1]), tuple(int(j) for j in c[c >= 0]))
                     for f, c in zip(FOOT_NAMES, chains, strict=True))
        skeleton = Skeleton(tuple(str(n) for n in names), r.get("skeleton/parents", "i", (J,)),
                            r.get("skeleton/offsets", "f", (J, 3)), r.get("skeleton/end_site", "b", (J,)),
                            feet, str(meta.get("skeleton", animal)))
    except (ValueError, IndexError) as exc:
        raise r.fail("skeleton", str(exc)) from None
    maps = {}
    for gait in gaits:
        if gait not in HUBS[1:]:
            raise r.fail("meta", f"unknown gait {gait!r}")
        k = f"map/{gait}"
        speeds = r.get(f"{k}/speeds", "f", (None,))
        if len(speeds) == 0 or np.any(np.diff(speeds) < 0):
            raise r.fail(f"{k}/speeds", "must be ascending and not empty")
        N = len(speeds)
        rotations = r.get(f"{k}/rotations", "f", (N, None, J, 4))
        F = rotations.shape[1]
        maps[gait] = SpeedMap(gait, skeleton, fps, speeds, r.get(f"{k}/root_pos", "f", (N, F, 3)),
                              rotations, r.get(f"{k}/contacts", "b", (F, 4)),
                              r.get(f"{k}/stretch", "f", (N, F, 4)),
                              float(r.get(f"{k}/source_speed", "f", ())))
    clips = {}
    for name in ["idle", *transitions]:
        k = f"clip/{name}"
        rotations = r.get(f"{k}/rotations", "f", (None, J, 4))
        F = rotations.shape[0]
        clips[name] = Motion(skeleton, r.get(f"{k}/root_pos", "f", (F, 3)), rotations, fps,
                             r.get(f"{k}/contacts", "b", (F, 4)), name, "static" if name == "idle" else None)
    extra = {k: v for k, v in meta.items()
             if k not in ("animal", "fps", "source", "skeleton", "gaits", "transitions", "generated")}
    library = Library(animal, skeleton, fps, maps, clips.pop("idle"), clips, generated,
                      str(meta.get("source", "")), extra)
    try:
        library.graph  # noqa: B018 - validates the transitions against the hubs
    except ValueError as exc:
        raise r.fail("meta", str(exc)) from None
    return library
