"""The edge scenario suite (issue 27): its paths do what they say, and a run measures every figure.

The issue's targets are not asserted here: today's motion misses many of them (the suite is the
measurement; behaviour work follows in other branches)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from quadsynth.cli import main
from synth_core.quality import edge, evaluate
from synth_core.quality.reference import library_reference
from synth_core.runtime.bank import Bank

FPS = 60.0
HORSE = {"walk": (0.56, 1.51), "trot": (1.36, 3.24), "canter": (2.6, 5.62), "gallop": (4.75, 10.26)}


def scenario(name: str, seed: int = 0, gaits: dict[str, tuple[float, float]] = HORSE) -> edge.Scenario:
    return edge.scenarios(gaits, FPS, seed, [name])[0]


def ground_speed(positions: np.ndarray) -> np.ndarray:
    """(C, F-1) m/s."""
    return np.linalg.norm(np.diff(positions[..., [0, 2]], axis=1), axis=-1) * FPS


def circle_radius(points: np.ndarray) -> float:
    """Least-squares circle through ``points (n, 2)``: x^2 + y^2 = 2 a x + 2 b y + c."""
    A = np.column_stack([2 * points, np.ones(len(points))])
    a, b, c = np.linalg.lstsq(A, (points**2).sum(axis=1), rcond=None)[0]
    return float(np.sqrt(c + a * a + b * b))


def test_every_scenario_is_a_small_finite_herd_on_the_ground_and_seeded() -> None:
    suite = edge.scenarios(HORSE, FPS, seed=3)
    assert [s.name for s in suite] == list(edge.MAKERS)
    for s in suite:
        C, F, _ = s.positions.shape
        assert 2 <= C <= 5 and 300 <= F <= 1200, (s.name, C, F)  # a 5 m U-turn at a walk: 19 s
        assert s.positions.dtype == np.float32 and np.isfinite(s.positions).all()
        # On the ground: flat at 0, or on the scenario's terrain (as a crowd simulator sends it).
        ground = 0.0 if s.ground is None else s.ground.sample(s.positions[..., 0], s.positions[..., 2])
        assert np.allclose(s.positions[..., 1], ground, atol=1e-5) and s.scales.shape == (C,)
        assert s.reference.shape == s.positions.shape
    again = edge.scenarios(HORSE, FPS, seed=3)
    other = edge.scenarios(HORSE, FPS, seed=4)
    assert all(np.array_equal(a.positions, b.positions) for a, b in zip(suite, again, strict=True))
    jitter = [s.name for s in suite].index("jitter_10hz")
    assert not np.array_equal(suite[jitter].positions, other[jitter].positions)  # jitter draws its noise
    with pytest.raises(ValueError, match="unknown"):
        edge.scenarios(HORSE, FPS, names=["moonwalk"])


def test_a_library_without_a_gait_gets_no_corners_at_its_speed() -> None:
    names = [s.name for s in edge.scenarios({k: v for k, v in HORSE.items() if k != "gallop"}, FPS)]
    assert "corner_gallop" not in names and "uturn_gallop" not in names and "corner_canter" in names


def test_a_stop_really_stops_and_stands() -> None:
    s = scenario("stop_and_stand")
    speed = ground_speed(s.positions)
    assert speed.max() > edge.cruise(HORSE, "canter") * 0.99  # it did run
    assert np.all(speed[:, -int(2.5 * FPS):] == 0)  # then stood still for the last 2.5 s
    assert np.diff(speed, axis=1).min() * FPS > -edge.BRAKE - 0.1  # braking at 3 m/s^2


def test_the_baseline_cruises_straight_at_each_gaits_speed() -> None:
    s = scenario("cruise_straight")
    assert ground_speed(s.positions)[:, -1] == pytest.approx([edge.cruise(HORSE, g) for g in HORSE], rel=1e-3)
    assert np.ptp(s.positions[..., 0], axis=1) == pytest.approx(0.0, abs=1e-6)  # straight along +Z


def test_stop_go_pauses_last_what_it_says() -> None:
    s = scenario("stop_go")
    still = ground_speed(s.positions) == 0
    moved = np.cumsum(~still, axis=1) > 0  # after the first move
    pauses = (still & moved).sum(axis=1) / FPS
    assert pauses[0] == pytest.approx(0.3, abs=0.05) and pauses[2] == pytest.approx(3.0, abs=0.05)
    assert 0.3 < pauses[1] < 3.0
    assert np.all(ground_speed(s.positions)[:, -1] > 0)  # and went again


def test_a_creep_keeps_its_speed_in_range() -> None:
    speed = ground_speed(scenario("creep").positions)[:, -int(FPS):]  # the last second
    low, high = edge.CREEP_RANGE
    assert np.all(speed >= low - 1e-3) and np.all(speed <= high + 1e-3)
    assert speed.mean(axis=1) == pytest.approx(edge.CREEP_SPEEDS, abs=1e-3)
    assert min(edge.CREEP_SPEEDS) == low and max(edge.CREEP_SPEEDS) == high


@pytest.mark.parametrize(("name", "degrees"), [("corner_trot", 90), ("uturn_canter", 180)])
def test_corners_and_u_turns_have_the_stated_radius_and_angle(name: str, degrees: int) -> None:
    s = scenario(name)
    for c, radius in enumerate(edge.RADII):
        xz = s.positions[c][:, [0, 2]].astype(np.float64)
        step = np.diff(xz, axis=0)
        heading = np.unwrap(np.arctan2(step[:, 0], step[:, 1]))
        assert abs(heading[-1] - heading[0]) == pytest.approx(np.radians(degrees), abs=0.02)
        turning = np.abs(np.gradient(heading)) > 1e-4
        assert circle_radius(xz[1:][turning]) == pytest.approx(radius, rel=0.03)
        assert np.all(ground_speed(s.positions[c:c + 1])[0, turning] == pytest.approx(
            edge.cruise(HORSE, name.split("_")[1]), rel=1e-3))  # at the gait's speed


def test_small_circles_and_the_jitter_hold_their_ticks() -> None:
    circles = scenario("small_circles")
    for c, radius in enumerate((1.0, 2.0, 3.0)):
        assert circle_radius(circles.positions[c, -120:][:, [0, 2]].astype(np.float64)) == pytest.approx(
            radius, rel=0.02)
    jitter = scenario("jitter_10hz")
    hold = int(FPS / edge.JITTER_HZ)
    ticks = jitter.positions.reshape(jitter.positions.shape[0], -1, hold, 3)
    assert np.all(ticks == ticks[:, :, :1])  # sample and hold
    noise = (jitter.positions - jitter.reference)[:, ::hold][..., [0, 2]]  # at each tick
    assert 0.5 * edge.JITTER_M < noise.std() < 2 * edge.JITTER_M


def test_one_character_too_fast_and_sizes_mixed() -> None:
    fast = ground_speed(scenario("too_fast").positions).max(axis=1)
    assert fast[-1] == pytest.approx(edge.TOO_FAST * HORSE["gallop"][1], rel=1e-3)
    assert np.all(fast[:-1] <= HORSE["canter"][1])
    sizes = scenario("mixed_sizes")
    assert sizes.scales.min() == 0.5 and sizes.scales.max() == 2.0


def test_a_suite_run_on_the_horse_has_every_figure_finite(bank: Bank) -> None:
    out = evaluate.edge_suite(bank, names=["stop_and_stand", "corner_trot"])
    assert set(out["scenarios"]) == {"stop_and_stand", "corner_trot"}
    for entry in out["scenarios"].values():
        figures = entry["figures"]
        for name in evaluate.EDGE_TARGETS:
            assert figures[name] is not None and np.isfinite(figures[name]), name
        for name in ("touchdown_mm_max", "yaw_deg_s_p95", "path_cm_mean", "strict_skate_mm_mean"):
            assert np.isfinite(figures[name]), name
        assert figures["nan_count"] == 0 and figures["clock_kept"] == 1
        assert entry["failed"] == [f for f in evaluate.EDGE_TARGETS
                                   if not evaluate.passes(f, figures[f])]
        assert entry["pass"] == {f: f not in entry["failed"] for f in evaluate.EDGE_TARGETS}
    for name, target in out["targets"].items():
        assert out["worst"][name]["target"] == target
    assert out["worst"]["yaw_deg_s_max"]["scenario"] == "corner_trot"  # the standing stop never turns


def test_eval_suite_edge_writes_json_a_table_and_the_worst_moment(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--suite", "edge", "--animal", "dog", "--scenario", "creep", "--scenario",
                 "too_fast", "--json", "--out", str(tmp_path)]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert set(printed["scenarios"]) == {"creep", "too_fast"}
    assert printed["scenarios"]["too_fast"]["figures"]["clock_kept"] == 1  # the caller's clock kept (default)
    assert "clock_kept" not in printed["scenarios"]["too_fast"]["failed"]
    assert json.loads((tmp_path / "edge.json").read_text()) == printed
    assert "| too_fast |" in (tmp_path / "edge.md").read_text()
    assert (tmp_path / "edge_worst_dog.png").stat().st_size > 10_000


def test_eval_refuses_edge_options_without_the_edge_suite_and_unknown_scenarios(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--scenario", "creep"]) == 2
    assert "--scenario and --out: only with --suite edge" in capsys.readouterr().err
    assert main(["eval", "--live", "low_latency"]) == 2
    assert "--live: only with --suite edge" in capsys.readouterr().err
    assert main(["eval", "--suite", "edge", "--latency-ms", "100"]) == 2
    assert "--latency-ms: only with --live low_latency" in capsys.readouterr().err
    assert main(["eval", "--suite", "edge", "--live", "exact", "--velocity"]) == 2
    assert "--velocity: only with --live low_latency" in capsys.readouterr().err
    assert main(["eval", "--suite", "edge", "--animal", "dog", "--scenario", "moonwalk"]) == 2
    assert "scenario: unknown ['moonwalk']" in capsys.readouterr().err


def test_the_worst_scenario_is_ranked_over_terrain_misses_too() -> None:
    """A suite with terrain scenarios ranks them by their terrain targets' misses as well (the
    whole edge suite's report picked its worst moment and crashed on a terrain figure)."""
    flat_figure, (_, flat_limit) = next(iter(evaluate.EDGE_TARGETS.items()))
    ground_figure, (_, ground_limit) = next(iter(evaluate.TERRAIN_TARGETS.items()))
    suite = {"scenarios": {
        "flat": {"beyond_target": {flat_figure: abs(flat_limit) or 1.0}, "failed": [flat_figure]},
        "hill": {"beyond_target": {ground_figure: 3 * (abs(ground_limit) or 1.0)}, "failed": [ground_figure]},
    }}
    assert evaluate.worst_scenario(suite) == "hill"


def test_a_big_dogs_steady_canter_carries_it_no_longer_alone_than_its_tempo_gives() -> None:
    """Issue 27: no foot alone past its gait's longest stance. A dog twice the library's size at
    the same Froude number (the canter's middle speed x sqrt(2)) plays the library's own canter
    at 1 / sqrt(2) of its tempo (synthesis' default), so each stance lasts sqrt(2) times the
    library's frames; held to the library's 9 frames, its own steady canter read 1.1."""
    from synth_core.build.library_store import builtin_library
    from synth_core.runtime.bank import build_bank
    from synth_core.runtime.synthesis import Options, synthesize

    bank = build_bank(builtin_library("dog"))
    low, high = (float(bank.speeds[3][0]), float(bank.speeds[3][-1]))  # the canter's clips
    v = 0.5 * (low + high) * np.sqrt(2.0)
    F = edge.frames_for(0.5 + v / edge.SPEED_UP + 6.0, FPS)
    sc = edge.herd([edge.run(F, FPS, edge.start_at(v))], [2.0])
    result = synthesize(bank, sc.positions, FPS, scales=sc.scales, options=Options(seed=0))
    figures = evaluate.edge_figures(bank, result, sc.reference, F, library_reference(bank))
    assert figures["gait_frames"]["canter"] > 4 * 60  # it does canter, seconds of it
    assert figures["single_support_ratio_max"] <= 1.0


def test_a_path_moving_at_frame_0_starts_in_its_gait_not_from_standing() -> None:
    """An agent spawned at speed: each character plays its speed's gait from frame 0 (standing,
    it shuffled through every transition up to it while its body glided: the dog's glide 0.137,
    a paw jump 8.8 cm), and the dog then meets the issue's glide, jump and support targets
    after FK. A path standing at frame 0 still starts standing."""
    from synth_core.build.library_store import builtin_library
    from synth_core.runtime.bank import build_bank
    from synth_core.runtime.synthesis import Options, synthesize

    bank = build_bank(builtin_library("dog"))
    gaits = {g: (float(bank.speeds[h][0]), float(bank.speeds[h][-1]))
             for h, g in enumerate(("static", "walk", "trot", "canter", "gallop")) if h}
    sc = edge.scenarios(gaits, FPS, 0, ["moving_start"])[0]
    result = synthesize(bank, sc.positions, FPS, scales=sc.scales, options=Options(seed=0))
    assert result.gait[:, 0].tolist() == [1, 2, 3, 4]  # walk, trot, canter, gallop at once
    F = sc.positions.shape[1]
    figures = evaluate.edge_figures(bank, result, sc.reference, F, library_reference(bank))
    for name in ("glide_ratio", "jump_cm_max", "walk_support_share", "limb_flips"):
        assert evaluate.passes(name, figures[name]), (name, figures[name])
    standing = edge.scenarios(gaits, FPS, 0, ["cruise_straight"])[0]
    still = synthesize(bank, standing.positions[:, :120], FPS, scales=standing.scales,
                       options=Options(seed=0))
    assert (still.gait[:, 0] == 0).all()
