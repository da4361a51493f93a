"""Run-time synthesis (paper sections 5-6) and the foot lock, on the built-in horse and a herd."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build.library_store import builtin_library
from synth_core.compiled import foot_kernels, kernels
from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.quality import metrics as M
from synth_core.runtime import footlock
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.synthesis import Options, Result, headings, synthesize
from synth_core.runtime.trajectory import TrajectoryError
from tests.helpers.motion import plant_stands


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(6, 900, seed=0, top=6.0)


@pytest.fixture(scope="module")
def result(bank: Bank, herd: np.ndarray) -> Result:
    return synthesize(bank, herd, options=Options(scale_range=(0.8, 1.2), seed=0))


def feet_of(bank: Bank, res: Result) -> np.ndarray:
    offsets = bank.skeleton.offsets[None, None] * res.scales[:, None, None, None]
    pos, _ = forward_kinematics(bank.skeleton, res.root_pos, res.rotations, offsets)
    return np.asarray(pos)[..., bank.skeleton.foot_joints, :]


def test_shapes_and_no_nan(bank: Bank, herd: np.ndarray, result: Result) -> None:
    C, T = herd.shape[:2]
    assert result.rotations.shape == (C, T, bank.skeleton.n_joints, 4)
    assert result.root_pos.shape == (C, T, 3) and result.contacts.shape == (C, T, 4)
    assert np.isfinite(result.rotations).all() and np.isfinite(result.root_pos).all()
    assert np.allclose(np.linalg.norm(result.rotations, axis=-1), 1.0, atol=1e-4)


def test_everyone_starts_standing_and_moves_one_hub_at_a_time(result: Result) -> None:
    assert np.all(result.gait[:, 0] == 0)
    assert np.abs(np.diff(result.gait.astype(int), axis=1)).max() == 1
    used = set(np.unique(result.gait).tolist())
    assert used == {0, 1, 2, 3, 4}, used  # this herd speeds up to a gallop and back


def test_root_stays_on_the_path_and_keeps_time(result: Result) -> None:
    error = M.path_error(result.root_pos, result.path)
    assert error.max_cm <= 10.0  # timing: the same frame's trajectory point
    offset = (result.root_pos - result.path)[..., [0, 2]]
    yaw = headings(result.path, 60.0)
    left = np.stack([np.cos(yaw), -np.sin(yaw)], axis=-1)
    assert np.abs(np.sum(offset * left, axis=-1)).max() <= 0.01  # sideways: at most 1 cm



def test_headings_of_the_first_frames_are_the_wholes() -> None:
    """headings(frames=n) reads the path beyond n only for characters standing until then."""
    t = np.arange(300)[:, None]
    path = np.zeros((3, 300, 3))
    path[0] = np.where(t < 40, 0.0, 0.02 * (t - 40)) * np.array([1.0, 0.0, 0.0])  # moves at 40
    path[1] = np.where(t < 200, 0.0, 0.02 * (t - 200)) * np.array([0.0, 0.0, -1.0])  # stands past 120
    path[2] = 0.01 * t * np.array([0.6, 0.0, 0.8])  # moves from the start
    whole = headings(path, 60.0)
    for n in (1, 41, 120, 299, 300, 400):
        np.testing.assert_array_equal(headings(path, 60.0, n), whole[:, :n])
    assert whole[1, 0] == np.pi  # the standing one faces where it will go

def test_same_seed_same_motion_other_seed_other_choices(bank: Bank, herd: np.ndarray, result: Result) -> None:
    again = synthesize(bank, herd, options=Options(scale_range=(0.8, 1.2), seed=0))
    assert np.array_equal(again.rotations, result.rotations)
    assert np.array_equal(again.root_pos, result.root_pos)
    other = synthesize(bank, herd, options=Options(scale_range=(0.8, 1.2), seed=1))
    assert not np.array_equal(other.scales, result.scales)


def test_a_bigger_animal_uses_slower_motion_on_the_same_path(bank: Bank) -> None:
    path = crowd.simulate(1, 600, seed=3, top=3.0)
    both = np.concatenate([path, path])
    res = synthesize(bank, both, scales=np.array([1.0, 2.0]))
    assert res.gait[1].astype(int).sum() < res.gait[0].astype(int).sum()
    standing = res.gait[:, 5] == 0
    assert standing.all()
    assert res.root_pos[1, 5, 1] == pytest.approx(2 * res.root_pos[0, 5, 1], rel=0.02)


def test_bad_characters_are_named_or_skipped_without_losing_the_others(bank: Bank) -> None:
    paths = crowd.simulate(3, 300, seed=0, top=3.0).astype(np.float64)
    paths[1, 40] = np.nan
    with pytest.raises(TrajectoryError, match="character b: positions: NaN or Inf at frame 40"):
        synthesize(bank, paths, ids=["a", "b", "c"])
    res = synthesize(bank, paths, ids=["a", "b", "c"], options=Options(skip_invalid=True))
    assert res.kept.tolist() == [0, 2] and list(res.rejected) == [1]
    assert np.isfinite(res.rotations).all()
    with pytest.raises(TrajectoryError, match="scales: expected 3 values"):
        synthesize(bank, paths, scales=np.ones(2))


def test_plant_targets_hold_each_plant_in_one_place() -> None:
    rng = np.random.default_rng(0)
    feet = np.cumsum(rng.normal(0, 0.01, (2, 60, 4, 3)), axis=1)
    contacts = np.zeros((2, 60, 4), bool)
    contacts[:, 10:25] = contacts[:, 40:55] = True
    targets = np.empty_like(feet)
    for c in range(2):
        soles = np.ascontiguousarray(feet[c, ..., 1])  # the clips stand each foot where it is
        foot_kernels.plant_targets(feet[c], soles, contacts[c], targets[c], kernels.WHOLE_PLANT,
                                   np.zeros((4, 3)), np.full(4, foot_kernels.NOWHERE), -1,
                                   foot_kernels.no_steps(60))
    for a, b in ((10, 25), (40, 55)):
        for c, f in np.ndindex(2, 4):
            assert np.allclose(targets[c, a:b, f], plant_stands(feet[c, a:b, f]))
    # Swings: no jump where a plant starts or ends (over the ground).
    step = np.linalg.norm(np.diff(targets[..., [0, 2]], axis=1), axis=-1)
    assert step.max() < 5 * np.linalg.norm(np.diff(feet[..., [0, 2]], axis=1), axis=-1).max()


def _targets(feet: np.ndarray, contacts: np.ndarray, leg: float) -> np.ndarray:
    T = len(feet)
    body = list(foot_kernels.no_steps(T))
    body[0] = np.zeros((4, 6))
    body[0][:, 4] = leg  # each leg's reach: the swing's clearance is a share of it
    targets = np.empty_like(feet)
    soles = np.ascontiguousarray(feet[..., 1])  # the clips stand each foot where it is
    foot_kernels.plant_targets(feet, soles, contacts, targets, kernels.WHOLE_PLANT, np.zeros((4, 3)),
                               np.full(4, foot_kernels.NOWHERE), -1, tuple(body))
    return targets


def test_a_plant_held_up_by_a_fade_stands_on_the_ground_and_a_swing_clears_it() -> None:
    """Issue 27's glide: a foot near the ground while it moves slides. A plant whose last frames
    a fade lifts 2 cm stands where its foot stood, on the ground; a swing whose clip pose drags
    the foot along the ground (a fade under a held frame) is lifted off it, rising early and
    setting down over its last frames."""
    T, leg = 60, 1.0
    feet = np.zeros((T, 4, 3))
    feet[:, :, 2] = np.linspace(0.0, 3.0, T)[:, None]  # moving on, never off the ground
    contacts = np.zeros((T, 4), bool)
    contacts[10:25] = contacts[40:55] = True
    feet[10:25, :, 2] = feet[10, :, 2]
    feet[40:55, :, 2] = feet[40, :, 2]
    feet[16:25, :, 1] = 0.02  # the plant's last frames lifted by a fade
    targets = _targets(feet, contacts, leg)
    assert np.allclose(targets[10:25, :, 1], 0.0)
    swing = targets[25:40, :, 1]
    clear = footlock.CLEARANCE * footlock.STEP_HEIGHT * leg
    # Up to its clearance, less what the jump easing takes off a swing rising this fast while the
    # foot speeds up 3 -> 10 cm a frame (jump_kernels.ease_jumps: 38 mm of 40): never under the
    # least clearance in the world, well out of the glide's 2.5 cm band.
    assert footlock.CLEAR_LEAST <= swing.max() <= clear and (swing > 0).all()
    rise, fall = np.diff(swing[:4, 0]).max(), -np.diff(swing[-4:, 0]).min()
    assert rise > fall > 0  # up fast, down slowly
    assert np.allclose(targets[10:25, :, 2], feet[10:25, :, 2])


def test_foot_lock_pins_planted_feet(bank: Bank, herd: np.ndarray, result: Result) -> None:
    unlocked = synthesize(bank, herd, options=Options(scale_range=(0.8, 1.2), seed=0, foot_lock=False))
    before = M.foot_skate(feet_of(bank, unlocked), unlocked.contacts)
    after = M.foot_skate(feet_of(bank, result), result.contacts)
    assert after.p95_mm < before.p95_mm / 2 and after.mean_mm < before.mean_mm / 2


def test_writing_into_given_output_arrays_gives_the_same_motion(bank: Bank, herd: np.ndarray,
                                                               result: Result) -> None:
    out = (np.full_like(result.root_pos, np.nan), np.full_like(result.rotations, np.nan))
    again = synthesize(bank, herd, options=Options(scale_range=(0.8, 1.2), seed=0), out=out)
    assert again.root_pos is out[0] and again.rotations is out[1]
    assert np.array_equal(again.rotations, result.rotations)
    assert np.array_equal(again.root_pos, result.root_pos)
    with pytest.raises(ValueError, match=r"out rotations: need a C-contiguous float32 array of shape"):
        synthesize(bank, herd, options=Options(scale_range=(0.8, 1.2)), out=(out[0], out[1][:, :-1]))


def test_unknown_backend_is_refused(bank: Bank, herd: np.ndarray) -> None:
    with pytest.raises(TrajectoryError, match="backend"):
        synthesize(bank, herd[:1, :50], options=Options(backend="gpu"))


@pytest.mark.parametrize("animal", ["horse", "dog"])
def test_issue_5_quality_figures_on_the_standard_scenario(animal: str) -> None:
    """`quadsynth eval`: 500 characters x 500 frames of crowd-sim seed 0, scales in [0.8, 1.2]."""
    bank = build_bank(builtin_library(animal))  # the file ./scripts/test builds (else built here)
    fig = evaluate.standard(bank)
    assert fig["path_error_cm_max"] <= 1.0 and fig["timing_error_cm_max"] <= 10.0
    assert fig["skate_mm_mean"] <= 1.0 and fig["skate_mm_p95"] <= 3.0
    # Strides wholly in one piece; those with a piece starting inside step partly in a transition.
    assert fig["footfall_preserved"] >= 0.99 and fig["footfall_across_transitions"] >= 0.98
    assert fig["pop_ratio"] <= 1.5
    assert fig["penetration_mm"] <= 5.0 and fig["nan_count"] == 0
    assert min(fig["gait_frames"].values()) > 0.05 * 500 * 500  # every gait used, and not in passing
    # Today's defaults (the clock kept, Froude sizes, each character's tempo): the same bounds on
    # the path, skate and footfall within a gait; pops and transition strides are reported.
    now = fig["defaults"]
    assert now["resample_rate"] == 1.0 and now["nan_count"] == 0 and now["penetration_mm"] <= 5.0
    assert now["path_error_cm_max"] <= 1.0 and now["skate_mm_p95"] <= 3.0
    assert now["footfall_preserved"] >= 0.99


def test_footfall_strides_with_a_piece_starting_inside_are_counted_apart(bank: Bank) -> None:
    hub = bank.hubs.index("trot")
    piece = bank.gaits[hub]
    stride = bank.contacts[piece.offset:piece.offset + piece.frames]
    contacts = np.tile(stride, (6, 1))[None]  # six strides of the library's own trot
    T = contacts.shape[1]

    def shares(contacts: np.ndarray, stitches: np.ndarray) -> tuple[float, float]:
        result = Result(np.zeros((1, T, 3), np.float32), np.zeros((1, T, 1, 4), np.float32),
                        np.full((1, T), hub, np.int8), contacts, stitches, np.ones(1), np.zeros((1, T, 3)),
                        1.0, np.arange(1))
        return evaluate.footfall_preserved(bank, result)

    none = np.zeros((1, T), bool)
    within, across = shares(contacts, none)
    assert within == 1.0 and np.isnan(across)
    # One stride's right fore lands a third of a stride late: that stride is out of order.
    broken = contacts.copy()
    a = 2 * piece.frames
    broken[0, a:a + piece.frames, 1] = np.roll(stride[:, 1], piece.frames // 3)
    within, across = shares(broken, none)
    assert 0 < within < 1 and np.isnan(across)
    # With a piece starting inside it (a transition's end, say) it is counted apart.
    starts = none.copy()
    starts[0, a + piece.frames // 2] = True
    within, across = shares(broken, starts)
    assert within == 1.0 and across == 0.0


def test_pops_are_looked_for_near_each_stitch_only() -> None:
    stitches = np.zeros((2, 10), bool)
    stitches[0, 9] = stitches[1, 4] = True
    near = evaluate.near_stitches(stitches, 2)
    assert near[0].tolist() == [False] * 7 + [True] * 3  # the last frame's stitch does not wrap round
    assert near[1].tolist() == [False] * 2 + [True] * 5 + [False] * 3


def _steady(speeds: list[float], frames: int = 900) -> np.ndarray:
    """Characters on parallel straight lines, each at its own steady speed (m/s, 60 fps),
    after a second's stand."""
    t = np.clip(np.arange(frames) - 60, 0, None) / 60.0
    return np.stack([np.stack([np.full(frames, 3.0 * c), np.zeros(frames), s * t], axis=-1)
                     for c, s in enumerate(speeds)])


def _stride_frames(res: Result, c: int) -> float:
    """Median frames between LH touchdowns over the last 400 frames (the gait settled)."""
    down = np.flatnonzero(np.diff(res.contacts[c, -400:, 2].astype(int)) == 1)
    return float(np.median(np.diff(down)))


def test_sizes_are_dynamically_similar_by_default_and_geometric_as_the_paper_on_request(bank: Bank) -> None:
    """Froude: a character of scale h at speed v moves as the library does at v / sqrt(h) -- the
    same gait at the same v^2 / (g h) -- with stride frequency ~ 1 / sqrt(h) (Alexander & Jayes
    1983). So a half-size and a double-size horse at the same Froude number take the same gait,
    the small one at twice the frequency; the paper's s/h matching steps every size at the
    library's frequency, and sends a half-size horse at 3 m/s into a faster gait."""
    canter = bank.hubs.index("canter")
    v1 = float(np.mean(bank.speeds[canter][[0, -1]]))  # the library's mid canter, scale 1
    h = np.array([0.5, 2.0])
    paths = _steady(list(v1 * np.sqrt(h)))  # one Froude number for both
    froude = synthesize(bank, paths, scales=h, options=Options(tempo_spread=0.0))
    assert (froude.gait[:, -400:] == canter).all()
    small, big = _stride_frames(froude, 0), _stride_frames(froude, 1)
    assert big / small == pytest.approx(2.0, rel=0.08)  # sqrt(2.0 / 0.5)
    # A half-size horse at 3 m/s: s/h asks the library for 6 m/s (a gallop), Froude for 4.2.
    paper = synthesize(bank, _steady([3.0]), scales=[0.5],
                       options=Options(size_matching="geometric", tempo_spread=0.0))
    dynamic = synthesize(bank, _steady([3.0]), scales=[0.5], options=Options(tempo_spread=0.0))
    assert paper.gait[0, -1] == bank.hubs.index("gallop") and dynamic.gait[0, -1] < paper.gait[0, -1]
    same_fr = synthesize(bank, _steady(list(v1 * h)), scales=h,  # s/h alike: one frequency for both
                         options=Options(size_matching="geometric", tempo_spread=0.0))
    assert _stride_frames(same_fr, 0) == pytest.approx(_stride_frames(same_fr, 1), abs=1.0)


def test_each_character_steps_at_its_own_tempo_seeded(bank: Bank) -> None:
    """Equal horses at one speed: stride periods spread within +- the tempo spread (drawn per
    character from its key: the same seed, the same tempos); none with spread 0."""
    paths = _steady([2.2] * 8)
    opts = Options(scale_range=(1.0, 1.0), seed=3)
    res = synthesize(bank, paths, options=opts)
    periods = np.array([_stride_frames(res, c) for c in range(8)])
    assert periods.max() / periods.min() > 1.03 and periods.max() / periods.min() < (1.06 / 0.94) * 1.03
    again = synthesize(bank, paths, options=opts)
    assert np.array_equal(again.contacts, res.contacts)
    same = synthesize(bank, paths, options=Options(scale_range=(1.0, 1.0), seed=3, tempo_spread=0.0))
    assert len({_stride_frames(same, c) for c in range(8)}) == 1
    with pytest.raises(TrajectoryError, match="tempo_spread"):
        synthesize(bank, paths, options=Options(tempo_spread=0.5))
    with pytest.raises(TrajectoryError, match="size_matching"):
        synthesize(bank, paths, options=Options(size_matching="cubic"))


def test_a_creeping_character_walks_slowly_with_its_feet_on_the_ground(bank: Bank) -> None:
    """Below the slowest walk clip the walk plays slower (longer stances) instead of the animal
    standing while its root creeps on over pinned feet (issue 27: hooves floated 25 cm). After FK:
    the lowest foot stays on the ground (<= 1 cm, issue 27's floating target) and the feet step."""
    speeds = [0.1, 0.2, 0.4]
    res = synthesize(bank, _steady(speeds, 720), scales=np.ones(3), options=Options(tempo_spread=0.0))
    feet = feet_of(bank, res)
    height = feet[..., 1] - res.path[..., None, 1]
    moving = slice(180, None)  # past the start
    assert (height[:, moving].min(axis=-1) <= 0.01).all()
    walk = bank.hubs.index("walk")
    assert (res.gait[:, moving] == walk).mean() > 0.95
    travelled = np.linalg.norm(feet[:, -1][..., [0, 2]] - feet[:, 180][..., [0, 2]], axis=-1)  # (C, 4)
    assert (travelled > 0.5 * np.array(speeds)[:, None] * (720 - 180) / 60).all()  # every foot steps on
