"""Ground that is not flat (issue 33): the height field, the render on it, and its figures."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build.animals import build_builtin
from synth_core.compiled import foot_kernels, kernels
from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import edge
from synth_core.quality import metrics as M
from synth_core.quality.evaluate import HUBS, TERRAIN_TARGETS, edge_suite, passes, world_positions
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.streaming import BatchStream
from synth_core.runtime.synthesis import Options, synthesize
from synth_core.runtime.terrain import HeightField, TerrainError, along_ground
from synth_core.runtime.trajectory import Prepared
from tests.helpers.motion import herd_on_hills


def test_bilinear_sampling_is_exact_on_planes_and_holds_the_edges() -> None:
    x, z = np.meshgrid(np.arange(5.0), np.arange(4.0))
    field = HeightField.make(0.3 * x - 0.2 * z + 1.0, origin=(10.0, -2.0), spacing=0.5)
    rng = np.random.default_rng(0)
    px, pz = rng.uniform(10.0, 12.0, 50), rng.uniform(-2.0, -0.5, 50)
    expect = 0.3 * (px - 10.0) / 0.5 - 0.2 * (pz + 2.0) / 0.5 + 1.0
    assert np.allclose(field.sample(px, pz), expect)
    # Outside the grid: the nearest edge's height.
    assert np.allclose(field.sample([0.0, 100.0], [-2.0, -2.0]), [1.0, 0.3 * 4 + 1.0])
    assert field.sample(np.zeros((2, 3)), np.zeros((2, 3))).shape == (2, 3)


@pytest.mark.parametrize(("heights", "kw", "field"), [
    ([[0.0, np.nan], [0.0, 0.0]], {}, "ground.heights"),
    ([0.0, 1.0, 2.0], {}, "ground.heights"),
    ([[0.0, 1.0]], {}, "ground.heights"),
    (np.zeros((2, 2)), {"spacing": 0.0}, "ground.spacing"),
    (np.zeros((2, 2)), {"origin": (0.0, np.inf)}, "ground.origin"),
    (np.zeros((2, 2)), {"origin": (0.0,)}, "ground.origin"),
])
def test_bad_height_fields_are_refused_naming_the_field(heights: object, kw: dict[str, object],
                                                        field: str) -> None:
    with pytest.raises(TerrainError, match=field):
        HeightField.make(heights, **kw)  # type: ignore[arg-type]


def test_the_gait_reads_the_speed_along_the_ground() -> None:
    x = np.linspace(0.0, 20.0, 601)
    positions = np.stack([x, np.zeros_like(x), np.zeros_like(x)], -1)[None]
    prep = Prepared(positions, 30, np.full((1, 20), 2.0), 1.0, np.zeros(1, np.int64))
    xs = np.arange(-5.0, 30.0)
    field = HeightField.make(np.tile(0.3 * xs, (3, 1)), origin=(-5.0, -1.0), spacing=1.0)
    on = along_ground(prep, field, 30.0)
    assert np.allclose(on.positions[0, :, 1], 0.3 * x)
    assert np.allclose(on.segment_speeds, np.hypot(1.0, 0.3) * 20.0 / 600 * 30.0)


def test_a_flat_terrain_renders_as_the_flat_paths_do(bank: Bank) -> None:
    """... but for the body lowering further where a leg would stretch (the flat render sinks
    the root 5% of a leg at most, a terrain 20%): there the terrain's legs reach less far."""
    paths, _ = herd_on_hills()
    paths[..., 1] = 0.7
    field = HeightField.make(np.full((8, 8), 0.7), origin=(-20.0, -20.0), spacing=20.0)
    plain = synthesize(bank, paths, 60.0, options=Options(seed=1))
    on = synthesize(bank, paths, 60.0, options=Options(seed=1, ground=field))
    assert np.array_equal(plain.gait, on.gait) and np.array_equal(plain.contacts, on.contacts)
    lowered = np.abs(plain.root_pos - on.root_pos).max(axis=-1) > 1e-4
    assert lowered.mean() < 0.05 and np.all(on.root_pos[lowered, 1] < plain.root_pos[lowered, 1])
    reach = [M.limb_reach(world_positions(bank, r), bank.skeleton).max(axis=-1) for r in (plain, on)]
    assert np.all(reach[1][lowered] < reach[0][lowered])
    same = ~lowered
    assert np.abs(plain.root_pos[same] - on.root_pos[same]).max() < 1e-4
    dots = np.abs(np.sum(plain.rotations[same] * on.rotations[same], -1))
    assert 2 * np.degrees(np.arccos(np.clip(dots, 0, 1))).max() < 0.1  # float32: 1 ulp is 0.04


@pytest.mark.parametrize("name", ["slope_up_30", "slope_down_30", "slope_across_30", "step_20cm",
                                  "rolling_hills", "bumpy"])
def test_terrain_scenarios_meet_the_issue_targets(bank: Bank, name: str) -> None:
    entry = edge_suite(bank, names=[name])["scenarios"][name]
    figures = entry["figures"]
    for figure in TERRAIN_TARGETS:  # planted feet on the ground, none in it, the body with the slope
        assert passes(figure, figures[figure]), (figure, figures[figure])
    assert figures["stretch_pct_max"] <= 3.0
    assert figures["limb_flips"] == 0
    assert figures["glide_ratio"] <= 0.10 and figures["strict_skate_mm_p95"] <= 3.0
    # Issue 27's one-frame jump: a hoof planted on the step's edge was over its top in its first
    # swing frame, 13.7 cm up at once, before the terrain's jumps were eased (step_20cm: 11.6 cm).
    assert passes("jump_cm_max", figures["jump_cm_max"]), figures["jump_cm_max"]


def test_stream_windows_on_a_terrain_equal_the_whole_batch(bank: Bank) -> None:
    """(The reference backend: tests/test_backends.py, as for tests/test_streaming.py.)"""
    paths, field = herd_on_hills()
    opts = Options(scale_range=(0.8, 1.2), seed=2, ground=field)
    whole = synthesize(bank, paths, 60.0, options=opts)
    for chunk in (7, 100):
        windows = list(BatchStream(bank, paths, 60.0, options=opts, chunk_frames=chunk).windows())
        for name in ("root_pos", "rotations", "gait", "contacts"):
            joined = np.concatenate([getattr(w, name) for w in windows], axis=1)
            assert np.array_equal(joined, getattr(whole, name)), (name, chunk)


def test_a_swing_steps_up_a_step_instead_of_jumping_onto_it() -> None:
    z = np.concatenate([np.zeros(10), np.linspace(0.0, 1.0, 12)[1:-1], np.ones(10)])  # 30 frames
    targets = np.zeros((1, 30, 4, 3))
    targets[0, :, :, 2] = z[:, None]
    contacts = np.zeros((1, 30, 4), bool)
    contacts[0, :10] = contacts[0, 20:] = True
    xs = np.arange(-1.0, 2.0, 0.01)
    step = np.where(xs > 0.3, 0.2, 0.0)  # a 20 cm step 0.3 m into the swing
    field = HeightField.make(np.tile(step[:, None], (1, 3)), origin=(-0.01, -1.0), spacing=0.01)
    on = targets[0].copy()
    f = field
    foot_kernels.ground_targets(on, contacts[0], f.heights, *f.origin, f.spacing, 1.0, np.empty(30))
    y = on[:, 0, 1]
    under = field.sample(targets[0, :, 0, 0], targets[0, :, 0, 2])
    assert np.allclose(y[contacts[0, :, 0]], under[contacts[0, :, 0]])  # planted: on it
    assert np.all(y >= under - 1e-9)  # never in it
    assert np.abs(np.diff(y)).max() < 0.2 / 2  # up over frames, not in the one crossing the edge


def test_a_live_session_stands_on_its_ground_as_the_batch_does(bank: Bank) -> None:
    paths, field = herd_on_hills()
    live = LiveSynth(bank, len(paths), 60.0, seed=5, ground=field)
    windows = [w for i in range(0, paths.shape[1], 6) if (w := live.append(paths[:, i:i + 6])) is not None]
    if (last := live.finish()) is not None:
        windows.append(last)
    root = np.concatenate([w.root_pos for w in windows], axis=1)
    rot = np.concatenate([w.rotations for w in windows], axis=1)
    contacts = np.concatenate([w.contacts for w in windows], axis=1)
    offsets = bank.skeleton.offsets[None, None] * live.scales[:, None, None, None].astype(np.float32)
    feet = np.asarray(forward_kinematics(bank.skeleton, root, rot, offsets)[0])
    feet = feet[..., bank.skeleton.foot_joints, :]
    above = feet[..., 1] - field.sample(feet[..., 0], feet[..., 2])
    assert above.min() > -0.005  # no foot in the hills
    # Planted feet on them (within a centimetre of their lowest, as in the batch: the paw's sole).
    batch = synthesize(bank, paths, 60.0, options=Options(seed=5, ground=field))
    b_feet = np.asarray(forward_kinematics(bank.skeleton, batch.root_pos, batch.rotations, offsets)[0])
    b_feet = b_feet[..., bank.skeleton.foot_joints, :]
    b_above = b_feet[..., 1] - field.sample(b_feet[..., 0], b_feet[..., 2])
    assert np.percentile(above[contacts], 95) <= np.percentile(b_above[batch.contacts], 95) + 0.005


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_live_session_chooses_its_gaits_on_the_speed_along_the_ground_as_the_batch(
        bank: Bank, backend: str) -> None:
    if backend == "numba" and not kernels.AVAILABLE:
        pytest.skip("numba is not installed")
    # Straight up a 30% slope at speeds around the gaits' boundaries: over the map they read 4.4%
    # slower than along the ground, which moves some gait choices.
    T = 900
    speed = np.interp(np.arange(T), [0, 300, 600, T], [1.0, 2.4, 4.2, 1.6])
    paths = np.zeros((4, T, 3))
    for c in range(4):
        paths[c, :, 2] = np.cumsum(speed * (0.9 + 0.07 * c)) / 60.0
        paths[c, :, 0] = 2.0 * c
    xs = np.arange(-5.0, 60.0)
    field = HeightField.make(np.tile(0.3 * xs[:, None], (1, 20)), origin=(-5.0, -5.0), spacing=1.0)
    opts = dict(seed=5, foot_lock=False, backend=backend)
    batch = synthesize(bank, paths, 60.0, options=Options(ground=field, **opts))  # type: ignore[arg-type]
    flat = synthesize(bank, paths, 60.0, options=Options(**opts))  # type: ignore[arg-type]
    live = LiveSynth(bank, len(paths), 60.0, seed=5, foot_lock=False, backend=backend, ground=field)
    windows = [w for i in range(0, T, 7) if (w := live.append(paths[:, i:i + 7])) is not None]
    if (last := live.finish()) is not None:
        windows.append(last)
    gait = np.concatenate([w.gait for w in windows], axis=1)
    contacts = np.concatenate([w.contacts for w in windows], axis=1)
    root = np.concatenate([w.root_pos for w in windows], axis=1)
    t = slice(0, T - 3 * bank.mean_cycle)  # as tests/test_live.py: the batch's last segment differs
    assert not np.array_equal(batch.gait[:, t], flat.gait[:, t])  # the slope moved some choices ...
    np.testing.assert_array_equal(gait[:, t], batch.gait[:, t])  # ... and live moved them alike
    np.testing.assert_array_equal(contacts[:, t], batch.contacts[:, t])
    np.testing.assert_allclose(root[:, t], batch.root_pos[:, t], atol=1e-5)


def _live_feet(bank: Bank, live: LiveSynth, paths: np.ndarray, change: tuple[int, HeightField]) -> np.ndarray:
    """The session's feet after FK ``(C, T, 4, 3)``, points 6 at a time, the ground set anew
    before the points from frame ``change[0]`` on."""
    windows = []
    for i in range(0, paths.shape[1], 6):
        if i == change[0]:
            live.set_ground(change[1])
        if (w := live.append(paths[:, i:i + 6])) is not None:
            windows.append(w)
    if (last := live.finish()) is not None:
        windows.append(last)
    root = np.concatenate([w.root_pos for w in windows], axis=1)
    rot = np.concatenate([w.rotations for w in windows], axis=1)
    offsets = bank.skeleton.offsets[None, None] * live.scales[:, None, None, None].astype(np.float32)
    world = np.asarray(forward_kinematics(bank.skeleton, root, rot, offsets)[0])
    return world[..., bank.skeleton.foot_joints, :]


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_new_ground_mid_session_is_faded_in_not_jumped_to(bank: Bank, backend: str,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    if backend == "numba" and not kernels.AVAILABLE:
        pytest.skip("numba is not installed")
    from synth_core.runtime import live as live_module
    T = 600
    paths = np.zeros((3, T, 3))
    for c, speed in enumerate((0.0, 1.5, 3.0)):  # standing, walking, trotting
        paths[c, :, 2] = np.arange(T) * speed / 60.0
        paths[c, :, 0] = 3.0 * c
    low = HeightField.make(np.zeros((4, 4)), origin=(-10.0, -10.0), spacing=20.0)
    high = HeightField.make(np.full((4, 4), 0.2), origin=(-10.0, -10.0), spacing=20.0)  # 20 cm up
    feet = _live_feet(bank, LiveSynth(bank, 3, 60.0, seed=3, backend=backend, ground=low), paths, (360, high))
    # Frames from 150 on: the change falls there (the frames rendered after the points of frame
    # 360 came; the trot's first strides jump on flat ground too).
    jumps = M.one_frame_jumps_mm(feet[:, 150:])
    assert jumps.max() < 60.0  # no one-frame jump of a foot
    assert feet[:, :120, :, 1].min() < 0.01 and feet[:, -60:, :, 1].min() > 0.19  # ... from one to the other
    # Without the fade (over no time), the feet jump the whole 20 cm in one frame: what is tested.
    monkeypatch.setattr(live_module, "GROUND_BLEND_S", 1e-9)
    sudden_live = LiveSynth(bank, 3, 60.0, seed=3, backend=backend, ground=low)
    sudden = _live_feet(bank, sudden_live, paths, (360, high))
    assert M.one_frame_jumps_mm(sudden[:, 150:]).max() > 150.0


@pytest.mark.parametrize("at", [0.05, 0.3, 0.5, 0.9])
def test_a_swing_rises_over_a_step_or_a_bump_no_higher_than_it_in_both_backends(at: float) -> None:
    """A 20 cm step, or a 20 cm bump 10 cm across, ``at`` of the way into a 1 m swing: the foot's
    ground (its clip height 0 here) stays on or over the terrain and is never higher than the
    terrain's top (the symmetric bump it replaced rose some 1.7 times a step near the swing's
    ends); the kernel compiled and interpreted alike."""
    z = np.concatenate([np.zeros(10), np.linspace(0.0, 1.0, 12)[1:-1], np.ones(10)])
    targets = np.zeros((1, 30, 4, 3))
    targets[0, :, :, 2] = z[:, None]
    contacts = np.zeros((1, 30, 4), bool)
    contacts[0, :10] = contacts[0, 20:] = True
    xs = np.arange(-1.0, 2.0, 0.01)
    for terrain in (np.where(xs > at, 0.2, 0.0), np.where(np.abs(xs - at) < 0.05, 0.2, 0.0)):
        field = HeightField.make(np.tile(terrain[:, None], (1, 3)), origin=(-0.01, -1.0), spacing=0.01)
        ys = []
        for run in (foot_kernels.ground_targets, getattr(foot_kernels.ground_targets, "py_func", None)):
            if run is None:  # numba not installed: the source is the function itself
                continue
            mine = targets[0].copy()  # the kernel writes in place
            run(mine, np.ascontiguousarray(contacts[0]), field.heights, field.origin[0], field.origin[1],
                field.spacing, 1.0, np.empty(30))
            ys.append(mine[:, 0, 1])
        y = ys[0]
        under = field.sample(targets[0, :, 0, 0], targets[0, :, 0, 2])
        assert np.all(y >= under - 1e-9) and y.max() <= 0.2 + 1e-9
        for other in ys[1:]:  # compiled and interpreted alike
            np.testing.assert_allclose(other, y, atol=1e-12)


@pytest.fixture(scope="module")
def dog_bank() -> Bank:
    return build_bank(build_builtin("dog"))


def test_the_dog_climbs_the_20cm_step_with_no_limb_flip(dog_bank: Bank) -> None:
    """Issue 33: the hind leg stretching back to its plant below the step sank the body while
    the other hind paw swung up onto it, and the IK folded that knee through its thigh (a knee
    flip, two frames). The sink now leaves every leg room to reach folded no further than the
    clips fold it (foot_kernels.fold_room), with no other figure of the scenario given up."""
    figures = edge_suite(dog_bank, names=["step_20cm"])["scenarios"]["step_20cm"]["figures"]
    assert figures["limb_flips"] == 0, figures["limb_flips_at"]
    for figure in TERRAIN_TARGETS:
        assert passes(figure, figures[figure]), (figure, figures[figure])
    assert figures["stretch_pct_max"] <= 3.0 and figures["jump_cm_max"] <= 6.0


def test_the_sink_leaves_a_folded_leg_room_and_a_stretched_one_its_reach() -> None:
    """fold_room on one frame: a swing target 0.1 below the hip with the leg folding to 0.25 at
    most lifts an eased sink of 0.3 to the room the fold leaves (0.1 - 0.25: the body up 0.15),
    but a planted leg whose target is 0.5 below the hip with a 0.55 reach holds it at -0.05."""
    legs = np.zeros((1, 4, foot_kernels.LEG_WIDTH))
    legs[0, :, foot_kernels.LEG_REACH] = 1.0
    legs[0, :, foot_kernels.LEG_THIGH] = 0.5
    bends = np.zeros((4, 5))
    bends[:, 3] = (0.25 ** 2 - 0.5) / 0.5  # folded to 0.25: 0.5^2 + 0.5^2 + 2 (0.5) (0.5) cos
    bends[:, 4] = 0.55  # the longest reach in the poses (below reach_sink's share of the leg's 1.0)
    targets = np.zeros((1, 4, 3))
    targets[0, :, 1] = -0.1  # every hip at the origin, its target right below it
    eased = np.array([0.3])
    foot_kernels.fold_room(targets, legs, bends, 1.0, 0, 1, eased, np.zeros(1))
    assert eased[0] == pytest.approx(0.1 - 0.25)
    targets[0, 0, 1] = -0.5  # one leg planted far below
    eased[0] = 0.3
    foot_kernels.fold_room(targets, legs, bends, 1.0, 0, 1, eased, np.zeros(1))
    assert eased[0] == pytest.approx(0.5 - 0.55)


@pytest.mark.parametrize("animal", ["horse", "dog"])
def test_the_body_rises_onto_the_step_without_a_jump(animal: str) -> None:
    """The room fold_room leaves a folded leg, and what it gives back where a leg would not
    reach, are eased in time as the sink is: applied frame by frame they moved the root 8-10 cm
    in one frame on the step (horse and dog) as a plant's target changed. The foot lock's
    vertical change of the root (the posed root against the plan's: the same character not
    posed) held to the issue's one-frame jump limit."""
    bank = build_bank(build_builtin(animal))
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    sc = edge.scenarios(gaits, bank.fps, 0, ["step_20cm"])[0]
    heights = [synthesize(bank, sc.positions, bank.fps, scales=sc.scales,
                          options=Options(seed=0, ground=sc.ground, posed=np.full(len(sc.positions), posed))
                          ).root_pos[..., 1].astype(np.float64) for posed in (True, False)]
    lock = heights[0] - heights[1]
    assert np.abs(np.diff(lock, axis=1)).max() * 100 <= 6.0
