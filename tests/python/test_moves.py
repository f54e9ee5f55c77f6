"""The moves a game throws by name (`punch(&"jab")`), with the hand its stance gives: a left-hand punch is its
policy played mirrored, and lands at the mirror image of where the right hand's does, as fast."""

import itertools
import json

import pytest

from punch_trainer.sim.godot import GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot

LEAD_MOVES = {"jab", "lead_hook", "lead_uppercut"}
SIX_MOVES = ["jab", "cross", "lead_hook", "rear_hook", "lead_uppercut", "rear_uppercut"]


def run_moves_scene():
    script = PROJECT_ROOT / "tests" / "godot" / "moves_scene.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script)],
                    check=False, timeout_s=120)
    line = next((line for line in run.log.splitlines() if line.startswith("MOVES_SCENE ")), None)
    assert line is not None and run.fatal_lines() == [], run.log[-3000:]
    return run, json.loads(line[len("MOVES_SCENE "):])


def test_each_move_is_thrown_by_its_stances_hand_and_lands_on_its_side():
    run, report = run_moves_scene()
    orthodox, southpaw = 0, 1
    by_throw = {}
    for throw in report["throws"]:
        lead_is_left = throw["stance"] == orthodox
        hand = "left" if lead_is_left == (throw["move"] in LEAD_MOVES) else "right"
        assert throw["started"] == [[throw["move"], hand]], throw
        (finished,) = throw["finished"]
        assert (finished["move"], finished["hand"], finished["ended"]) == (throw["move"], hand, "completed"), finished
        bag_hits = [hit for hit in throw["hits"] if hit["bag"]]
        assert bag_hits and bag_hits[0]["hand"] == hand, throw
        # The fist lands on its own side of the centre line, where its bag is. From the stance's guard the lead fist
        # guards the centre line itself (docs/moves.md), and its punches land on it, within 3 cm.
        side = bag_hits[0]["x"] * (1 if hand == "left" else -1)
        assert side > (-0.03 if throw["stance_pose"] and throw["move"] in LEAD_MOVES else 0.0), throw
        by_throw[(throw["stance_pose"], throw["stance"], throw["move"])] = {**finished, "speed_at_hit": bag_hits[0]["speed"],
                                                                           "side_m": side}
    assert len(by_throw) == 2 * 2 * len(SIX_MOVES), "each move in each stance, from the square and the stance's guard"
    # The other stance throws each move with the other hand: the same policy mirrored, at the mirrored bag, lands
    # as fast and as hard (the physics is not bit-symmetric: Jolt solves the right arm's joints first; docs/env.md,
    # "Mirror"; after the contact the two part more, so the figures are the hit's). From the stance's guard the two
    # stances' guards are mirror images too, but each punch first turns the trunk there from the square guard
    # (`guard_first`), and the two turns part a little more: within 15% (the jab measured 8.5% apart).
    for stance_pose, move in itertools.product((False, True), SIX_MOVES):
        apart = 0.15 if stance_pose else 0.01
        left_handed, right_handed = by_throw[(stance_pose, orthodox, move)], by_throw[(stance_pose, southpaw, move)]
        if move in LEAD_MOVES:
            assert left_handed["hand"] == "left"
        else:
            left_handed, right_handed = right_handed, left_handed
        assert left_handed["speed_at_hit"] == pytest.approx(right_handed["speed_at_hit"], rel=apart), (stance_pose, move)
        assert left_handed["strongest_hit_ns"] == pytest.approx(right_handed["strongest_hit_ns"], rel=5 * apart), (stance_pose, move)
        assert left_handed["hits"] == right_handed["hits"] >= 1, (stance_pose, move)
        assert left_handed["side_m"] == pytest.approx(right_handed["side_m"], abs=0.03), (stance_pose, move)


def test_a_move_with_no_policy_or_no_name_is_refused_naming_it():
    run, report = run_moves_scene()
    assert report["refused"] == {"haymaker": False, "cross_from_own_moveset": False}
    assert "no move named 'haymaker' (the moves: jab, cross, lead_hook, rear_hook, lead_uppercut, rear_uppercut)" in run.log
    assert "has no policy for 'cross'" in run.log
    assert report["moves_of_own_moveset"] == ["jab"]
    # A move's reach (the left hand's mirrored; the shipped policies' side ranges are symmetric, so it looks alike).
    assert set(report["reach_of_jab"]) >= {"distance_m", "height_m", "side_m"} and report["reach_of_haymaker"] == {}
    # With no moveset set, `stance_pose` plays the addon's stance moveset: its lead hook covers the near part of the
    # lead hand's volume, 0.10 m further ahead than the square guard's hook (a hook is a close punch: 0.70-0.80 m).
    square, stance = report["lead_hook_distance_m"], report["lead_hook_in_stance_distance_m"]
    assert stance[0] == pytest.approx(square[0] + 0.1, abs=1e-4) and stance[1] < square[1] + 0.1, (square, stance)
    assert stance == pytest.approx([0.70, 0.80], abs=1e-4)
    assert report["moves_of_addon_moveset"] == ["jab", "cross", "lead_hook", "rear_hook", "lead_uppercut", "rear_uppercut"]


def test_the_evaluator_throws_a_policy_with_either_hand(tmp_path):
    """The `hands` scenario: the left hand, at the mirror images of the right hand's held-out placements, lands as the
    right does, and its punches are measured in its own frame (the return and the naturalness work unchanged)."""
    from punch_trainer.pipelines.evaluation import EvalArgs, run_eval

    args = EvalArgs(policy=PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "straight.onnx", scenario="hands",
                    placements=6, sigmas=[0.0], out=tmp_path)
    _, report = run_eval(args, progress=False)
    rows = {row["condition"]: row for row in report["evaluations"][0]["rows"]}
    right, left = rows["right hand (orthodox)"], rows["left hand (southpaw)"]
    assert right["successes"] == left["successes"] == 6, rows
    assert left["impact_spread_m"] == pytest.approx(right["impact_spread_m"], abs=0.01)


def test_a_scenario_with_a_stance_that_is_none_is_refused():
    from punch_trainer.pipelines.scenario import ScenarioError, build_scenario

    with pytest.raises(ScenarioError, match="stance is \"orthodox\" or \"southpaw\""):
        build_scenario({"conditions": [{"name": "x", "move": "jab", "stance": "boxer"}]}, "inline")


def test_the_demo_throws_every_move_in_both_stances_at_its_bag():
    """The demo (godot_project/demo/demo.tscn) as a newcomer plays it: keys 1-6 in each stance (the stance picked in
    its picker), the bag nudged right, then the swing from the move picker. Every move of the moveset is thrown in
    both stances with its stance's hand and hits the bag, which hangs on that hand's side; a key whose move has no
    policy throws nothing and says so, with no error in the log."""
    script = PROJECT_ROOT / "tests" / "godot" / "demo_moves.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script)],
                    check=False, timeout_s=120)
    line = next((line for line in run.log.splitlines() if line.startswith("DEMO_MOVES ")), None)
    assert line is not None and run.fatal_lines() == [] and "ERROR" not in run.log, run.log[-3000:]
    report = json.loads(line[len("DEMO_MOVES "):])
    moveset = report["moveset"]
    assert {"jab", "cross", "lead_hook", "rear_hook"} <= set(moveset), report["moveset"]
    labels = {move: f"{number} {move.replace('_', ' ')}" for number, move in enumerate(SIX_MOVES, 1)}
    assert report["items"] == [labels[move] for move in moveset] + ["swing (policy)"], report["items"]
    assert report["stances"] == ["orthodox (left leads)", "southpaw (right leads)"]
    thrown, nudges = set(), 0
    for throw in report["throws"]:
        orthodox = throw["stance"] == 0
        nudges += throw["action"] == "key Right"
        key_move = SIX_MOVES[int(throw["action"][-1]) - 1] if throw["action"][-1].isdigit() else None
        if key_move is not None and key_move not in moveset:
            assert throw["started"] == [] and throw["label"] == f"{labels[key_move]}: no policy for it in the moveset yet"
            continue
        ((move, hand),) = throw["started"]
        if key_move is not None:
            assert move == key_move, throw
        expected = "right" if move == "" else ("left" if orthodox == (move in LEAD_MOVES) else "right")
        assert hand == expected and [(f["move"], f["hand"], f["ended"]) for f in throw["finished"]] == \
            [(move, hand, "completed")], throw
        bag_hits = [hit for hit in throw["hits"] if hit["bag"]]
        assert bag_hits and all(hit["hand"] == hand for hit in bag_hits), throw
        name = labels.get(move, "swing")
        assert throw["label"] == f"{name}, {hand} hand: hit the bag ({hand} fist)", throw
        if nudges == 2:  # the bag nudged 10 cm right, then mirrored onto the side of each punch's hand
            assert throw["bag_x"] == pytest.approx(0.10 if hand == "left" else -0.10, abs=1e-3), throw
        thrown.add((throw["stance"], move))
    assert thrown == {(stance, move) for stance in (0, 1) for move in moveset} | {(1, "")}, thrown
    throws = sum(1 for throw in report["throws"] if throw["started"])
    assert report["hit_rate_label"] == f"hit rate: {throws} of {throws} (100%)"


def test_from_the_stances_guard_the_character_turns_and_still_lands(tmp_path):
    """`stance_pose`: each punch first returns to the stance's guard (the trunk turned 30°, recorded as the first
    frame's waist rotation, mirrored for the left hand into the policy's frame), then lands."""
    import numpy as np

    from punch_trainer.pipelines.evaluation import EvalArgs, recorded, run_episodes, run_eval
    from punch_trainer.pipelines.scenario import load_scenario

    args = EvalArgs(policy=PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "straight.onnx", scenario="stance",
                    placements=4, sigmas=[0.0], out=tmp_path)
    _, report = run_eval(args, progress=False)
    for row in report["evaluations"][0]["rows"]:
        assert row["successes"] >= 3, row
    scenario = load_scenario("stance")
    assert all(condition.stance_pose for condition in scenario.conditions)
    # The first recorded frame of an orthodox cross (the right hand, unmirrored) has the trunk turned right.
    meta = run_episodes(args.policy, [{"seed": 0, "move": "cross", "stance": "orthodox", "stance_pose": True}],
                        tmp_path / "one", record=True)
    features = recorded(tmp_path / "one", meta, "features")
    waist = features[0, 0, meta["feature_names"].index("angle_waist_rotation")]
    assert np.degrees(waist) == pytest.approx(-30.0, abs=3.0), np.degrees(waist)


def test_a_character_stands_in_its_stance_before_it_punches():
    """`stance_pose` set before the controller is ready: the character turns into the stance's guard without a punch
    and without a `recovered` (a game's `recovered` handlers wait for punches); setting `stance` or `stance_pose` while
    it is idle turns it into the other stance's guard, then back to the square guard."""
    script = PROJECT_ROOT / "tests" / "godot" / "stance_at_rest.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script)],
                    check=False, timeout_s=60)
    line = next((line for line in run.log.splitlines() if line.startswith("STANCE_AT_REST ")), None)
    assert line is not None and run.fatal_lines() == [], run.log[-3000:]
    report = json.loads(line[len("STANCE_AT_REST "):])
    orthodox, southpaw, square = report["turn_deg"]
    # The orthodox guard turns the trunk 30° to the right (the left shoulder forward); the southpaw's to the left.
    assert orthodox == pytest.approx(-30.0, abs=5.0) and southpaw == pytest.approx(30.0, abs=5.0), report
    assert square == pytest.approx(0.0, abs=3.0), report
    assert report["signals"] == [], report


def test_training_starts_in_the_guard_the_game_stands_in():
    """The training server's `stance_guard_actions`: a lead-in holding the orthodox guard leaves the character as
    `stance_pose` holds it in the game (trunk turned 30° right, the lead elbow opened, the lead fist nearer the target),
    before an episode and before a search's rollout alike (a chunk of 3 rollouts on 2 characters: padded); the southpaw's is its mirror."""
    import numpy as np

    from punch_trainer.learn.volume import STANCE_LEAD_IN_DECISIONS
    from punch_trainer.sim.conditions import EpisodeStart
    from punch_trainer.sim.env import PunchVectorEnv

    with PunchVectorEnv(1, 3, frames=50) as env:
        guards = env.info.stance_guard_actions
        assert np.allclose(env.info.mirror.actions(np.array(guards["orthodox"])), guards["southpaw"])
        lead_in = np.zeros((3, STANCE_LEAD_IN_DECISIONS, env.info.action_size), dtype=np.float32)
        lead_in[1], lead_in[2] = guards["orthodox"], guards["southpaw"]
        env.reset(options=EpisodeStart([env.info.default_bag] * 3, lead_in))
        *_, info = env.step(np.zeros((3, env.info.action_size), dtype=np.float32))
    names = env.feature_names
    waist = np.degrees(info["features"][:, 0, names.index("angle_waist_rotation")])
    lead_elbow = np.degrees(info["features"][:, 0, [names.index("angle_elbow_l_extension"), names.index("angle_elbow_r_extension")]])
    assert waist[0] == pytest.approx(0.0, abs=1.0) and waist[1] == pytest.approx(-30.0, abs=2.0), waist
    assert waist[2] == pytest.approx(30.0, abs=2.0), waist
    assert lead_elbow[1, 0] > 10.0 and lead_elbow[2, 1] > 10.0 and abs(lead_elbow[1, 1]) < 2.0, lead_elbow
    # The lead fist stands as much nearer the target as the handshake's `stance_lead_forward_m` says (the lead hand's
    # reach volume is the square one moved that far forward): the southpaw's right fist against the square guard's.
    fist_z = info["features"][:, 0, names.index("fist_r_pos_z")]
    assert fist_z[2] - fist_z[0] == pytest.approx(env.info.stance_lead_forward_m, abs=0.02), fist_z
    # The trajectory search's open-loop rollouts start there too, after the same lead-in.
    from punch_trainer.sim.rollouts import RolloutPool

    with RolloutPool(1, 2) as pool:
        features, _ = pool.run(np.zeros((3, 4, pool.info.action_size), dtype=np.float32), lead_in=lead_in)
        with pytest.raises(ValueError, match="lead-in of shape"):
            pool.run(np.zeros((3, 4, pool.info.action_size), dtype=np.float32), lead_in=lead_in[:2])
    rolled = np.degrees(features[:, 0, names.index("angle_waist_rotation")])
    assert rolled == pytest.approx(waist, abs=1.0), (rolled, waist)


def test_a_policy_trained_from_a_load_starts_there_in_the_game_as_in_training(tmp_path):
    """A policy file that says `punch_start_load`: the controller draws the punching arm from the stance's guard into
    that load before the policy's first decision, with `guard_first` off too, for either hand (the left mirrored into
    the policy's frame), to the pose a training lead-in of the server's `loaded_guard_actions` leaves the body in."""
    import numpy as np
    import onnx

    from punch_trainer.learn.volume import STANCE_LEAD_IN_DECISIONS
    from punch_trainer.pipelines.evaluation import recorded, run_episodes
    from punch_trainer.sim.conditions import EpisodeStart
    from punch_trainer.sim.env import PunchVectorEnv

    model = onnx.load(str(PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "lead_hook.onnx"))
    for entry in list(model.metadata_props):
        if entry.key == "punch_start_load":
            model.metadata_props.remove(entry)
    model.metadata_props.add(key="punch_start_load", value="uppercut")
    loaded = tmp_path / "loaded.onnx"
    onnx.save(model, str(loaded))
    episodes = [{"seed": 0, "move": "lead_uppercut", "stance": "orthodox", "stance_pose": True},
                {"seed": 1, "move": "lead_uppercut", "stance": "southpaw", "stance_pose": True, "guard_first": False}]
    meta = run_episodes(loaded, episodes, tmp_path / "game", record=True)
    game = recorded(tmp_path / "game", meta, "features")[:, 0]
    names = meta["feature_names"]
    with PunchVectorEnv(1, 1, frames=50) as env:
        lead_in = np.tile(np.asarray(env.info.loaded_guard_actions["southpaw"]["uppercut"], dtype=np.float32),
                          (1, STANCE_LEAD_IN_DECISIONS, 1))
        env.reset(options=EpisodeStart([env.info.default_bag], lead_in))
        *_, info = env.step(np.zeros((1, env.info.action_size), dtype=np.float32))
    trained = info["features"][0, 0]
    for joint in ("angle_waist_rotation", "angle_waist_flexion", "angle_shoulder_r_flexion", "angle_elbow_r_extension"):
        column = names.index(joint)
        # The policy starts within the move's tolerance of its load (the lead hand's 0.1 rad: 6°), not settled.
        assert np.degrees(np.abs(game[:, column] - trained[column])).max() < 9.0, (joint, game[:, column], trained[column])
    # The uppercut's load drops the lead fist (to the chest) from the guard it is drawn from.
    assert np.degrees(trained[names.index("angle_shoulder_r_flexion")]) > 30.0


def test_body_shots_are_drawn_in_the_body_band(tmp_path):
    """`placements.height_m`: the body scenario's targets lie 1.00-1.20 m high (below most of the volume); a band
    that runs downward or is not two numbers is refused."""
    from punch_trainer.pipelines.evaluation import EvalArgs, run_eval
    from punch_trainer.pipelines.scenario import ScenarioError, build_scenario

    args = EvalArgs(policy=PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "straight.onnx", scenario="body",
                    placements=4, sigmas=[0.0], out=tmp_path)
    _, report = run_eval(args, progress=False)
    heights = [placement["height_m"] for placement in report["placements"]]
    assert len(heights) == 4 and all(1.0 <= h <= 1.2 for h in heights), heights
    assert len(report["evaluations"][0]["rows"]) == 4
    for band, message in (([1.2, 1.0], "runs downward"), ([1.0], r"\[low, high\]"), ("1.0", r"\[low, high\]")):
        with pytest.raises(ScenarioError, match=message):
            build_scenario({"placements": {"height_m": band}, "conditions": [{"name": "x"}]}, "inline")
