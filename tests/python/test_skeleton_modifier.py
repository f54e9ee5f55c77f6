"""PunchSkeletonModifier: a game's own rigged skeleton (built at run time in several namings, rest poses and bone
axis conventions, and the converted CC0 characters when they are there) driven by a PunchController's simulated
upper body, blended with its animation."""

import json

import pytest

from punch_trainer.sim.godot import ADDON_POLICIES, GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot


def run_scene(*args: str) -> list[dict]:
    script = PROJECT_ROOT / "tests" / "godot" / "skeleton_modifier.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script), "--",
                     f"--policy={ADDON_POLICIES / 'straight.onnx'}", *args], check=False, timeout_s=120)
    assert run.fatal_lines() == [], run.log[-3000:]
    errors = [line for line in run.log.splitlines() if "ERROR" in line]
    # One error, for the rig whose bones cannot be mapped, and nothing else.
    assert len(errors) == 1 and "PunchSkeletonModifier" in errors[0] and "upper arm" in errors[0], run.log[-3000:]
    cost = next(line for line in run.log.splitlines() if line.startswith("SKELETON_MODIFIER_COST "))
    print(cost)
    line = next(line for line in run.log.splitlines() if line.startswith("SKELETON_MODIFIER "))
    return json.loads(line[len("SKELETON_MODIFIER "):])


@pytest.fixture(scope="module")
def rigs() -> dict[str, dict]:
    report = run_scene()
    for rig in report:
        jumps = rig["jumps_rad"]
        print(f"{rig['name']:18s} hits {rig['hits']} fist gap at first hit {100 * rig['hit_gap_m']:.1f} cm, "
              f"largest fully blended {100 * rig['max_gap_full_m']:.1f} cm; per-frame rotation (deg) blend-in "
              f"{jumps['blend_in'] * 57.3:.1f} blend-out {jumps['blend_out'] * 57.3:.1f} animation "
              f"{jumps['animation'] * 57.3:.1f} simulated {jumps['simulated'] * 57.3:.1f}; unwritten bones off the "
              f"animation by {rig['untouched_max_rad']:.1e} rad")
    return {rig["name"]: rig for rig in report}


MAPPED = ["mixamo_t_y", "unreal_a_x", "profile_t_x", "mixamo_a_y_long", "unreal_t_y_short"]


def test_every_naming_is_mapped_without_hand_work(rigs):
    expected = {"mixamo_t_y": "mixamorig_RightArm", "unreal_a_x": "upperarm_r", "profile_t_x": "RightUpperArm"}
    for name, upper_arm in expected.items():
        rig = rigs[name]
        assert rig["mapped"] and rig["problem"] == "", rig
        assert rig["bone_map"]["upper_arm_r"] == upper_arm
        # Spine (3), clavicle, upper arm, forearm and hand per side.
        assert len(rig["written"]) == 3 + 2 * 4, rig["written"]
        assert rig["warnings"] == [], rig["warnings"]


def test_a_rig_without_the_bones_keeps_its_animation_and_says_what_is_missing(rigs):
    rig = rigs["unmapped"]
    assert not rig["mapped"] and rig["written"] == []
    assert any("upper arm" in warning for warning in rig["warnings"]), rig["warnings"]
    assert rig["untouched_max_rad"] < 1e-5


def test_the_rigs_punch_and_their_legs_keep_the_animation(rigs):
    for name in MAPPED:
        rig = rigs[name]
        assert rig["hits"] >= 1, name
        assert rig["untouched_max_rad"] < 1e-5, name  # legs, hips, neck, head, fingers: the animation's own


def test_the_visible_fist_lands_on_the_simulated_fist_for_rigs_of_the_simulated_proportions(rigs):
    for name in ["mixamo_t_y", "unreal_a_x", "profile_t_x"]:
        rig = rigs[name]
        assert 0.0 <= rig["hit_gap_m"] <= 0.01, (name, rig["hit_gap_m"])
        assert rig["max_gap_full_m"] <= 0.01, (name, rig["max_gap_full_m"])


def test_blending_eases_without_steps(rigs):
    """A blend over n frames must turn a bone by (angle between the animation's and the simulated pose) / n per
    frame beyond their own motion; smoothstep adds at most 1.5 times that and no step in speed at either end.
    Here the animation is a T-pose idle, up to 180 degrees from the simulated guard (forearms folded back), so
    the default 0.1 s blend turns bones faster than the punch itself does: the README says to lengthen it
    when the animation's guard is far from the simulated one."""
    frames_per_blend = 0.1 * 120
    for name in MAPPED:
        rig = rigs[name]
        jumps = rig["jumps_rad"]
        assert rig["blend_frames"] >= 2 * (frames_per_blend - 1), rig["blend_frames"]  # 0.1 s in and out
        own = max(jumps["animation"], jumps["simulated"])
        bound = own + 1.5 * rig["pose_gap_rad"] / frames_per_blend + 1e-3
        assert jumps["blend_in"] <= bound and jumps["blend_out"] <= bound, (name, jumps, rig["worst_bone"])
