"""Gait parameters of the built-in horse and dog, from published gait biomechanics.

Each number says where it comes from; where we had to choose, it says so.

Footfall phases are touchdown times relative to the left hind (LH) as a fraction of the stride;
duty factor is the share of the stride a foot is planted.

Horse (1.6 m warmblood). Tempo (stride frequency, stride length, duty factor) at each gait's
typical speed follows the literature compiled in ``docs/gait-reference.md`` (of the shared docs;
tables 1a, 2a, 3a); speed maps then keep a gait's stride frequency and duty factor over its speed
range (synthesis plays one clip frame per output frame), so each gait sits where the literature's
frequency is mid-range for it:
- Walk: four-beat lateral sequence LH, LF, RH, RF at even quarter-stride spacing (Robilliard, Pfau
  & Wilson 2007, J. Exp. Biol. 210:187-197; Hildebrand 1965, Science 150:701-708), duty factor
  0.60-0.70. 1.6 m/s, the standard test speed (Buchner et al. 1996, Equine Vet. J. 28:71; Barrey
  et al. 1993), stride 1.6-1.9 m at 0.85-1.0 Hz: 64 frames (0.94 Hz, 1.71 m), duty 0.64.
- Trot: diagonal pairs, the hind landing a little before its fore (advanced placement +30 ms of a
  794 ms stride, Holmstrom et al. 1994): RF 0.03 after LH. Stride frequency 1.26 Hz (Holmstrom
  1994) rising to 1.64 Hz at 5 m/s (Wickler et al. 2002, Equine Vet. J. Suppl. 34:126); duty 0.47
  at Froude 0.5, 0.41 at 0.75, 0.39 at 1.0 (Bullimore & Burn 2006, J. Exp. Biol. 209:455, at 500
  kg). We use 3.3 m/s (the preferred trot, Wickler et al. 2000, J. Exp. Biol. 203:2195), 42 frames
  (1.43 Hz, 2.31 m) and duty 0.43: within 0.08 of the 0.40 at this speed, and the speed map's
  slowest trots (where the literature's duty nears 0.5) keep only a short suspension.
- Canter (left lead): trailing hind (RH), then the diagonal pair (LH+RF), then the leading fore
  (LF), then one suspension (Muybridge 1887; Back & Clayton, *Equine Locomotion*, 2013, ch. 7);
  duty 0.40-0.50. At 5.0 m/s 111 strides/min (1.85 Hz), stride 2.68 m, barely rising with speed
  (Wickler et al. 2002): 5.0 m/s, 32 frames (1.88 Hz, 2.67 m), duty 0.42.
- Gallop (left lead, transverse): RH, LH, RF, LF, one gathered suspension (Bertram & Gutmann 2009,
  J. R. Soc. Interface 6:549). At 9 m/s stance 131-143 ms and protraction 355-364 ms: a 0.495 s
  stride (2.0 Hz), duty 0.27 fore, 0.29 hind (Witte, Hirst & Wilson 2006, J. Exp. Biol.
  209:4389-4397; 2.4 Hz at 17 m/s, so about 2.04 Hz at 9.8): 9.8 m/s, 29 frames (2.07 Hz,
  4.74 m), duty 0.26 (0.28 on whole frames); the speed map's fastest clips (10.6 m/s) keep up
  with the standard herd's fastest members for their size. Phases RH 0.86, RF 0.24,
  LF 0.40 (within table 1a's ranges), far enough apart that blends into and out of the canter
  keep four separate footfalls.
- The paper's Table 1 cycles (walk 82, trot 56, canter 51, gallop 51 frames at 60 fps) are its
  horse mocap's; they stride 20-40% slower than these sources at our speeds, so we follow the
  sources.
- Trunk: vertical excursion at the trot ~70 mm peak to peak (Buchner, Obermuller & Scheidl 2000,
  Vet. J. 160:225-234: centre of mass 53 mm, the trunk 27% more); twice per stride in walk and
  trot, once per stride in canter and gallop. Head and neck nod twice per stride at the walk and
  once per stride at the canter and gallop; at the trot they move twice per stride, in phase with
  the diagonal stance, the head kept fairly level (Buchner et al. 1996; Dunbar et al. 2008, J.
  Exp. Biol. 211:3889: head, neck and trunk pitch within 20 deg). The trunk pitches once per
  stride in canter and gallop (gait-reference table 4). Amplitudes are our estimates, kept so
  the head's pitch in the world swings within Dunbar et al.'s 20 deg at the walk, trot and canter
  (measured: 9.6, 3.5 and 17 deg peak to peak).
- Swing: each foot lifts a little differently (fore higher than hind, the two sides a few per
  cent apart; ``FOOT_LIFT``), as no two legs of an animal move alike.

Dog (the MANN dog, ``../shared/mocap/mann_dog/SOURCE.md``, measured there and in issue 2):
- Walk: four-beat lateral, LF 0.12-0.39 after LH, duty ~0.62 at 0.4-0.9 m/s. We use LF 0.25,
  duty 0.62, 0.85 m/s, 46 frames (the measured walk cycle is 48 frames at 0.81 m/s; a longer
  stride is beyond the reach of the dog's short scapula at this duty factor).
- Trot: duty ~0.42 at 1.5-2.3 m/s, cycles of 28-30 frames. We use 1.9 m/s, 30 frames.
- Canter: the real dog's asymmetric gait is a rotary gallop at every speed (issue 2 measured
  phases LF 0.12-0.21, RF 0.31-0.39, RH 0.81-0.88). For the dog's canter we use the classic
  three-beat canter of dogs (Hildebrand 1977, Am. Zool. 17:143-157): RH 0.75, RF 0.0, LF 0.2,
  duty 0.30, 3.2 m/s, 28 frames.
- Gallop: **rotary**, as the real dog: RH 0.86, LF 0.16, RF 0.35, duty 0.24 (measured 0.24 at
  4.4-5.2 m/s), 4.6 m/s, 25 frames. Spine flexion is large in the dog's gallop (Hildebrand 1959,
  J. Mammal. 40:481-495); amplitudes are our estimates.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from synth_core import FOOT_NAMES


@dataclass(frozen=True)
class GaitSpec:
    """One gait of one animal. Angles in degrees, lengths in metres, phases in strides."""

    name: str
    speed: float  # m/s
    frames: int  # one stride at 60 fps
    phases: dict[str, float]  # touchdown phase per foot, LH = 0
    duty: float
    step_height: float  # peak lift of the toe in swing, in leg lengths
    crouch: float  # trunk lowered by this (m) so legs reach the stance extremes
    bob: float  # trunk vertical amplitude (m, half peak-to-peak)
    bob_per_stride: int  # 2: walk, trot; 1: canter, gallop
    bob_low: float  # phase of the lowest trunk point (first one)
    pitch: float  # trunk pitch amplitude (deg, + nose down)
    pitch_down: float  # phase of the most nose-down pitch
    nod: float  # head-and-neck nod amplitude (deg)
    nod_per_stride: int
    nod_down: float  # phase of the lowest head
    steady_head: float  # share of the trunk's and neck's pitch the head cancels (1: level in the world)
    spine_flex: float  # dorsoventral spine flexion amplitude (deg, + = arched)
    spine_arched: float  # phase of the most arched spine
    carpus_flex: float  # peak carpus flexion in swing (deg)
    hock_flex: float  # peak hock flexion in swing (deg)
    hock_load: float  # hock flexion at mid-stance (deg)
    fetlock_sink: float  # extra pastern slope at mid-stance (deg): the fetlock sinks under load
    digit_flex: float  # peak digit (fetlock, toe) flexion in swing (deg)
    breakover: float  # digit rotation over the toe at lift-off (deg)
    tail_lift: float  # tail raised (deg)
    tail_swing: float  # tail follow-through amplitude (deg)
    sway: float = 0.0  # neck and tail side to side, once per stride (deg)
    # Share of the swing over which the foot slows to rest before touchdown; it reaches past its
    # landing place relative to the body meanwhile (swing-leg retraction), so a gait whose legs are
    # at full stretch at touchdown (the horse's long gallop stance) takes less.
    touchdown_ease: float = 0.25
    # Swing height profile s (1 - s)^lift_fall (s: progress through the swing): above 1 the foot
    # lifts steeply and comes down less steeply, peaking just before mid-swing. A small animal
    # sets its foot down steeper: with the horse's 1.2 the dog's paws were under 1 cm up in their
    # last swing frame while still moving forward 4-9 mm, a strict-plant skate (issue 27: gallop
    # 9 mm p95); at 1.0 they are over 1 cm there, as the horse's hooves (2-3 cm) are at 1.2.
    lift_fall: float = 1.2
    # Share of the body-relative plan's speed a foot leaves the ground with (``foot_paths``:
    # the swing's advance ramps up from it). The real MANN dog's paw moves 0.10 of the body's
    # speed in its first swing frame, 0.18-0.22 in its second, at the trot, canter and gallop
    # (../shared/mocap/mann_dog, clean ranges); at 0.5 the built-in dog's canter and gallop paws
    # read 0.63 and 0.8, skimming forward through the 2.5 cm of the glide measure as they rose
    # (the steady canter's glide 0.091, gallop 0.082; now 0.33 and 0.59 of the body's speed,
    # glide 0.062, 0.052). The trot keeps 0.5: at 0.2 its clips glide less (0.071 -> 0.053) but
    # the edge suite's turns and brakes, whose glide is mostly the held end of walk2trot fading
    # out (docs/edge_dogs.md), read worse.
    lift_off_speed: float = 0.5
    notes: str = field(default="", compare=False)

    @property
    def stride_length(self) -> float:
        return self.speed * self.frames / 60.0


def _spec(**kw: object) -> GaitSpec:
    spec = GaitSpec(**kw)  # type: ignore[arg-type]
    if set(spec.phases) != set(FOOT_NAMES) or spec.phases["LH"] != 0.0:
        raise ValueError(f"{spec.name}: phases must name all four feet with LH = 0")
    return spec


HORSE_GAITS: dict[str, GaitSpec] = {g.name: g for g in (
    _spec(name="walk", speed=1.6, frames=64, phases={"LH": 0.0, "LF": 0.25, "RH": 0.5, "RF": 0.75},
          duty=0.64, step_height=0.09, crouch=0.0, bob=0.012, bob_per_stride=2, bob_low=0.1,
          pitch=1.0, pitch_down=0.25, nod=4.0, nod_per_stride=2, nod_down=0.3, steady_head=0.0,
          spine_flex=0.5, spine_arched=0.0, carpus_flex=55.0, hock_flex=35.0, hock_load=4.0,
          fetlock_sink=8.0, digit_flex=40.0, breakover=25.0, tail_lift=0.0, tail_swing=4.0, sway=3.0),
    _spec(name="trot", speed=3.3, frames=42, phases={"LH": 0.0, "RF": 0.03, "RH": 0.5, "LF": 0.53},
          duty=0.43, step_height=0.14, crouch=0.03, bob=0.035, bob_per_stride=2, bob_low=0.2,
          pitch=1.0, pitch_down=0.2, nod=3.0, nod_per_stride=2, nod_down=0.25, steady_head=0.6,
          spine_flex=1.0, spine_arched=0.2, carpus_flex=85.0, hock_flex=50.0, hock_load=8.0,
          fetlock_sink=14.0, digit_flex=55.0, breakover=30.0, tail_lift=10.0, tail_swing=6.0, sway=1.5),
    _spec(name="canter", speed=5.0, frames=32, phases={"RH": 0.73, "LH": 0.0, "RF": 0.0, "LF": 0.20},
          duty=0.42, step_height=0.16, crouch=0.05, bob=0.05, bob_per_stride=1, bob_low=0.1,
          pitch=4.0, pitch_down=0.33, nod=6.0, nod_per_stride=1, nod_down=0.35, steady_head=0.0,
          spine_flex=3.5, spine_arched=0.0, carpus_flex=95.0, hock_flex=55.0, hock_load=10.0,
          fetlock_sink=18.0, digit_flex=60.0, breakover=30.0, tail_lift=15.0, tail_swing=10.0, sway=1.0),
    _spec(name="gallop", speed=9.8, frames=29, phases={"RH": 0.86, "LH": 0.0, "RF": 0.24, "LF": 0.40},
          duty=0.26, step_height=0.18, crouch=0.07, bob=0.06, bob_per_stride=1, bob_low=0.2,
          pitch=5.0, pitch_down=0.38, nod=7.0, nod_per_stride=1, nod_down=0.4, steady_head=0.0,
          spine_flex=5.0, spine_arched=0.1, carpus_flex=110.0, hock_flex=60.0, hock_load=12.0,
          fetlock_sink=22.0, digit_flex=70.0, breakover=35.0, tail_lift=25.0, tail_swing=12.0, sway=1.0,
          touchdown_ease=0.12),
)}

DOG_GAITS: dict[str, GaitSpec] = {g.name: g for g in (
    _spec(name="walk", speed=0.85, frames=46, phases={"LH": 0.0, "LF": 0.25, "RH": 0.5, "RF": 0.75},
          duty=0.62, step_height=0.11, crouch=0.025, bob=0.006, bob_per_stride=2, bob_low=0.1,
          pitch=1.0, pitch_down=0.25, nod=4.0, nod_per_stride=2, nod_down=0.3, steady_head=0.0,
          spine_flex=1.0, spine_arched=0.0, carpus_flex=60.0, hock_flex=35.0, hock_load=5.0,
          fetlock_sink=6.0, digit_flex=35.0, breakover=25.0, tail_lift=5.0, tail_swing=8.0, sway=3.0,
          lift_fall=1.0),
    _spec(name="trot", speed=1.9, frames=30, phases={"LH": 0.0, "RF": 0.0, "RH": 0.5, "LF": 0.5},
          duty=0.42, step_height=0.13, crouch=0.025, bob=0.012, bob_per_stride=2, bob_low=0.21,
          pitch=1.0, pitch_down=0.2, nod=2.0, nod_per_stride=2, nod_down=0.25, steady_head=0.7,
          spine_flex=2.0, spine_arched=0.2, carpus_flex=80.0, hock_flex=45.0, hock_load=8.0,
          fetlock_sink=8.0, digit_flex=45.0, breakover=30.0, tail_lift=10.0, tail_swing=8.0, sway=1.5,
          lift_fall=1.0),
    _spec(name="canter", speed=3.2, frames=28, phases={"RH": 0.75, "LH": 0.0, "RF": 0.0, "LF": 0.20},
          duty=0.30, step_height=0.15, crouch=0.035, bob=0.02, bob_per_stride=1, bob_low=0.1,
          pitch=5.0, pitch_down=0.33, nod=8.0, nod_per_stride=1, nod_down=0.35, steady_head=0.0,
          spine_flex=8.0, spine_arched=0.0, carpus_flex=90.0, hock_flex=50.0, hock_load=10.0,
          fetlock_sink=10.0, digit_flex=50.0, breakover=30.0, tail_lift=15.0, tail_swing=12.0, sway=1.0,
          lift_fall=1.0, lift_off_speed=0.2),
    _spec(name="gallop", speed=4.6, frames=25, phases={"RH": 0.86, "LH": 0.0, "LF": 0.16, "RF": 0.35},
          duty=0.24, step_height=0.20, crouch=0.055, bob=0.025, bob_per_stride=1, bob_low=0.15,
          pitch=7.0, pitch_down=0.35, nod=10.0, nod_per_stride=1, nod_down=0.4, steady_head=0.0,
          spine_flex=14.0, spine_arched=0.0, carpus_flex=100.0, hock_flex=55.0, hock_load=12.0,
          fetlock_sink=12.0, digit_flex=60.0, breakover=35.0, tail_lift=20.0, tail_swing=15.0, sway=1.0,
          lift_fall=1.0, lift_off_speed=0.2),
)}

# Swing height of each foot relative to its gait's step height: no two legs of an animal lift
# alike; fore feet clear the ground higher than hind ones (hoof clearance peaks higher in the
# forelimb, gait-reference table 4), and the two sides differ by a few per cent (our choice).
FOOT_LIFT: dict[str, float] = {"LF": 1.0, "RF": 0.94, "LH": 0.86, "RH": 0.9}

GAIT_SPECS: dict[str, dict[str, GaitSpec]] = {"horse": HORSE_GAITS, "dog": DOG_GAITS}

# Touchdown-order templates for synth_core.quality.metrics.footfall_order (groups that land together).
FOOTFALL_TEMPLATES: dict[str, dict[str, list[list[str]]]] = {
    "horse": {
        "walk": [["LH"], ["LF"], ["RH"], ["RF"]],
        "trot": [["LH", "RF"], ["RH", "LF"]],
        "canter": [["LH", "RF"], ["LF"], ["RH"]],
        "gallop": [["LH"], ["RF"], ["LF"], ["RH"]],
    },
    "dog": {
        "walk": [["LH"], ["LF"], ["RH"], ["RF"]],
        "trot": [["LH", "RF"], ["RH", "LF"]],
        "canter": [["LH", "RF"], ["LF"], ["RH"]],
        "gallop": [["LH"], ["LF"], ["RF"], ["RH"]],
    },
}
