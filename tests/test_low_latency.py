"""The low-latency live mode (issue 31): poses within the latency budget, counted in frames of
lag between the last point received and the last pose sent; feet planted after FK; the causal
fits it smooths with."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from api_schemas import LiveRequest, models
from synth_core.motion.contacts import runs
from synth_core.quality import evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.quality.live_run import play
from synth_core.quality.reference import library_reference
from synth_core.runtime import causal, gaussian, live
from synth_core.runtime.bank import Bank
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.live_shards import LiveShards
from synth_core.runtime.trajectory import TrajectoryError
from tests.helpers.motion import plant_stands


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(10, 600, seed=21)


@pytest.mark.parametrize("latency_ms", [50.0, 150.0, 400.0])
def test_poses_lag_their_points_by_the_budget_at_most(bank: Bank, herd: np.ndarray,
                                                      latency_ms: float) -> None:
    run = play(bank, herd, latency_ms=latency_ms, points_per_tick=3)
    budget = int(latency_ms * bank.fps / 1000)
    assert run.latency_frames == budget
    assert run.lags.max() <= budget  # never later than the budget, a tick after another
    assert run.lags[len(run.lags) // 2:].min() >= budget - 3  # and no frame held back for nothing
    assert LiveSynth(bank, 2, bank.fps).latency_frames > 5 * budget  # the exact mode: seconds late


def test_points_at_30_fps_come_back_within_the_budget(bank: Bank) -> None:
    herd = crowd.simulate(4, 300, seed=5, fps=30.0)
    synth = LiveSynth(bank, 4, 30.0, latency_ms=150.0)
    lags = []
    for i in range(herd.shape[1]):  # a point a tick: a 30 fps simulator
        synth.append(herd[:, i:i + 1])
        lags.append(2 * i + 1 - synth.rendered)  # library frames: the last point received is 2 i
    assert max(lags) <= synth.latency_frames == 9
    assert synth.finish() is not None and synth.rendered == 2 * herd.shape[1] - 1


def test_feet_stay_planted_after_fk(bank: Bank, herd: np.ndarray) -> None:
    run = play(bank, herd, seed=2, latency_ms=150.0)
    figures = evaluate.edge_figures(bank, run.result, herd, herd.shape[1], library_reference(bank))
    assert figures["strict_skate_mm_p95"] <= 5.0  # issue 31's targets
    assert figures["glide_ratio"] <= 0.12
    assert figures["nan_count"] == 0
    assert len(set(run.result.gait.ravel().tolist())) >= 4  # it moved through the gaits


def test_a_steady_run_plants_its_feet_on_the_ground_live(bank: Bank) -> None:
    """Where its contacts say planted, a hoof stands on the ground (issue 33's 5 mm, p95): plants
    taken from their first frames and lowered to a quartile of them as a batch's are
    (footlock.LIFTED_PLANT) hovered 7 mm in every straight run."""
    from synth_core.build.motion_graph import HUBS
    from synth_core.quality import edge

    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    (sc,) = edge.scenarios(gaits, bank.fps, 0, ["cruise_straight"])
    run = play(bank, sc.positions, sc.scales, latency_ms=100.0)
    ref = library_reference(bank)
    fk = evaluate.feet_after_fk(bank, run.result, ref)
    ground = evaluate.ground_figures(bank, run.result, fk, None, ref)
    assert evaluate.passes("planted_ground_mm_p95", ground["planted_ground_mm_p95"]), ground


def test_a_budget_out_of_range_is_refused_naming_it(bank: Bank) -> None:
    with pytest.raises(TrajectoryError, match=r"latency_ms: must be within \[50, 2000\] ms"):
        LiveSynth(bank, 2, 60.0, latency_ms=10.0)
    with pytest.raises(TrajectoryError, match="latency_ms"):
        LiveSynth(bank, 2, 60.0, latency_ms=float("nan"))
    assert (models.LATENCY_MS, models.LOW_LATENCY_MS) == (live.LATENCY_MS, live.LOW_LATENCY_MS)


def test_the_live_request_names_the_field_and_its_limits() -> None:
    chars = [{"id": "a"}]
    with pytest.raises(ValidationError, match="latency_ms"):
        LiveRequest.model_validate({"characters": chars, "latency_ms": 20})
    with pytest.raises(ValidationError, match="latency_ms\n  Value error, only with mode low_latency"):
        LiveRequest.model_validate({"characters": chars, "mode": "exact", "latency_ms": 200})
    with pytest.raises(ValidationError, match="mode"):
        LiveRequest.model_validate({"characters": chars, "mode": "fast"})
    assert LiveRequest.model_validate({"characters": chars}).budget_ms is None
    assert LiveRequest.model_validate({"characters": chars, "mode": "low_latency"}).budget_ms == 100.0
    assert LiveRequest.model_validate({"characters": chars, "latency_ms": 80}).budget_ms == 80.0


def test_the_fit_follows_a_steady_path_without_lag() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(80.0)
    steady = np.stack([0.25 * t + 3, np.zeros_like(t), -0.1 * t], axis=-1)[None]
    for behind, ahead in ((16, 0), (16, 4), (24, 2)):
        value, slope = causal.fit_weights(4.0, behind, ahead)
        got = causal.apply(steady, value, behind, 30, 40)
        np.testing.assert_allclose(got, steady[:, 30:70], atol=1e-9)  # no lag on a straight line
        np.testing.assert_allclose(causal.apply(steady, slope, behind, 30, 40)[0],
                                   np.broadcast_to([0.25, 0.0, -0.1], (40, 3)), atol=1e-9)
        noisy = steady + rng.normal(0, 0.05, steady.shape)
        assert np.std(causal.apply(noisy, value, behind, 30, 40) - steady[:, 30:70]) < 0.05  # noise averaged
    # Read symmetrically, the fit's value is the Gaussian the batch smooths with.
    value, _ = causal.fit_weights(4.0, 16, 16)
    kernel = gaussian.weights(4.0)
    np.testing.assert_allclose(value, np.concatenate([kernel[:0:-1], kernel]), atol=1e-12)


def _targets(feet: np.ndarray, contacts: np.ndarray, most: int, compiled: bool = True,
             pins: np.ndarray | None = None, pinned: np.ndarray | None = None, last: int = -1,
             air: np.ndarray | None = None) -> np.ndarray:
    """foot_kernels.plant_targets of one character (compiled, or its source interpreted); none
    pinned unless ``pins``, ``pinned`` (written: the plants ``last`` is in, if >= 0); ``air``
    (written, if given): the feet up as the targets have them."""
    from synth_core.compiled import foot_kernels
    run = foot_kernels.plant_targets if compiled else getattr(foot_kernels.plant_targets, "py_func",
                                                              foot_kernels.plant_targets)
    out = np.empty(feet.shape)
    pins = np.zeros((4, 3)) if pins is None else pins
    pinned = np.full(4, foot_kernels.NOWHERE) if pinned is None else pinned
    # Every frame counted as sent before: the plants and swings alone, no jump eased on any
    # (jump_kernels.ease_unsent: tests/test_stitch_jumps.py for ease_jumps).
    body = (*foot_kernels.no_steps(len(feet))[:-2], len(feet), (np.zeros((2, 4, 3)), foot_kernels.NOWHERE))
    up = run(feet, np.ascontiguousarray(feet[..., 1]), contacts, out, most, pins, pinned, last, body)
    if air is not None:
        air[:] = up
    return out


def test_a_plants_target_can_average_its_first_frames_only() -> None:
    rng = np.random.default_rng(3)
    feet = rng.normal(size=(40, 4, 3))
    contacts = rng.random((40, 4)) < 0.7
    for most in (1, 3, 1000):
        air = np.empty(contacts.shape, np.bool_)
        got = _targets(feet, contacts, most, air=air)
        np.testing.assert_allclose(_targets(feet, contacts, most, compiled=False), got, atol=1e-12)
        for f in range(4):  # each plant where its first `most` frames stand
            for i, (start, stop) in enumerate(runs(contacts[:, f])):
                want = plant_stands(feet[start:min(stop, start + most), f], whole=most >= len(feet))
                # (over the ground, a plant after a swing too short to ease its lift-off correction
                # out keeps the rest where most < all: swing_kernels.swings)
                axes = [0, 1, 2] if i == 0 or most >= len(feet) else [1]
                held = np.all(np.abs(got[start:stop, f][:, axes] - want[axes]) <= 1e-12, axis=1)
                if most < len(feet):
                    assert held.all()
                    continue
                # A batch's swing too short for its distance takes frames off its plants' ends,
                # into the air (jump_kernels.widen_swings): the rest holds the plant.
                where = np.flatnonzero(held)
                assert where.size and where[-1] - where[0] + 1 == where.size
                assert np.all(air[start:stop, f][~held])
    # A plant's target is its first frame's foot with most=1: what frames after it hold changes nothing.
    later = feet.copy()
    later[1:] += 1.0
    first = contacts[0] & contacts[1]
    np.testing.assert_allclose(_targets(later, contacts, 1)[1][first], feet[0][first], atol=1e-12)


def test_a_pinned_plant_stays_where_it_was_sent_over_the_ground() -> None:
    """plant_targets' pins: the plant through a pinned frame keeps the pin's place over the ground
    (its height its frames' here) whatever its frames average; each foot's last plant up to
    ``last`` is pinned anew -- the one it is in, or the one before its swing."""
    from synth_core.compiled.foot_kernels import NOWHERE
    rng = np.random.default_rng(5)
    feet = rng.normal(size=(30, 4, 3))
    contacts = np.zeros((30, 4), bool)
    contacts[0:12, 0] = contacts[20:30, 0] = True  # foot 0: a plant cut by the context's start, swing, plant
    contacts[5:25, 1] = True  # foot 1: a plant whose first frames are here
    pins = np.arange(12.0).reshape(4, 3) + 100.0
    pinned = np.array([3, NOWHERE, NOWHERE, NOWHERE])
    for compiled in (True, False):
        p, q = pins.copy(), pinned.copy()
        got = _targets(feet, contacts, 3, compiled, p, q, last=15)
        np.testing.assert_allclose(got[0:12, 0, [0, 2]], np.broadcast_to(pins[0, [0, 2]], (12, 2)))
        np.testing.assert_allclose(got[0:12, 0, 1], feet[0:3, 0, 1].mean())  # its height: its frames'
        np.testing.assert_allclose(got[5:25, 1], np.broadcast_to(feet[5:8, 1].mean(axis=0), (20, 3)))
        # The swing after the pinned plant eases out the lift-off correction from the pin (over
        # half its plant's length, no step's length given: swing_kernels._eased), the touchdown
        # one in over the swing.
        y, x = (12 - 11) / (12 // 2), (12 - 11) / (20 - 11)
        y, x = y * y * (3 - 2 * y), x * x * (3 - 2 * x)
        lift, touch = pins[0] - feet[11, 0], feet[20:23, 0].mean(axis=0) - feet[20, 0]
        np.testing.assert_allclose(got[12, 0, [0, 2]], (feet[12, 0] + (1 - y) * lift + x * touch)[[0, 2]])
        # Frame 15: foot 0 swings after its plant [0, 12), foot 1 stands in [5, 25), 2 and 3 never planted.
        np.testing.assert_array_equal(q, [11, 15, NOWHERE, NOWHERE])
        np.testing.assert_allclose(p[:2], got[[11, 15], [0, 1]])
        np.testing.assert_array_equal(p[2:], pins[2:])
    # None pinned, none asked for: the plants' averages, as without pins.
    plain = _targets(feet, contacts, 3)
    np.testing.assert_allclose(plain[0:12, 0], np.broadcast_to(feet[0:3, 0].mean(axis=0), (12, 3)))


def test_a_swing_eases_out_a_held_plants_correction_before_its_next_plant_is_planned() -> None:
    """The low-latency mode plans a plant a few frames before it sends it, and pins each plant at
    its first frames: a plant the body carried off (turning on the spot over it: 1 m here) leaves
    its swing that correction to ease out. Eased over a guess at the swing that a standing
    plant's length made a second long, the swing still carried most of it when its next plant
    came, and let go of it in one frame (horse turn_on_spot: 95 cm). Played window by window as
    a live session sends it, no frame of the foot moves more than issue 27's one-frame jump
    (6 cm) beyond the steps either side of it."""
    from synth_core.compiled import foot_kernels
    from synth_core.quality import metrics as M
    from synth_core.runtime.footlock import STEP_S

    T, lag = 130, 3  # a frame is sent once the 3 after it are planned (100 ms at 60 fps)
    feet = np.zeros((T, 4, 3))
    feet[:, :, 2] = [0.6, -0.6, 0.6, -0.6]
    feet[:, :, 0] = [1.2, 1.2, -1.2, -1.2]
    contacts = np.ones((T, 4), bool)
    contacts[70:90, 0] = False  # foot 0: a 70-frame plant, a 20-frame swing, a plant
    feet[:70, 0, 0] = np.linspace(0.0, 1.0, 70)  # carried 1 m off by the body over its plant
    swing = np.linspace(0.0, 1.0, 22)[1:-1]
    feet[70:90, 0, 0] = 1.0 + 0.6 * swing
    feet[70:90, 0, 1] = 0.12 * np.sin(np.pi * swing)
    feet[90:, 0, 0] = 1.6
    body = list(foot_kernels.no_steps(T))
    body[0] = np.zeros((4, 6))
    body[0][:, 4], body[0][:, 5] = 1.0, round(STEP_S * 60)
    pins, pinned = np.zeros((4, 3)), np.full(4, foot_kernels.NOWHERE)
    sent = np.empty((T - lag, 4, 3))
    kept = np.zeros((2, 4, 3))  # the targets of the last two frames sent (kernels.Posed's sent)
    for k in range(T - lag):  # each window: the frames planned so far, the last one sent pinned
        out = np.empty((k + lag + 1, 4, 3))
        body[-2:] = k, (kept, k - 1)  # frame k sent now, those before it by earlier windows
        seen = feet[:k + lag + 1]
        soles = np.ascontiguousarray(seen[..., 1])  # the clips stand each foot where it is
        foot_kernels.plant_targets(seen, soles, contacts[:k + lag + 1], out, 3, pins, pinned, k, tuple(body))
        sent[k] = out[k]
    assert np.abs(sent[90:, 0, 0] - 1.6).max() < 1e-9  # the next plant where the clip sets it down
    assert M.one_frame_jumps_mm(sent[:, :1]).max() <= 60.0


def test_a_plant_longer_than_the_frames_kept_stays_planted(bank: Bank) -> None:
    """A creeping horse (0.05-0.4 m/s: the edge suite's creep) stands on plants longer than the
    frames a live session keeps for its foot lock. Re-averaged over the frames still kept, each
    such plant followed its foot in the clip as they were dropped (glide 0.176); its place as sent
    is kept instead. Issue 31's targets, after FK on the frames sent."""
    from synth_core.build.motion_graph import HUBS
    from synth_core.quality import edge

    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    (sc,) = edge.scenarios(gaits, bank.fps, 0, ["creep"])
    run = play(bank, sc.positions, sc.scales, latency_ms=100.0)
    figures = evaluate.edge_figures(bank, run.result, sc.reference, sc.positions.shape[1],
                                    library_reference(bank))
    assert figures["glide_ratio"] <= 0.12
    assert figures["strict_skate_mm_p95"] <= 5.0


@pytest.mark.parametrize("name", ["jitter_10hz", "turn_on_spot"])
def test_a_standing_body_turning_keeps_its_feet_planted(bank: Bank, name: str) -> None:
    """A body turning as it stands (turn_on_spot; jitter_10hz at its start, its heading following
    the 10 Hz noise) over plants that run on past the last frame planned. The batch steps a
    plant the turn carries out of reach (replant_kernels); each one-frame window split it anew
    where it was cut, and the feet of frames sent were dragged with the body, then let go (strict
    skate p95 77 mm, glide 0.23). A live session holds each plant whole, as sent. Issue 31's
    targets, after FK on the frames sent."""
    from synth_core.build.motion_graph import HUBS
    from synth_core.quality import edge

    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    (sc,) = edge.scenarios(gaits, bank.fps, 0, [name])
    run = play(bank, sc.positions, sc.scales, latency_ms=100.0)
    figures = evaluate.edge_figures(bank, run.result, sc.reference, sc.positions.shape[1],
                                    library_reference(bank), sent=sc.positions)
    assert figures["glide_ratio"] <= 0.12
    assert figures["strict_skate_mm_p95"] <= 5.0


def test_shards_make_the_low_latency_sessions_frames(bank: Bank, herd: np.ndarray) -> None:
    whole = LiveSynth(bank, len(herd), 60.0, seed=4, latency_ms=100.0)
    shards = LiveShards(bank, len(herd), 60.0, seed=4, shards=3, latency_ms=100.0)
    assert shards.latency_frames == whole.latency_frames
    for i in range(0, 300, 7):
        a, b = whole.append(herd[:, i:i + 7]), shards.append(herd[:, i:i + 7])
        assert (a is None) == (b is None)
        if a is not None and b is not None:
            joined = np.concatenate([w.root_pos for w in b])
            np.testing.assert_array_equal(joined, a.root_pos)
            np.testing.assert_array_equal(np.concatenate([w.gait for w in b]), a.gait)


def test_a_path_moving_at_its_first_points_starts_in_its_gait_live(bank: Bank) -> None:
    """The low-latency mode's head behind the first points is their line (it was the first point
    held: a path moving at once was planned from standing, its plants left out of reach -- the
    horse's hooves jumped 21 cm, a walk with one hoof down). The first frame reads the points its
    budget waits for anyway. Issue 27's targets after FK on the frames sent (the dog meets them
    all; the horse its walk support and flips); a path standing at first still starts standing."""
    from synth_core.build.library_store import builtin_library
    from synth_core.build.motion_graph import HUBS
    from synth_core.quality import edge
    from synth_core.runtime.bank import build_bank

    dog = build_bank(builtin_library("dog"))
    for animal, judged in ((dog, ("glide_ratio", "jump_cm_max", "walk_support_share", "limb_flips")),
                           (bank, ("walk_support_share", "limb_flips"))):
        gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in animal.speeds.items()}
        (sc,) = edge.scenarios(gaits, animal.fps, 0, ["moving_start"])
        run = play(animal, sc.positions, sc.scales, latency_ms=100.0)
        assert run.result.gait[:, 0].tolist() == [1, 2, 3, 4]  # walk, trot, canter, gallop at once
        figures = evaluate.edge_figures(animal, run.result, sc.reference, sc.positions.shape[1],
                                        library_reference(animal), sent=sc.positions)
        for name in judged:
            assert evaluate.passes(name, figures[name]), (name, figures[name])
        (standing,) = edge.scenarios(gaits, animal.fps, 0, ["cruise_straight"])
        still = play(animal, standing.positions[:, :120], standing.scales, latency_ms=100.0)
        assert (still.result.gait[:, 0] == 0).all()
