"""Foot lock (beyond the paper; after Kovar et al. 2002): planted feet stay where they land.

Blending clips, bending them along curved paths and scaling them all make a planted foot drift.
A last pass over the synthesized motion, per character over its frames -- written once, in the
render's kernels (:mod:`synth_core.compiled.kernels`, passes 2-4, with
:mod:`~synth_core.compiled.foot_kernels` and :mod:`~synth_core.compiled.limb_kernels`); this
module holds its constants:

1. Each plant (a run of planted frames of one foot) gets one world position: the foot's average
   over the plant.
2. A swinging foot follows its own path plus a correction eased (smoothstep) from the one its
   last plant needed at lift-off to the one its next plant needs at touchdown -- over the
   ground only, so swing heights are the clip's.
3. Where a target would straighten a leg beyond 98% of its reach, the root sinks just enough
   (at most ``MAX_SINK`` of the leg length), eased in and out over ``EASE_FRAMES``.
4. Limb IK (:func:`synth_core.build.ik.solve`'s, in SIMD lanes) puts each foot on its target.

Scaled characters are solved in their own unit: a character of scale h is the library skeleton
with every length times h, so dividing its world positions by h gives the library's geometry.
"""

from __future__ import annotations

REACH = 0.98  # of a leg's full reach, at most
MAX_SINK = 0.05  # of the leg length, the most the root is lowered
# ... on a terrain: a foot planted a stride downhill of its hip is further from it than on the
# flat (at 30%, 7% of the leg for a foot half a leg ahead), and a body lowers rather than a leg
# stretches (issue 33).
TERRAIN_MAX_SINK = 0.2
EASE_FRAMES = 9
# Frames either side of a frame that its eased sink reads: the running max's half width plus the
# Gaussian's radius (ease_sink: sigma EASE_FRAMES / 6, truncated at 4 sigma), twice: fold_room's
# raise is eased again over the eased sink.
PAD = 2 * (EASE_FRAMES // 2 + int(4.0 * EASE_FRAMES / 6 + 0.5))
