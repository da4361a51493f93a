"""QuadSynth synthesis core: Sung 2011, "Fast Motion Synthesis of Massive Number of Quadruped Animals".

numpy and scipy; numba for the compiled kernels (without it the same source runs interpreted, the
same motion); pygltflib for glTF. Never imports web code (fastapi, pydantic, service).

Glossary of array shapes, stated once (every module refers here):

=====================  ==============  ===================================================
name                   shape           meaning
=====================  ==============  ===================================================
quaternion             (..., 4)        float32, **xyzw** (scalar last, as scipy and glTF),
                                       unit norm
offsets                (J, 3)          rest offset of each joint from its parent, metres
parents                (J,)            parent index, -1 for the root; parent < child
root_pos               (F, 3)          world position of joint 0 per frame, metres
rotations              (F, J, 4)       local rotation of each joint relative to its parent
                                       (joint 0: world rotation of the root)
contacts               (F, 4)          bool, a foot is planted; feet ordered LF, RF, LH, RH
positions              (F, J, 3)       world joint positions from forward kinematics
crowd arrays           (C, F, ...)     a leading character axis C on any of the above
=====================  ==============  ===================================================

Axes: Y up, right-handed, metres. Frames are counted from 0; frame ranges are half-open
``[start, stop)`` like Python slices.
"""

FOOT_NAMES: tuple[str, str, str, str] = ("LF", "RF", "LH", "RH")
"""Foot order used by every `(..., 4)` foot axis: left fore, right fore, left hind, right hind."""

UP_AXIS = 1
"""Index of the vertical axis (Y up)."""

SIZE_MATCHING: tuple[str, str] = ("froude", "geometric")
"""How a character of scale h uses the library (synth_core.runtime.synthesis.character_tempo)."""

TEMPO_SPREAD = 0.06
"""Each character's own stride frequency, uniform within +- this share of its size's (seeded).
Individuals of one size at one speed differ by a few per cent; without it a herd of equal sizes
started together stepped as one (issue 28: 58% of frames with the same 4-foot pattern)."""
