"""The one evaluator (`punch eval --scenario`, docs/evaluation.md): scenarios are data, checked key by key before
Godot starts; `eval-moving` and `eval-sizes` are its scenarios `moving` and `sizes` with their flags; every punch
runs through PunchController in headless Godot (tools/evaluate.gd), one row per condition and sigma. `punch
eval`'s own scenario (held_out) is measured in test_naturalness.py and test_volume.py."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import PROJECT_ROOT
from punch_trainer.cli import main as cli_main
from punch_trainer.errors import GodotRunError, PunchError
from punch_trainer.learn.reach import ReachVolume
from punch_trainer.pipelines.evaluation import (
    EvalArgs,
    EvalError,
    draw_placements,
    episodes_of,
    parse_sizes,
    run_episodes,
    run_eval,
    scenario_of,
)
from punch_trainer.pipelines.scenario import ScenarioError, build_scenario, load_scenario, shipped_scenarios
from punch_trainer.policy_file import read_policy_metadata
from punch_trainer.sim.conditions import ARM_SCALE_RANGE, SCENE_ARM_LENGTHS_M
from punch_trainer.sim.godot import ADDON_POLICIES

POLICY = ADDON_POLICIES / "straight.onnx"
CASES = ["standing", "forward 0.7 m/s"]
REACH = ReachVolume((0.6, 0.85), (1.15, 1.55), (-0.25, 0.25), 1.0, True)


def punch(*arguments: str, timeout: int = 180) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "punch_trainer.cli.main", *arguments], capture_output=True, text=True,
                          timeout=timeout)


def test_the_shipped_scenarios_read_and_name_their_conditions_once_a_sigma():
    assert {"held_out", "moving", "sizes"} <= set(shipped_scenarios())
    held_out = load_scenario("held_out")
    assert held_out.success == "return" and held_out.volume == "spec" and held_out.placements == 64
    assert [(c.name, c.sigmas) for c in held_out.conditions] == [
        ("every decision", (0.0,)), ("every decision", (0.1, 0.3, 0.5)), ("first 4 decisions", (0.1, 0.3, 0.5)),
        ("bag swinging", (0.0,)), ("after a punch", (0.0,))]
    moving = load_scenario("moving")
    assert len(moving.conditions) == 29 and all(c.lead_s == 0.5 and c.moves() for c in moving.conditions)
    assert len({c.name for c in moving.conditions}) == 29
    sizes = load_scenario("sizes")
    assert [c.arms for c in sizes.conditions][:5] == [(s, s) for s in (0.75, 0.85, 1.0, 1.15, 1.25)]


def test_an_episode_plays_its_condition_with_the_seed_rule():
    """Episode e of sigma index s of a condition: placement e modulo their count, noise seed noise_seed *
    1000003 + s * 100003 + e; sigma 0 one punch per placement, above it `noisy_punches`; swinging twins keep the
    places of the placements at rest."""
    scenario = scenario_of(EvalArgs(policy=POLICY, placements=3, seed=5, sigmas=[0.0, 0.3]))
    still, swinging = draw_placements(scenario, REACH)
    assert [b.position_m().tolist() for b in still] == [b.position_m().tolist() for b in swinging]
    assert all(b.velocity_side_mps == 0 for b in still) and any(b.velocity_side_mps != 0 for b in swinging)
    episodes, groups = episodes_of(scenario, still, swinging)
    assert [(g.condition.name, g.sigma, g.count) for g in groups] == [
        ("every decision", 0.0, 3), ("every decision", 0.3, 6), ("first 4 decisions", 0.3, 6), ("bag swinging", 0.0, 3),
        ("after a punch", 0.0, 3)]
    first4 = episodes[groups[2].start:groups[2].start + 6]
    assert [e["seed"] for e in first4] == [1 * 1000003 + e for e in range(6)] and first4[0]["noise_decisions"] == 4
    assert episodes[groups[3].start]["placement"]["velocity_side_mps"] == swinging[0].velocity_side_mps
    assert episodes[groups[4].start]["start"] == "after_punch"
    moving = scenario_of(EvalArgs(policy=POLICY, scenario="moving", placements=2, sigmas=[0.0, 0.3], conditions=CASES))
    episodes, groups = episodes_of(moving, *draw_placements(moving, REACH))
    assert [e["seed"] for e in episodes[groups[1].start:groups[1].start + 2]] == [moving.seed * 1000003 + 100003 + p for p in (0, 1)]
    assert episodes[groups[2].start]["body"]["velocity_mps"] == [0.0, 0.0, 0.7]


def test_a_lead_hands_move_from_the_stance_punches_at_the_placements_moved_forward():
    """The stance's lead-hand conditions (a jab, in either stance) play each placement `lead_forward_m` further ahead,
    the lead hand's volume, and a combination from there with a lead hand's move where both hands reach; the rear
    hand's, and every condition away from the stance's guard, play it as drawn."""
    scenario = scenario_of(EvalArgs(policy=POLICY, scenario="stance", placements=4, sigmas=[0.0]))
    still, swinging = draw_placements(scenario, REACH)
    episodes, groups = episodes_of(scenario, still, swinging, 0.1)
    for group in groups:
        distances = [e["placement"]["distance_m"] for e in episodes[group.start:group.start + group.count]]
        moved = 0.1 if group.condition.move == "jab" else 0.0
        assert distances == pytest.approx([b.distance_m + moved for b in still]), group.condition.name
    assert {g.condition.move for g in groups} == {"jab", "cross"}
    square = build_scenario({"conditions": [{"name": "jab", "move": "jab"}]}, "inline")
    episodes, _ = episodes_of(square, still, swinging, 0.1)
    assert [e["placement"]["distance_m"] for e in episodes] == [b.distance_m for b in still]
    # A combination from the stance with a lead hand's move: at the distances both hands reach, 0.70-0.85 m, in order.
    combos = build_scenario({"success": "hit", "conditions": [
        {"name": "1-2", "combo": ["jab", "cross"], "stance_pose": True, "sigmas": [0.0]},
        {"name": "2-4", "combo": ["cross", "rear_hook"], "stance_pose": True, "sigmas": [0.0]}]}, "inline")
    many = REACH.sample(np.random.default_rng(0), 64)
    episodes, groups = episodes_of(combos, many, [], 0.1, REACH.distance_m)
    both = [e["placement"]["distance_m"] for e in episodes[:64]]
    assert min(both) >= 0.7 and max(both) <= 0.85 and sorted(range(64), key=both.__getitem__) == sorted(
        range(64), key=lambda i: many[i].distance_m)
    assert [e["placement"]["distance_m"] for e in episodes[64:]] == [b.distance_m for b in many]


def test_a_move_whose_reach_is_nearer_than_its_hands_is_measured_over_its_own_distances():
    """A hook trained over 0.70-0.85 m (its reach nearer than the lead hand's 0.70-0.95) plays the lead hand's
    placements drawn into its own distances, in order; a policy whose reach is its hand's, or lies outside it (a
    square guard's policy thrown by the lead hand), plays them as before, and so does a combination."""
    scenario = scenario_of(EvalArgs(policy=POLICY, scenario="stance", placements=64, sigmas=[0.0]))
    still, swinging = draw_placements(scenario, REACH)
    episodes, groups = episodes_of(scenario, still, swinging, 0.1, REACH.distance_m, (0.70, 0.85))
    for group in groups:
        distances = [e["placement"]["distance_m"] for e in episodes[group.start:group.start + group.count]]
        if group.condition.move == "jab":
            assert min(distances) >= 0.70 and max(distances) <= 0.85, group.condition.name
            assert sorted(range(64), key=distances.__getitem__) == sorted(range(64), key=lambda i: still[i].distance_m)
        else:  # the rear hand's 0.60-0.85 holds 0.70-0.85 too
            assert distances == pytest.approx([0.70 + (b.distance_m - 0.60) * 0.6 for b in still]), group.condition.name
    for own in [(0.60, 0.85), (0.70, 0.95), None]:
        as_before, _ = episodes_of(scenario, still, swinging, 0.1, REACH.distance_m, own)
        plain, _ = episodes_of(scenario, still, swinging, 0.1, REACH.distance_m)
        assert as_before == plain, own


def test_a_punch_from_recovery_draws_its_delay_from_its_own_seed_within_the_band():
    """`from_recovery`: every episode its own cancel delay, the same for the same seed, spread over the band; the
    arms not sent back to guard first and the bag hung again for the second punch."""
    scenario = scenario_of(EvalArgs(policy=POLICY, scenario="from_recovery", placements=64, conditions=["jab, then cross"]))
    episodes, _ = episodes_of(scenario, *draw_placements(scenario, REACH))
    delays = [e["cancel_delay_s"] for e in episodes]
    assert all(0.0 <= d <= 0.6 for d in delays) and max(delays) - min(delays) > 0.4 and len(set(delays)) > 60
    assert all(e["guard_first"] is False and e["reset_target"] and e["until_recovered"] for e in episodes)
    again, _ = episodes_of(scenario, *draw_placements(scenario, REACH))
    assert [e["cancel_delay_s"] for e in again] == delays


def test_scales_and_proportions_make_the_sizes_conditions_in_order():
    scenario = scenario_of(EvalArgs(policy=POLICY, scenario="sizes", scales=[0.75, 1.0, 1.25], proportions=[(0.7, 0.85)]))
    assert [(c.name, c.arms) for c in scenario.conditions] == [
        ("0.75", (0.75, 0.75)), ("1", (1.0, 1.0)), ("1.25", (1.25, 1.25)), ("0.7x0.85", (0.7, 0.85))]
    only_proportions = scenario_of(EvalArgs(policy=POLICY, scenario="sizes", proportions=[(0.85, 0.7)]))
    assert [c.name for c in only_proportions.conditions] == ["0.75", "0.85", "1", "1.15", "1.25", "0.85x0.7"]


@pytest.mark.parametrize(("data", "message"), [
    ({"conditions": [{"name": "a", "sigma": [0.0]}]}, "unknown key\\(s\\) 'sigma'"),
    ({"condition": []}, "unknown key\\(s\\) 'condition'"),
    ({"conditions": []}, "no \\[\\[conditions\\]\\]"),
    ({"conditions": [{"name": "a", "body": {}, "target": {"velocity_mps": [1.0, 0.0, 0.0]}}]}, "one of them at a time"),
    ({"conditions": [{"name": "a", "body": {"speed": 1.0}}]}, "unknown key\\(s\\) 'speed'"),
    ({"conditions": [{"name": "a", "arms": 0.5}]}, "arm scale 0.5 is outside the range PunchCharacter.size_arms accepts"),
    ({"conditions": [{"name": "a", "sigmas": [1.5]}]}, "must be a finite number, at least 0 and at most 1"),
    ({"conditions": [{"name": "a"}, {"name": "a"}]}, "two conditions named 'a' at sigma 0"),
    ({"success": "hits", "conditions": [{"name": "a"}]}, "success is \"hit\" or \"return\""),
    ({"placements": {"count": 0}, "conditions": [{"name": "a"}]}, "placements.count 0"),
    ({"placements": {"side_m": [0.1, -0.1]}, "conditions": [{"name": "a"}]}, "placements.side_m \\[0.1, -0.1\\] runs downward"),
    ({"conditions": [{"name": "a", "combo": ["jab", "haymaker"]}]}, "combo is a list of moves"),
    ({"conditions": [{"name": "a", "combo": ["jab"], "move": "cross"}]}, "a move or a combo, not both"),
    ({"success": "return", "conditions": [{"name": "a", "combo": ["jab"]}]}, "a combo's, a struck character's or a defender's success is \"hit\""),
    ({"success": "return", "conditions": [{"name": "a", "move": "jab", "defender": {}}]}, "a defender's success is \"hit\""),
    ({"conditions": [{"name": "a", "defender": {"blocks": "yes"}}]}, "defender.blocks: true or false"),
    ({"conditions": [{"name": "a", "defender": {"dodges": True}}]}, "unknown key\\(s\\) 'dodges'"),
    ({"conditions": [{"name": "a", "defender": {"part": "legs"}}]}, "defender.part: \"head\" or \"torso\""),
    ({"conditions": [{"name": "a", "defender": {"head_up_m": 0.5}}]}, "defender.head_up_m: metres from -0.04 to 0.11"),
    ({"conditions": [{"name": "a", "defender": {"turned_deg": 120}}]}, "defender.turned_deg: degrees from -90 to 90"),
    ({"conditions": [{"name": "a", "defender": {"motion": {"velocity_mps": [0.7]}}}]}, "defender.motion.velocity_mps: three numbers"),
    ({"conditions": [{"name": "a", "defender": {"motion": {"sway": 1.0}}}]}, "unknown key\\(s\\) 'sway'"),
    ({"conditions": [{"name": "a", "combo": ["jab"], "defender": {}}]}, "a defender stands in the bag's place"),
    ({"placements": {"distance_m": [0.9, 0.7]}, "conditions": [{"name": "a"}]}, "placements.distance_m \\[0.9, 0.7\\] runs downward"),
    ({"conditions": [{"name": "a", "cancel_delay_s": [0.0, 0.5]}]}, "cancel_delay_s delays a combo's next punch; it needs a combo"),
    ({"conditions": [{"name": "a", "combo": ["jab"], "cancel_delay_s": [0.5, 0.1]}]}, "the lower delay first"),
    ({"conditions": [{"name": "a", "combo": ["jab"], "cancel_delay_s": [0.0, 3.0]}]}, "at most 2"),
    ({"conditions": [{"name": "a", "reset_target": True}]}, "true only with a combo"),
    ({"conditions": [{"name": "a", "guard_first": "no"}]}, "guard_first is true or false"),
    ({"conditions": [{"name": "a", "struck": {"part": "tail", "impulse_ns": 30}}]}, "part is one of head, torso"),
    ({"conditions": [{"name": "a", "struck": {"impulse_ns": 3000}}]}, "at most 1000"),
    ({"conditions": [{"name": "a", "struck": {"impulse_ns": 30, "from": "above"}}]}, "from is one of front, back"),
    ({"conditions": [{"name": "a", "struck": {"part": "head"}}]}, "needs impulse_ns"),
    ({"conditions": [{"name": "a", "move": "jab", "struck": {"impulse_ns": 30}}]}, "a struck character holds its guard"),
])
def test_a_scenario_that_cannot_be_played_is_refused_with_its_reason(data, message):
    with pytest.raises(ScenarioError, match=message):
        build_scenario(data, "mine.toml")


def test_unknown_scenarios_and_conditions_are_refused_naming_what_there_is(tmp_path):
    with pytest.raises(ScenarioError, match="no scenario named 'nope'; the shipped ones are blocks, blocks_hooks, blocks_uppercuts, body, combos, frame_data, from_recovery, hands, held_out, hits, moving, sizes, stance, stance_moving"):
        scenario_of(EvalArgs(policy=POLICY, scenario="nope"))
    with pytest.raises(ScenarioError, match="unknown condition\\(s\\) 'moonwalk'; the scenario's are: standing"):
        scenario_of(EvalArgs(policy=POLICY, scenario="moving", conditions=["moonwalk"]))
    broken = tmp_path / "broken.toml"
    broken.write_text("name = \n")
    with pytest.raises(ScenarioError, match="not TOML"):
        scenario_of(EvalArgs(policy=POLICY, scenario=str(broken)))


@pytest.mark.parametrize("scales", ["0.5", "1,1.3", "nan"])
def test_an_arm_scale_outside_the_range_is_one_clear_error_before_godot(capsys, scales):
    assert cli_main.main(["eval-sizes", "--policy", str(POLICY), "--scales", scales]) == 1
    err = capsys.readouterr().err
    assert err.startswith("punch: arm scale ") and err.count("\n") == 1, err
    assert "outside the range PunchCharacter.size_arms accepts: 0.75 to 1.25 times" in err, err


def test_proportions_a_rig_may_not_have_are_one_clear_error_before_godot(capsys):
    with pytest.raises(ScenarioError, match=r"proportions 0\.65x0\.7 are outside .* the arm 0\.75 to 1\.25 times"):
        scenario_of(EvalArgs(policy=POLICY, scenario="sizes", proportions=[(0.65, 0.7)]))
    with pytest.raises(EvalError, match=r"bad --proportions '0\.7-0\.8'"):
        parse_sizes("0.7-0.8")
    assert cli_main.main(["eval-moving", "--policy", str(POLICY), "--arms", "0.6"]) == 1
    assert "arm scale 0.6 is outside the range PunchCharacter.size_arms accepts" in capsys.readouterr().err


def test_scales_that_are_no_numbers_are_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exit_:
        cli_main.main(["eval-sizes", "--policy", str(POLICY), "--scales", "0.8,big"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "bad --scales '0.8,big'" in err.strip().splitlines()[-1], err


@pytest.mark.godot
def test_eval_sizes_reports_every_scale_and_sigma_with_the_lengths_godot_sized(tmp_path):
    run = punch("eval-sizes", "--policy", str(POLICY), "--scales", "0.75,1.0,1.25", "--proportions", "0.7x0.85",
                "--sigmas", "0,0.3", "--placements", "4", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr[-3000:]
    report = json.loads((tmp_path / "eval.json").read_text())
    assert report["scenario"]["name"] == "sizes" and len(report["placements"]) == 4
    assert report["arm_scale_range"] == list(ARM_SCALE_RANGE)  # Godot's own, as PunchCharacter reports it
    rows = report["evaluations"][0]["rows"]
    assert [(r["condition"], r["sigma"]) for r in rows] == [(s, sigma) for s in ("0.75", "1", "1.25", "0.7x0.85") for sigma in (0.0, 0.3)]
    for row in rows:
        upper, forearm = (float(v) for v in (row["condition"].split("x") * 2)[:2])
        # Upper arm and forearm times their scales, the shoulders as they are, as Godot measures them sized.
        assert row["arm_lengths_m"] == pytest.approx([upper * SCENE_ARM_LENGTHS_M[0], forearm * SCENE_ARM_LENGTHS_M[1],
                                                      SCENE_ARM_LENGTHS_M[2]], abs=0.002), row
        assert row["punches"] == 4 and 0 <= row["successes"] <= 4, row
        # Shorter arms reach less far: the controller says so of some targets (docs/env.md); the body's or longer never.
        assert row["out_of_reach"] == 0 if row["condition"] in ("1", "1.25") else row["out_of_reach"] <= 4, row
        assert row["success_interval"][0] <= row["success_rate"] <= row["success_interval"][1]
    assert rows[2]["successes"] >= 3, rows[2]  # the shipped straight at its own arms hits most of them
    assert "| 1 | 0.00 | 4 |" in run.stdout and "0.197 / 0.286 / 0.360" in run.stdout, run.stdout


@pytest.mark.godot
def test_eval_moving_reports_every_case_and_the_standing_punches_hit(tmp_path):
    run = punch("eval-moving", "--policy", str(POLICY), "--placements", "2", "--sigmas", "0", "--cases", *CASES,
                "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr[-3000:]
    report = json.loads((tmp_path / "eval.json").read_text())
    assert len(report["placements"]) == 2 and report["scenario"]["conditions"][1]["lead_s"] == 0.5
    standing, walking = report["evaluations"][0]["rows"]
    assert (standing["condition"], walking["condition"]) == tuple(CASES)
    assert standing["successes"] == 2 and standing["moved_m"] == 0.0, standing
    # Walking for the 0.5 s lead (`--lead-s`), then the 50 frames of a punch at 120 Hz (and the few frames a
    # character walked out of its guard takes to return to it first: `guard_first`).
    assert 0.7 * (0.5 + 50 / 120) - 0.02 <= walking["moved_m"] <= 0.7 * (0.5 + 0.2 + 50 / 120)
    assert "| standing | 0.00 | 2 | 2 (100.0%) |" in (tmp_path / "report.md").read_text()


@pytest.mark.godot
def test_eval_moving_sizes_the_arms_it_is_given(tmp_path):
    """`--arms UxF`: every character's arms sized through size_arms (short ones here), as a rig would size them;
    the straight still lands from standing. Of the two placements, the first (0.73 m ahead) is well within these
    arms' reach; the second is the reach volume's far corner, where these arms land some punches and not others."""
    run = punch("eval-moving", "--policy", str(POLICY), "--placements", "2", "--sigmas", "0", "--cases", *CASES,
                "--arms", "0.8x0.75", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr[-3000:]
    report = json.loads((tmp_path / "eval.json").read_text())
    standing = report["evaluations"][0]["rows"][0]
    assert standing["arms"] == "0.8x0.75" and 0 not in standing["missed_placements"], standing
    assert standing["arm_lengths_m"][0] == pytest.approx(0.8 * SCENE_ARM_LENGTHS_M[0], abs=0.002)


@pytest.mark.godot
def test_a_scenario_file_of_ones_own_runs_a_new_condition(tmp_path):
    """docs/evaluation.md's example, as the doc gives it: a file, not a harness: after an earlier punch while
    walking, and against a target swinging, through the same driver (on 2 placements at sigma 0 here)."""
    doc = (PROJECT_ROOT / "docs" / "evaluation.md").read_text()
    example = doc.split("# after_walking.toml\n")[1].split("```")[0]
    scenario = tmp_path / "after_walking.toml"
    scenario.write_text(example)
    run = punch("eval", "--policy", str(POLICY), "--scenario", str(scenario), "--placements", "2", "--sigmas", "0",
                "--out", str(tmp_path / "out"))
    assert run.returncode == 0, run.stderr[-3000:]
    rows = json.loads((tmp_path / "out" / "eval.json").read_text())["evaluations"][0]["rows"]
    assert [(r["condition"], r["punches"]) for r in rows] == [("after a punch, walking", 2), ("swinging", 2)]
    assert rows[0]["moved_m"] > 0.3, rows[0]
    assert rows[1]["moved_m"] == 0.0, rows[1]  # the bag swings; its hook, the node a target motion moves, stays


@pytest.mark.godot
def test_a_character_struck_while_it_walks_reacts_as_one_standing(tmp_path):
    """A `struck` condition with a `body` motion: the character walks 0.5 s, is struck at the head from the side, and
    the figures are read in its own frame: it went on walking and turned as far as standing (a constant walk carries
    the kinematic pelvis and every body with it)."""
    scenario = tmp_path / "walking_hit.toml"
    scenario.write_text('name = "walking_hit"\ndescription = "struck walking"\nsuccess = "hit"\nsigmas = [0.0]\n'
                        '[placements]\ncount = 2\nvolume = "spec"\n'
                        '[[conditions]]\nname = "standing"\nstruck = { impulse_ns = 60.0, part = "head", from = "right" }\n'
                        '[[conditions]]\nname = "walking"\nstruck = { impulse_ns = 60.0, part = "head", from = "right" }\n'
                        'body = { velocity_mps = [0.0, 0.0, 0.7] }\nlead_s = 0.5\n')
    run = punch("eval", "--policy", str(POLICY), "--scenario", str(scenario), "--out", str(tmp_path / "out"))
    assert run.returncode == 0, run.stderr[-3000:]
    standing, walking = json.loads((tmp_path / "out" / "eval.json").read_text())["evaluations"][0]["rows"]
    assert standing["successes"] == walking["successes"] == 2 and standing["moved_m"] == 0.0
    assert walking["moved_m"] > 0.4, walking
    assert walking["struck"]["peak_turn_deg"] == pytest.approx(standing["struck"]["peak_turn_deg"], rel=0.15), (standing, walking)


@pytest.mark.godot
def test_godot_refuses_a_scale_outside_the_range_with_its_reason_and_does_not_crash(tmp_path):
    """The check in Godot itself (a caller of `run_episodes` past the scenario's check): size_arms's error names the
    range, the driver stops with exit code 2, not a crash."""
    with pytest.raises(GodotRunError, match="exit code 2") as error:
        run_episodes(POLICY, [{"seed": 0, "arms": [0.5, 0.5]}], tmp_path, timeout_s=60)
    assert "outside 0.75..1.25" in error.value.log, error.value.log
    assert "error: evaluate: PunchCharacter.size_arms refused the arm scale 0.5" in error.value.log, error.value.log


@pytest.mark.godot
def test_a_godot_past_its_deadline_is_stopped_with_the_commands_error(tmp_path):
    with pytest.raises(EvalError, match="the punches did not finish within 0 s"):
        run_episodes(POLICY, [{"seed": 0}], tmp_path, timeout_s=0.01)


def test_a_policy_whose_file_is_missing_is_refused_before_godot(tmp_path):
    with pytest.raises(PunchError, match="policy file not found"):
        run_eval(EvalArgs(policy=tmp_path / "missing.onnx", scenario="sizes"), progress=False)
    assert read_policy_metadata(POLICY).physics_hz == 120
    assert Path(POLICY).is_file()


@pytest.mark.godot
def test_an_evaluation_writes_its_table_into_the_results_file_with_its_command(tmp_path, monkeypatch, capsys):
    """`--benchmarks SECTION`: the figures the docs link to are the evaluator's own output, never copied by hand; a
    second run replaces its section."""
    from punch_trainer.pipelines import bench

    results = tmp_path / "BENCHMARKS.md"
    results.write_text("# Benchmarks\n\nkept\n")
    monkeypatch.setattr(bench, "BENCHMARKS_FILE", results)
    arguments = ["eval-moving", "--policy", str(POLICY), "--placements", "2", "--sigmas", "0", "--cases", "standing",
                 "--out", str(tmp_path / "out"), "--benchmarks", "Standing, two placements"]
    for _ in range(2):
        assert cli_main.main(arguments) == 0
    text = results.read_text()
    assert text.count("## Standing, two placements") == 1 and "kept" in text
    assert f"Command: `punch {' '.join(arguments[:-1])} 'Standing, two placements'`" in text
    assert "| standing | 0.00 | 2 |" in text and "![" not in text
    capsys.readouterr()
