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
3. Where a target would straighten a leg beyond 98% of its reach, or ``LONGEST_OVER`` past the
   longest reach the library's own poses give it, the root sinks just enough (at most
   ``MAX_SINK`` of the leg length), eased in and out over ``EASE_FRAMES``.
4. Limb IK (:func:`synth_core.build.ik.solve`'s, in SIMD lanes) puts each foot on its target, a
   leg reaching no further than ``LONGEST_OVER`` past its longest (where the sink's bound leaves
   a target beyond it).

Scaled characters are solved in their own unit: a character of scale h is the library skeleton
with every length times h, so dividing its world positions by h gives the library's geometry.
"""

from __future__ import annotations

REACH = 0.98  # of a leg's full reach, at most
# ... and at most this share beyond the leg's longest reach in the library's poses, upper joint
# to ankle (ik.leg_ranges). An animal whose legs never straighten (the real dog's hind legs reach
# 0.92 of their chain) read 4-6 % past its clips' longest with 0.98 of the chain alone. Issue
# 27's limit is 3 % past the clips' longest hip-to-paw reach, after FK: two thirds of it here,
# the rest for the paw, whose angle this rule (on the ankle) does not hold -- the real dog's hind
# paws read up to 1.9 % past their longest with the ankle at this limit. The sink (bounded by
# MAX_SINK) comes first; past it the IK reaches toward the target no further (limb_kernels) and
# the foot falls short of it. The built-in animals' legs straighten: 0.98 of the chain binds them.
LONGEST_OVER = 0.02
# A foot flagged planted on the wire (kernels' contacts, foot_kernels.held) stands on its plant:
# its leg reaches the plant's target within this (metres, whatever the character's size); one
# the sink's bound leaves further short hangs above it, not flagged.
PLANTED_SLACK = 0.003
# ... and its plant stands no higher than this over the ground (metres; a plant's height is its
# clip frames', and a mocap paw's end site stands up to 3 cm up: the real dog's trot).
PLANTED_UP = 0.05
MAX_SINK = 0.05  # of the leg length, the most the root is lowered
# ... on a terrain: a foot planted a stride downhill of its hip is further from it than on the
# flat (at 30%, 7% of the leg for a foot half a leg ahead), and a body lowers rather than a leg
# stretches (issue 33).
TERRAIN_MAX_SINK = 0.2
EASE_FRAMES = 9
# A foot target's step longer than the mean of the steps either side of it by more than this
# (metres in the world; issue 27's one-frame jump target is 6 cm) is eased into a ramp over the
# swing frames around it (jump_kernels.ease_jumps). Half the target: the rest is for what comes
# after the targets -- the sink moving the hips, the IK falling short where a leg cannot reach,
# the hoof or paw below the ankle, which the IK does not hold.
JUMP_EASE = 0.03
# ... but a ramp's vertical part lowers no swing frame still moving over the ground by more than
# SWING_MOVING (metres a frame: the batch strict skate limit, issue 27) to within SWING_CLEAR of
# its plants' height, lower than the frame was un-eased: the strict-plant height (1 cm,
# metrics.STRICT_PLANT_M) and the IK's slack under a target (PLANTED_SLACK). Such a frame reads
# as planted after FK and skates: the low-latency dog's jitter_10hz, its last swing frames before
# a touchdown (12-15 mm up) lowered under 1 cm, strict skate p95 3.0 -> 6.6 mm (with a floor of
# 1 cm alone they landed at 9.3-9.9 mm after FK: still counted).
SWING_MOVING = 0.003
SWING_CLEAR = 0.01 + PLANTED_SLACK
# A body turning on the spot carries a standing foot round with it: held where it stood, the foot
# went out of the leg's reach (issue 27, turn_on_spot: a horse pivoting 180 deg on its hips over
# standing forefeet reared, the hooves hanging 35-50 cm up, then jumped 37 cm in a frame as they
# let go). An animal turning in place steps instead: a plant its leg can no longer reach (the
# sink's rule, reach_sink) ends there and the foot steps to the next, over STEP_S, lifted
# STEP_HEIGHT of the leg (the horse's walk swings its hooves 12 cm up, 0.08 of its leg), rising
# (and setting down) over STEP_LIFT of the step before it moves over the ground (a foot moving
# near the ground glides).
TURN_CARRY = 4.0
STEP_S = 0.2
STEP_HEIGHT = 0.08
STEP_LIFT = 0.15
# A swing foot stands at least this share of a step's height (STEP_HEIGHT) over the line between
# its plants, on a profile rising over the swing's first CLEAR_UP and setting down over its last
# CLEAR_DOWN (smoothstep each), as the real dog's feet lift quickly and slow before touchdown
# (issue 27's glide: a foot moving near the ground slides). Its clip pose alone let it skim the
# ground where a fade blended it with a held frame (dog accel_brake: 3-4 frames on the ground at
# 10 cm a frame before each touchdown after a transition) and through slow lift-offs.
# Never less than CLEAR_LEAST (world metres): a swing must leave the band the near-ground
# glide counts a moving foot in (2.5 cm), which a half-size dog's swings (0.9 cm of clearance)
# never did; at 2.5 cm a swing only touched its edge at mid-swing and spent its rise and fall in
# it (half-size dog: glide 0.18 at 2.5 cm, 0.16 at 3.5; the real dog's paws, skimming between
# clip frames, strict skate p95 in its gallop corners 5.4 -> 2.4 mm).
# It rises over CLEAR_UP of the swing, but over no less than CLEAR_RISE_S: over a quarter of the
# swing, a canter's paw lifted 8 mm in its first swing frame while moving 5-15 mm, skating inside
# the strict plant's 1 cm band (the real dog's corner and U-turn canters: strict skate p95 5 mm);
# over a share alone, a half-size dog's 5-frame swing rose 3.5 cm in one frame and flipped its toe.
CLEARANCE = 0.5
CLEAR_LEAST = 0.035
CLEAR_UP = 0.15
CLEAR_RISE_S = 0.02
CLEAR_DOWN = 0.4
# A plant stands at its frames' average standing height (the heights its clips stand the foot
# at, blended as the pose is: pose_kernels.clip_soles), unless that is more than LIFTED_PLANT (world
# metres) over their lower quartile: then part of it was lifted -- a finished transition's last
# frame fading out under the gait held the horse's trot pair 16-20 mm up for a whole plant
# (corner_gallop), read as not down after FK -- and it stands at the lower quartile. A real dog's
# paw rolling on its pad stands at its clip plant's low tenth (bank.standing_heights). Batch and
# the exact live mode only: the low-latency mode's plants are their first frames' (its horse's
# plants hovered 7 mm, 26 in corner_gallop, with it).
LIFTED_PLANT = 0.01
# An ankle bent less than this has no side; bent this much or more on two frames in a row, it keeps
# its side (limb_kernels.solve_legs): the limb flip's own threshold (metrics.FLIP_MIN_BEND_DEG,
# issue 28), below which a dog's toe swings 10 deg one way to 10 the other at a paw strike.
SIDE_DEG = 15.0
# Frames either side of a frame that its eased sink reads: the running max's half width plus the
# Gaussian's radius (ease_sink: sigma EASE_FRAMES / 6, truncated at 4 sigma), twice: fold_room's
# raise is eased again over the eased sink.
PAD = 2 * (EASE_FRAMES // 2 + int(4.0 * EASE_FRAMES / 6 + 0.5))
