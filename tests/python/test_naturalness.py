"""The naturalness figures (docs/naturalness.md) on made-up punches with known answers, on the motion capture
(shipped with the trainer, punch_trainer/data), and through the real `punch eval` on a shipped policy."""

import json
import math

import numpy as np
import pytest

from conftest import PROJECT_ROOT
from punch_trainer.capture.bvh import DEFAULT_BVH
from punch_trainer.capture.punches import captured_punches, speeds_from_positions
from punch_trainer.report.naturalness import (
    FIGURES,
    in_proximal_to_distal_order,
    largest_distance_from_chord,
    largest_distance_from_start,
    naturalness_table,
    path_over_chord,
    punch_naturalness,
    summarise,
)

HZ = 120.0
NAMES = [f"{stem}_{axis}" for stem in ("fist_r_pos", "fist_r_vel", "fist_l_pos", "fist_l_vel", "fist_r_impulse", "bag_pos") for axis in "xyz"]
NAMES += ["fist_r_bag_distance"]
NAMES += [f"angle_{dof}" for dof in ("waist_flexion", "waist_rotation", "shoulder_r_flexion", "shoulder_r_rotation", "shoulder_r_abduction",
                                     "elbow_r_extension", "shoulder_l_flexion", "shoulder_l_rotation", "shoulder_l_abduction", "elbow_l_extension")]
NAMES += [name.replace("angle_", "speed_") for name in NAMES if name.startswith("angle_")]


def made_up_punch(frames=40, contact=20, fist_speed=5.0, peaks=(5, 8, 12)):
    """A right fist driven straight ahead at `fist_speed` until it touches at frame `contact`; the left fist
    drifts 10 cm sideways by the contact and 30 cm by the end; the waist bends on to 0.2 rad at the end; waist rotation,
    shoulder and elbow speeds peak at the frames `peaks`."""
    f = np.zeros((frames, len(NAMES)))
    col = NAMES.index
    t = np.arange(frames)
    f[:, col("fist_r_pos_z")] = 0.3 + fist_speed * t / HZ
    f[:, col("fist_r_pos_y")] = 1.5
    f[:, col("fist_r_vel_z")] = fist_speed
    f[:, col("fist_r_bag_distance")] = np.abs(0.8 - f[:, col("fist_r_pos_z")])
    f[contact, col("fist_r_impulse_z")] = 1.0
    f[:, col("bag_pos_y")], f[:, col("bag_pos_z")] = 1.5, 0.8
    drift = np.where(t <= contact, 0.1 * t / contact, 0.1 + 0.2 * (t - contact) / (frames - 1 - contact))
    f[:, col("fist_l_pos_x")] = 0.18 + drift
    f[:, col("fist_l_vel_x")] = np.where(t <= contact, 0.1 * HZ / contact, 0.2 * HZ / (frames - 1 - contact))
    f[:, col("angle_waist_flexion")] = 0.2 * np.sin(0.5 * np.pi * t / (frames - 1))
    for name, peak in zip(("speed_waist_rotation", "speed_shoulder_r_flexion", "speed_elbow_r_extension"), peaks, strict=True):
        f[:, col(name)] = np.exp(-((t - peak) / 2.0) ** 2)
    return f


def upright(features):
    """The made-up punch with the trunk held upright (its shoulder where the scene has it)."""
    features[:, NAMES.index("angle_waist_flexion")] = 0.0
    return features


def test_a_straight_path_has_ratio_one_and_no_distance_from_its_chord():
    line = np.linspace([0.0, 1.4, 0.3], [0.1, 1.5, 0.9], 25)
    assert path_over_chord(line) == pytest.approx(1.0)
    assert largest_distance_from_chord(line) == pytest.approx(0.0, abs=1e-12)


def test_a_detour_is_measured_by_its_length_and_its_largest_distance():
    # Out 10 cm to the side halfway along a 1 m reach, and back: two legs of sqrt(0.1² + 0.5²) each.
    detour = np.concatenate([np.linspace([0, 0, 0], [0.1, 0, 0.5], 50, endpoint=False), np.linspace([0.1, 0, 0.5], [0, 0, 1.0], 51)])
    assert path_over_chord(detour) == pytest.approx(2 * math.hypot(0.1, 0.5))
    assert largest_distance_from_chord(detour) == pytest.approx(0.1)
    # A wind-up behind the start counts too: the distance is from the segment, not from the line through it.
    wind_up = np.array([[0, 0, 0], [0, 0, -0.2], [0, 0, 1.0]])
    assert largest_distance_from_chord(wind_up) == pytest.approx(0.2)
    assert largest_distance_from_start(np.array([[0, 0, 0], [0.3, 0.4, 0], [0.1, 0, 0]])) == pytest.approx(0.5)


def test_speeds_and_the_proximal_to_distal_order():
    path = np.outer(np.arange(11), [0.0, 0.0, 0.05])  # 5 cm a frame at 120 Hz
    assert speeds_from_positions(path, 1 / HZ) == pytest.approx(np.full(10, 6.0))
    bump = [np.exp(-((np.arange(30) - peak) / 2.0) ** 2) for peak in (5, 10, 15)]
    assert in_proximal_to_distal_order(*bump)
    assert in_proximal_to_distal_order(-bump[0], bump[1], -bump[2]), "the size of a speed counts, not its sign"
    assert not in_proximal_to_distal_order(bump[1], bump[0], bump[2])
    assert not in_proximal_to_distal_order(bump[0], bump[2], bump[1])
    assert in_proximal_to_distal_order(bump[0], bump[0], bump[2]), "a tie is in order"


def test_the_figures_of_a_made_up_punch():
    punch = punch_naturalness(made_up_punch(), NAMES, HZ)
    assert punch.path_over_chord == pytest.approx(1.0)
    assert punch.chord_distance_m == pytest.approx(0.0, abs=1e-9)
    assert punch.fist_peak_speed_mps == pytest.approx(5.0)
    assert punch.off_fist_from_guard_m == pytest.approx(0.1)
    assert punch.off_fist_from_guard_whole_m == pytest.approx(0.3)
    assert punch.off_fist_peak_speed_mps == pytest.approx(0.1 * HZ / 20)
    assert punch.off_fist_peak_speed_whole_mps == pytest.approx(0.2 * HZ / 19)
    assert punch.trunk_flexion_deg == pytest.approx(np.degrees(0.2 * np.sin(0.5 * np.pi * 20 / 39)))  # at contact
    assert punch.trunk_flexion_whole_deg == pytest.approx(np.degrees(0.2))
    assert punch.proximal_to_distal
    assert punch.time_to_contact_s == pytest.approx(21 / HZ)
    assert not punch_naturalness(made_up_punch(peaks=(12, 8, 5)), NAMES, HZ).proximal_to_distal
    # Straight ahead from the middle, the trunk upright: the line from the right shoulder (18 cm to the right) to the
    # bag is 12.7° off it.
    punch = punch_naturalness(upright(made_up_punch()), NAMES, HZ)
    assert punch.side_angle_at_contact_deg == pytest.approx(math.degrees(math.atan2(0.18, 0.8)))
    assert punch.rise_share_at_contact == 0.0
    assert punch.elbow_bend_at_contact_deg == pytest.approx(120.0), "the guard's bend: the elbow never straightened"


def test_the_shape_figures_of_a_hook_and_an_uppercut():
    """A fist arriving sideways (moving to the character's left, +X) comes in 90° - 12.7° off the shoulder's line; one
    rising at 45° has 0.71 of its speed upward; an elbow straightened 30° from the guard is bent 90°."""
    hook = upright(made_up_punch())
    col = NAMES.index
    hook[:, col("fist_r_vel_x")], hook[:, col("fist_r_vel_z")] = 5.0, 0.0
    hook[:, col("angle_elbow_r_extension")] = math.radians(30.0)
    punch = punch_naturalness(hook, NAMES, HZ)
    assert punch.side_angle_at_contact_deg == pytest.approx(90.0 - math.degrees(math.atan2(0.18, 0.8)))
    assert punch.elbow_bend_at_contact_deg == pytest.approx(90.0)
    uppercut = made_up_punch()
    uppercut[:, col("fist_r_vel_y")] = 5.0
    assert punch_naturalness(uppercut, NAMES, HZ).rise_share_at_contact == pytest.approx(math.sqrt(0.5))


def test_the_shoulder_turns_with_the_waist_as_the_scene_has_it():
    """At the guard the shoulder is where the character scene's joint is; the trunk turned 90° left brings the right
    shoulder forward, leaned 90° forward brings it down to the waist's height, in front."""
    import re

    from punch_trainer.scene import SCENE_SHOULDER_HEIGHT_M, SCENE_WAIST_HEIGHT_M, shoulder_positions

    scene = (PROJECT_ROOT / "addons" / "punch_controller" / "scenes" / "punch_character.tscn").read_text()

    def joint_origin(name):
        found = re.search(rf'\[node name="{name}" type="Generic6DOFJoint3D"[^\]]*\]\ntransform = Transform3D\(([^)]*)\)', scene)
        assert found, name
        return [float(v) for v in found.group(1).split(",")][9:]

    assert joint_origin("ShoulderR") == pytest.approx([-0.18, SCENE_SHOULDER_HEIGHT_M, 0.0])
    assert joint_origin("ShoulderL") == pytest.approx([0.18, SCENE_SHOULDER_HEIGHT_M, 0.0])
    assert joint_origin("Waist") == pytest.approx([0.0, SCENE_WAIST_HEIGHT_M, 0.0])
    col = NAMES.index
    frames = np.zeros((3, len(NAMES)))
    frames[1, col("angle_waist_rotation")] = math.pi / 2
    frames[2, col("angle_waist_flexion")] = math.pi / 2
    rise = SCENE_SHOULDER_HEIGHT_M - SCENE_WAIST_HEIGHT_M
    np.testing.assert_allclose(shoulder_positions(frames, col), [[-0.18, SCENE_SHOULDER_HEIGHT_M, 0.0],
                                                                [0.0, SCENE_SHOULDER_HEIGHT_M, 0.18],
                                                                [-0.18, SCENE_WAIST_HEIGHT_M, rise]], atol=1e-9)


def test_a_punch_that_misses_is_measured_to_its_closest_approach():
    features = made_up_punch()
    features[:, NAMES.index("fist_r_impulse_z")] = 0.0
    punch = punch_naturalness(features, NAMES, HZ)
    assert punch.time_to_contact_s is None
    # The fist passes the bag's centre (0.8 m) at frame 12: the figures stop there.
    assert punch.off_fist_from_guard_m == pytest.approx(0.1 * 12 / 20)


def test_medians_share_in_order_and_the_table():
    punches = [punch_naturalness(made_up_punch(fist_speed=speed, peaks=peaks), NAMES, HZ)
               for speed, peaks in [(4.0, (5, 8, 12)), (5.0, (12, 8, 5)), (6.0, (5, 8, 12))]]
    summary = summarise(punches)
    assert summary.medians["fist_peak_speed_mps"] == pytest.approx(5.0)
    assert summary.proximal_to_distal_share == pytest.approx(2 / 3)
    assert summary.punches == 3 and summary.contacts == 3
    assert type(summary).from_json(json.loads(json.dumps(summary.to_json()))) == summary
    table = naturalness_table([("sigma 0", summary)], [punches[0]])
    assert len(table) == 2 + len(FIGURES) + 2
    assert "| punching fist peak speed | 5.00 m/s | 4.00 m/s to 4.00 m/s |" in table
    assert "67%" in table[-2] and "1/1" in table[-2]


def test_the_stick_figure_of_the_guard_is_the_rest_pose():
    from punch_trainer.report.naturalness_plots import POLICY_JOINTS, policy_skeleton

    features = np.zeros((1, len(NAMES)))
    col = NAMES.index
    rest_fist = np.array([0.0, 1.42, 0.0]) + 0.282 * np.array([0, -np.cos(np.radians(35)), np.sin(np.radians(35))]) \
        + 0.337 * np.array([0, -np.cos(np.radians(155)), np.sin(np.radians(155))])
    for side, sign in (("r", -1), ("l", 1)):
        features[0, col(f"fist_{side}_pos_x"):col(f"fist_{side}_pos_z") + 1] = rest_fist + [sign * 0.18, 0, 0]
    joints = policy_skeleton(features, NAMES)[0]
    assert joints[POLICY_JOINTS.index("shoulder_r")] == pytest.approx([-0.18, 1.42, 0.0])
    elbow = np.array([-0.18, 1.42, 0.0]) + 0.282 * np.array([0, -np.cos(np.radians(35)), np.sin(np.radians(35))])
    assert joints[POLICY_JOINTS.index("elbow_r")] == pytest.approx(elbow, abs=1e-6)
    # Bent forward by the waist's flexion, the shoulders turn about the waist.
    features[0, col("angle_waist_flexion")] = np.radians(30)
    shoulder = policy_skeleton(features, NAMES)[0, POLICY_JOINTS.index("shoulder_l")]
    assert shoulder == pytest.approx([0.18, 1.056 + 0.364 * np.cos(np.radians(30)), 0.364 * np.sin(np.radians(30))])


def test_the_captured_punches_give_the_figures_of_the_data_readme():
    from punch_trainer.report.naturalness import capture_figures

    punches = capture_figures(DEFAULT_BVH)
    assert punches is not None and len(punches) == 4
    # punch_trainer/data/README.md, "Figures of the four punches".
    assert [round(p.path_over_chord, 2) for p in punches] == [1.03, 1.11, 1.07, 1.12]
    assert [round(100 * p.chord_distance_m, 1) for p in punches] == [4.7, 13.9, 9.2, 12.6]
    assert [round(p.fist_peak_speed_mps, 1) for p in punches] == [6.9, 8.4, 6.3, 7.1]
    assert [round(100 * p.off_fist_from_guard_m) for p in punches] == [12, 17, 20, 13]
    assert [round(p.time_to_contact_s, 3) for p in punches] == [0.142, 0.167, 0.183, 0.175]
    assert all(1.2 <= round(p.off_fist_peak_speed_mps, 1) <= 1.8 for p in punches)
    assert all(12 <= p.trunk_flexion_deg <= p.trunk_flexion_whole_deg <= 17 for p in punches)
    assert all(0 <= p.elbow_bend_at_contact_deg < 45 for p in punches), [p.elbow_bend_at_contact_deg for p in punches]
    assert all(p.side_angle_at_contact_deg is None and p.rise_share_at_contact is None for p in punches)


def test_the_capture_plots_are_written(tmp_path):
    from punch_trainer.report.naturalness_plots import plot_capture_comparison, plot_stick_strip

    capture = captured_punches(DEFAULT_BVH)
    punches = np.stack([made_up_punch(), made_up_punch(fist_speed=6.0)])
    fig4 = plot_capture_comparison(tmp_path, punches, NAMES, HZ, capture)
    strip = plot_stick_strip(tmp_path, punches[0], NAMES, HZ, capture[0])
    assert fig4.stat().st_size > 10_000 and strip.stat().st_size > 10_000


@pytest.mark.godot
def test_punch_eval_reports_the_naturalness_of_a_shipped_policy(tmp_path):
    from punch_trainer.pipelines.evaluation import EvalArgs, run_eval

    policy = PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "straight.onnx"
    args = EvalArgs(policy=policy, placements=3, sigmas=[0.0, 0.3], noisy_episodes=1, search_iterations=0, out=tmp_path)
    out, report = run_eval(args, progress=False)
    written = json.loads((out / "eval.json").read_text())
    every = written["evaluations"][0]["naturalness"]
    assert {row["condition"] for row in every} == {"every decision", "first 4 decisions", "bag swinging", "after a punch"}
    naturalness = [row for row in every if row["condition"] == "every decision"]
    assert [row["sigma"] for row in naturalness] == [0.0, 0.3] and naturalness[0]["punches"] == 3
    for row in naturalness:
        assert all(value is None or math.isfinite(value) for value in row["medians"].values())
        assert 0.0 <= row["proximal_to_distal_share"] <= 1.0
    assert all(math.isfinite(naturalness[0]["medians"][key]) for key in ("path_over_chord", "fist_peak_speed_mps", "trunk_flexion_deg"))
    assert len(written["evaluations"][0]["naturalness_at_sigma0"]) == 3
    medians = naturalness[0]["medians"]
    assert 0 <= medians["side_angle_at_contact_deg"] <= 180 and -1 <= medians["rise_share_at_contact"] <= 1
    assert 0 <= medians["elbow_bend_at_contact_deg"] <= 145, "within the elbow's action range from the guard's 120°"
    text = (out / "report.md").read_text()
    assert "| punching fist path length / chord |" in text and "| figure (median) | sigma 0 | sigma 0.3 |" in text
    assert (out / "naturalness_fig4.png").is_file() and (out / "naturalness_strip.png").is_file()
    assert len(written["captured_naturalness"]) == 4
