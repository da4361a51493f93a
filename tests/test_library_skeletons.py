"""Built-in horse and dog skeletons: anatomy present, proportions within the cited ranges."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.builtin import BUILTIN_ANIMALS, build_skeleton, dog_skeleton, horse_skeleton
from synth_core.motion import bvh, quat
from synth_core.motion.clip import Motion
from synth_core.motion.skeleton import Skeleton, forward_kinematics
from tests.helpers.mocap import mann_path


def rest_positions(skel: Skeleton) -> dict[str, np.ndarray]:
    """World joint positions of the rest (standing) pose, the root at its rest height."""
    root_height = {"horse": 1.45, "dog": 0.46}[skel.name]
    pos, _ = forward_kinematics(skel, np.array([0.0, root_height, 0.0]), quat.identity((skel.n_joints,)))
    return dict(zip(skel.names, pos.astype(np.float64), strict=True))


def seg(p: dict[str, np.ndarray], a: str, b: str) -> float:
    return float(np.linalg.norm(p[a] - p[b]))


@pytest.mark.parametrize("animal", list(BUILTIN_ANIMALS))
def test_stands_on_all_four_feet_in_rest_pose(animal: str) -> None:
    skel = build_skeleton(animal)
    pos = rest_positions(skel)
    feet = [skel.names[f.end_effector] for f in skel.feet]
    heights = [pos[f][1] for f in feet]
    np.testing.assert_allclose(heights, 0.0, atol=1e-4)
    lowest = min(p[1] for p in pos.values())
    assert lowest >= -1e-4, "nothing below the ground"
    # Left feet on +X, fore feet ahead (+Z): the convention the library promises.
    lf, rf, lh, rh = (pos[f] for f in feet)
    assert lf[0] > 0 > rf[0] and lh[0] > 0 > rh[0]
    assert min(lf[2], rf[2]) > max(lh[2], rh[2])


@pytest.mark.parametrize("animal", list(BUILTIN_ANIMALS))
def test_limb_chains_are_long_enough_for_ik_and_declared_in_preorder(animal: str) -> None:
    skel = build_skeleton(animal)
    for foot in skel.feet:
        assert len(foot.chain) >= 5, f"{foot.name}: {[skel.names[j] for j in foot.chain]}"
    motion = Motion(skel, np.zeros((2, 3)), quat.identity((2, skel.n_joints)), 60.0)
    again = bvh.parse(bvh.dumps(motion))
    assert again.skeleton.names == skel.names  # preorder: BVH keeps the order
    np.testing.assert_allclose(again.skeleton.offsets, skel.offsets, atol=1e-6)


def test_horse_anatomy_and_proportions() -> None:
    skel = horse_skeleton()
    names = set(skel.names)
    assert skel.n_joints >= 30
    assert sum(n.startswith("Spine") for n in names) >= 3
    assert sum(n.startswith("Neck") for n in names) >= 2
    assert {"Head", "Tail1", "Tail2", "Tail3"} <= names
    for side in "LR":
        fore = [f"{side}_{j}" for j in ("Scapula", "Humerus", "Radius", "Cannon", "Pastern", "Hoof")]
        hind = [f"{side}_{j}" for j in ("Femur", "Tibia", "HindCannon", "HindPastern", "HindHoof")]
        chain = {f.name: [skel.names[j] for j in f.chain] for f in skel.feet}
        assert chain[f"{side}F"][:-1] == fore and chain[f"{side}H"][:-1] == hind
    p = rest_positions(skel)
    assert p["Spine3_end"][1] == pytest.approx(1.60, abs=0.03)  # withers ~1.6 m
    body_length = p["L_Humerus"][2] - p["Tail1"][2]  # point of shoulder to point of buttock
    assert 0.95 < body_length / p["Spine3_end"][1] < 1.15  # a "square" horse
    forearm, fore_cannon = seg(p, "L_Radius", "L_Cannon"), seg(p, "L_Cannon", "L_Pastern")
    hind_cannon = seg(p, "L_HindCannon", "L_HindPastern")
    assert 1.4 < forearm / fore_cannon < 1.8  # forearm clearly longer than the cannon
    assert hind_cannon > fore_cannon  # hind cannon longer than fore cannon
    assert 0.85 < seg(p, "L_Femur", "L_Tibia") / seg(p, "L_Tibia", "L_HindCannon") < 1.15
    assert 0.8 < p["L_Radius"][1] < 1.0  # elbow height
    assert 1.0 < p["L_Humerus"][1] < 1.2  # point of shoulder height
    assert 0.45 < p["L_HindCannon"][1] < 0.6  # hock height
    # Standing conformation: stifle ahead of the hip, hock behind the stifle, pastern sloping
    # forward-down at 50-60 degrees to the ground.
    assert p["L_Tibia"][2] > p["L_Femur"][2] > p["L_HindCannon"][2]
    pastern = p["L_Hoof"] - p["L_Pastern"]
    angle = np.degrees(np.arctan2(-pastern[1], pastern[2]))
    assert 50 < angle < 60


def test_dog_matches_the_real_dog_proportions() -> None:
    skel = dog_skeleton()
    p = rest_positions(skel)
    assert p["Pelvis"][1] == pytest.approx(0.46)  # hip height, SOURCE.md
    # MANN segment lengths (SOURCE.md hierarchy, metres); our paw = metapodial + toe.
    assert seg(p, "L_Humerus", "L_Radius") == pytest.approx(0.152, abs=1e-3)
    assert seg(p, "L_Radius", "L_Metacarpus") == pytest.approx(0.178, abs=1e-3)
    assert seg(p, "L_Femur", "L_Tibia") == pytest.approx(0.160, abs=1e-3)
    assert seg(p, "L_Tibia", "L_Metatarsus") == pytest.approx(0.180, abs=1e-3)
    fore_paw = seg(p, "L_Metacarpus", "L_FrontToe") + seg(p, "L_FrontToe", "L_FrontToe_end")
    hind_paw = seg(p, "L_Metatarsus", "L_HindToe") + seg(p, "L_HindToe", "L_HindToe_end")
    assert fore_paw == pytest.approx(0.072, abs=1e-3)
    assert hind_paw == pytest.approx(0.108, abs=1e-3)


def test_dog_stance_matches_the_real_dog_standing() -> None:
    """Paw spacing and joint heights against MANN D1_ex01 standing (frames 20-140), within 3 cm."""
    real = bvh.read(mann_path("D1_ex01_KAN01_001"))
    pos = real.positions()[20:140].astype(np.float64).mean(axis=0)
    names = real.skeleton.names
    at = {n: pos[names.index(n)] for n in names}
    ours = rest_positions(dog_skeleton())
    # The real dog stands with one hind paw forward: compare the mean fore-hind spacing.
    real_spacing = np.mean([np.linalg.norm((at[f"{s}Hand_end"] - at[f"{s}Foot_end"])[[0, 2]])
                            for s in ("Left", "Right")])
    our_spacing = abs(ours["L_FrontToe_end"][2] - ours["L_HindToe_end"][2])
    assert our_spacing == pytest.approx(real_spacing, abs=0.03)
    for real_name, our_name in (("LeftArm", "L_Humerus"), ("LeftForeArm", "L_Radius"),
                                ("LeftUpLeg", "L_Femur"), ("LeftLeg", "L_Tibia")):
        assert ours[our_name][1] == pytest.approx(at[real_name][1], abs=0.03), our_name


def test_unknown_animal_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="animal: expected one of"):
        build_skeleton("unicorn")
