"""PunchSkeletonModifier: a game's own rigged skeleton (built at run time in several namings, rest poses and bone
axis conventions, and the converted CC0 characters when they are there) driven by a PunchController's simulated
upper body, blended with its animation."""

import json

import pytest

from characters import DEFAULT_OUT, make_characters
from punch_trainer.sim.godot import ADDON_POLICIES, GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot


# The simulated body's own arms (the addon's character scene): upper arm, elbow to fist centre, shoulder width (m),
# and the range of arm lengths (shoulder to fist centre, as a fraction of its own) it can be sized to.
SCENE_ARMS = [0.282, 0.337, 0.36]
ARM_RANGE = (0.75, 1.25)
# How high the simulated crown stands above the middle of its shoulder joints (m), as the scene has it.
SCENE_CROWN_M = 0.29
# The character whose modifier keeps `size_head_to_rig` off (tests/godot/skeleton_modifier.gd).
HEAD_LEFT_AS_IS = "mixamo_155"


def run_scene(*args: str) -> list[dict]:
    script = PROJECT_ROOT / "tests" / "godot" / "skeleton_modifier.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script), "--",
                     f"--policy={ADDON_POLICIES / 'straight.onnx'}", *args], check=False, timeout_s=120)
    assert run.fatal_lines() == [], run.log[-3000:]
    assert not any(line.startswith("SKELETON_MODIFIER_GLB_FAILED") for line in run.log.splitlines()), run.log[-3000:]
    cost = next(line for line in run.log.splitlines() if line.startswith("SKELETON_MODIFIER_COST "))
    print(cost)
    line = next(line for line in run.log.splitlines() if line.startswith("SKELETON_MODIFIER "))
    report = json.loads(line[len("SKELETON_MODIFIER "):])
    for rig in report:
        jumps = rig["jumps_rad"]
        print(f"{rig['name']:22s} hits {rig['hits']} fist gap at first hit {100 * rig['hit_gap_m']:.1f} cm, "
              f"largest fully blended {100 * rig['max_gap_full_m']:.1f} cm; per-frame rotation (deg) blend-in "
              f"{jumps['blend_in'] * 57.3:.1f} blend-out {jumps['blend_out'] * 57.3:.1f} animation "
              f"{jumps['animation'] * 57.3:.1f} simulated {jumps['simulated'] * 57.3:.1f}; unwritten bones off the "
              f"animation by {rig['untouched_max_rad']:.1e} rad; arms (upper, fore, shoulders) simulated "
              f"{fmt(rig['arm_lengths_m'])} rig {fmt(rig['rig_arm_lengths_m'])} m"
              + (f"; skinned hand at the hit {100 * rig['skinned_hit_gap_m']:.1f} cm off, its front "
                 f"{100 * rig['skinned_front_m']:+.1f} cm past the simulated fist's" if rig["skinned_hit_gap_m"] >= 0 else ""))
    # One error per rig whose bones cannot be mapped and per rig whose arms are outside the range the simulated
    # ones can be sized to (saying so), and nothing else.
    errors = [line for line in run.log.splitlines() if "ERROR" in line]
    unmapped = [e for e in errors if "PunchSkeletonModifier" in e and "upper arm" in e]
    refused = [e for e in errors if "cannot size the arms" in e and "the arm (shoulder to fist centre)" in e
               and "outside 0.75..1.25" in e]
    assert len(unmapped) == len([r for r in report if not r["mapped"]]), run.log[-3000:]
    assert len(refused) == len([r for r in report if r["mapped"] and not in_range(r)]), run.log[-3000:]
    assert len(errors) == len(unmapped) + len(refused), run.log[-3000:]
    return report


def in_range(rig: dict) -> bool:
    arm = rig["rig_arm_lengths_m"][0] + rig["rig_arm_lengths_m"][1]
    return ARM_RANGE[0] <= arm / (SCENE_ARMS[0] + SCENE_ARMS[1]) <= ARM_RANGE[1]


def fmt(lengths: list[float]) -> str:
    return "/".join(f"{x:.3f}" for x in lengths)


@pytest.fixture(scope="module")
def rigs() -> dict[str, dict]:
    return {rig["name"]: rig for rig in run_scene()}


@pytest.fixture(scope="module")
def characters() -> dict[str, dict]:
    """The converted CC0 characters (made here if they are not yet: cached, seconds)."""
    manifest = make_characters(DEFAULT_OUT)
    glbs = [f"--glb={DEFAULT_OUT / c['file']}" for c in manifest["characters"]]
    report = run_scene(*glbs)
    names = {c["file"].removesuffix(".glb") for c in manifest["characters"]}
    return {rig["name"]: rig for rig in report if rig["name"] in names}


MAPPED = ["mixamo_t_y", "unreal_a_x", "profile_t_x", "mixamo_a_y_long", "unreal_t_y_short", "mixamo_a_x_cm"]


def test_every_naming_is_mapped_without_hand_work(rigs):
    expected = {"mixamo_t_y": "mixamorig_RightArm", "unreal_a_x": "upperarm_r", "profile_t_x": "RightUpperArm"}
    for name, upper_arm in expected.items():
        rig = rigs[name]
        assert rig["mapped"] and rig["problem"] == "", rig
        assert rig["bone_map"]["upper_arm_r"] == upper_arm
        # Spine (3), neck and head (turned by the simulated head's snap), clavicle, upper arm, forearm, hand and its one
        # finger (curled into a fist) per side.
        assert len(rig["written"]) == 3 + 2 + 2 * 5, rig["written"]
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
        assert rig["untouched_max_rad"] < 1e-5, name  # legs, hips and the fingers not curled: the animation's own


def test_the_visible_fist_lands_on_the_simulated_fist_for_rigs_of_the_simulated_proportions(rigs):
    for name in ["mixamo_t_y", "unreal_a_x", "profile_t_x"]:
        rig = rigs[name]
        assert 0.0 <= rig["hit_gap_m"] <= 0.01, (name, rig["hit_gap_m"])
        assert rig["max_gap_full_m"] <= 0.01, (name, rig["max_gap_full_m"])


def test_the_simulated_arms_take_the_rigs_lengths(rigs):
    """Each mapped rig's arms (read from its rest, in its own units and scale) become the simulated arms, the
    long-armed (1.15) and short-armed (0.85) ones included."""
    for name in MAPPED:
        rig = rigs[name]
        assert rig["arm_lengths_m"] == pytest.approx(rig["rig_arm_lengths_m"], abs=0.002), name
    assert rigs["mixamo_a_y_long"]["arm_lengths_m"][0] == pytest.approx(1.15 * SCENE_ARMS[0], abs=0.002)
    assert rigs["unreal_t_y_short"]["arm_lengths_m"][1] == pytest.approx(0.85 * SCENE_ARMS[1], abs=0.002)


def test_the_visible_fist_lands_within_3_cm_of_the_simulated_fist_on_every_sized_rig(rigs):
    for name in MAPPED:
        rig = rigs[name]
        assert rig["hits"] >= 1, name
        assert 0.0 <= rig["hit_gap_m"] <= 0.03, (name, rig["hit_gap_m"])
        assert rig["max_gap_full_m"] <= 0.03, (name, rig["max_gap_full_m"])


def test_a_rig_outside_the_accepted_range_keeps_the_default_arms(rigs):
    """The tiny rig's arms are 0.6 of the simulated ones: one error (checked in run_scene) and the simulated body
    punches with its own arms; its skeleton is still driven."""
    rig = rigs["profile_a_y_tiny"]
    assert rig["mapped"] and rig["problem"] == "", rig["problem"]
    assert rig["rig_arm_lengths_m"][0] == pytest.approx(0.6 * SCENE_ARMS[0], abs=0.002)
    assert rig["arm_lengths_m"] == pytest.approx(SCENE_ARMS, abs=0.002)
    assert rig["hits"] >= 1


def test_blending_eases_without_steps(rigs):
    """A blend over n frames must turn a bone by (angle between the animation's and the simulated pose) / n per
    frame beyond their own motion; smoothstep adds at most 1.5 times that and no step in speed at either end.
    Here the animation is a T-pose idle, up to 180 degrees from the simulated guard (forearms folded back), so
    the default blends (0.05 s in, 0.1 s out) turn bones faster than the punch itself does: the README says to
    lengthen them when the animation's guard is far from the simulated one."""
    frames_in, frames_out = 0.05 * 120, 0.1 * 120
    for name in MAPPED:
        rig = rigs[name]
        jumps = rig["jumps_rad"]
        assert rig["blend_frames"] >= frames_in - 1 + frames_out - 1, rig["blend_frames"]
        own = max(jumps["animation"], jumps["simulated"])
        for key, frames in (("blend_in", frames_in), ("blend_out", frames_out)):
            # `simulated` is the simulated pose's own step at full weight only; a blend-in covers the punch's first
            # frames, where it moves fastest (the shipped straight lands in its sixth), hence the 10% margin.
            bound = 1.1 * (own + 1.5 * rig["pose_gap_rad"] / frames) + 1e-3
            assert jumps[key] <= bound, (name, key, jumps, rig["worst_bone"])


def test_the_cc0_characters_are_sized_and_their_visible_fists_land_within_3_cm(characters):
    """The converted characters (1.55, 1.60, 1.75, 1.90 and 1.95 m; Mixamo, Unreal, CMU and MakeHuman namings; A- and T-pose):
    each one whose arms are within the range gets them, and its fist lands within 3 cm of the simulated fist at
    the hit; one outside keeps the simulated body's own arms (its error is counted in run_scene)."""
    sized = [name for name, rig in characters.items() if in_range(rig)]
    assert sized == list(characters), sized  # all of them: 1.60 m ones have arms 0.78 of the simulated ones
    for name, rig in characters.items():
        assert rig["mapped"] and rig["hits"] >= 1, name
        assert rig["untouched_max_rad"] < 1e-5, name
        if name in sized:
            assert rig["arm_lengths_m"] == pytest.approx(rig["rig_arm_lengths_m"], abs=0.002), name
            assert 0.0 <= rig["hit_gap_m"] <= 0.03, (name, rig["hit_gap_m"])
            assert rig["max_gap_full_m"] <= 0.03, (name, rig["max_gap_full_m"])
        else:
            assert rig["arm_lengths_m"] == pytest.approx(SCENE_ARMS, abs=0.002), name


def test_the_simulated_head_takes_the_cc0_characters_head_and_a_rig_without_one_keeps_its_own(rigs, characters):
    """`size_head_to_rig` moves the simulated head to the rig's (`PunchCharacter.size_head`, from the vertices bound
    mostly to the rig's head): its crown stands as high above the shoulder joints as the rig's, measured apart from
    the modifier as the top of the rig's skinned mesh at rest, within 2 cm; a rig with neither a skin nor a head-top
    bone, and a modifier with the option off (its default), keep the scene's head (its crown 0.29 m above the
    shoulders)."""
    for name in MAPPED:
        assert rigs[name]["crown_m"] == pytest.approx(SCENE_CROWN_M, abs=0.002), name
    for name, rig in characters.items():
        # Their crowns stand 0.35-0.36 m above their shoulder joints: 6-7 cm above the scene's.
        assert rig["rig_crown_m"] > SCENE_CROWN_M + 0.04, name
        wanted = SCENE_CROWN_M if name == HEAD_LEFT_AS_IS else rig["rig_crown_m"]
        assert rig["crown_m"] == pytest.approx(wanted, abs=0.02), (name, rig["crown_m"], rig["rig_crown_m"])


def test_the_skinned_fist_of_the_cc0_characters_lands_within_3_cm_of_the_simulated_fist(characters):
    """The visible fist as the skin shows it, with the fingers curled into a fist (`fist_curl`): the centre of the
    vertices bound mostly to the right hand and the bones below it, skinned on the CPU at the hit
    (tests/godot/skeleton_modifier.gd), and its front (the furthest of them along the simulated forearm) against
    the simulated fist's front. Open, these hands lay 7-10 cm past the simulated fist. The CMU-named ones have one
    bone for all four fingers, rooted at the index finger's knuckle: their fist centre needs the skin to be found
    (`rig_fist_centres`; 3.6-4.2 cm off from the bones alone)."""
    checked = [name for name, rig in characters.items() if in_range(rig)]
    assert len(checked) >= 12 and any(name.startswith("cmu_") for name in checked), checked
    for name in checked:
        rig = characters[name]
        assert 0.0 <= rig["skinned_hit_gap_m"] <= 0.03, (name, rig["skinned_hit_gap_m"])
        assert abs(rig["skinned_front_m"]) <= 0.03, (name, rig["skinned_front_m"])


def test_the_own_character_demo_punches_the_bag_and_spars():
    """godot_project/demo/own_character.tscn: two converted CC0 characters (1.90 m Mixamo, 1.60 m Unreal), sized
    and driven through their skeletons, punch the bag and each other."""
    make_characters(DEFAULT_OUT)
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "res://demo/own_character.tscn",
                     "--", "--punches=6"], check=False, timeout_s=120)
    assert "ERROR" not in run.log, run.log[-3000:]
    line = next(line for line in run.log.splitlines() if line.startswith("OWN_CHARACTER "))
    fighters = json.loads(line[len("OWN_CHARACTER "):])
    print(fighters)
    assert [f["name"] for f in fighters] == ["mixamo_190", "unreal_160"] and all(f["mapped"] for f in fighters)
    assert fighters[0]["hits_on_bag"] >= 1 and fighters[1]["hits_on_opponent"] >= 1, fighters
    rate = json.loads(next(line for line in run.log.splitlines() if line.startswith("HIT_RATE "))[len("HIT_RATE "):])
    assert rate["punches"] == 6 and rate["hits"] >= 5, rate  # counted, not a float at the bar


@pytest.mark.parametrize("character", ["mixamo_190", "unreal_160"])
def test_a_knocked_down_rig_is_handed_to_the_games_ragdoll_and_taken_back_on_recover(character):
    """Issue 53's hand-off (tests/godot/knockdown_ragdoll.gd): a CC0 character wired by the editor plugin's action,
    turned 130 degrees, with a PhysicalBoneSimulator3D of the game's own under its skeleton (two rigs, 1.90 and 1.60 m,
    Mixamo and Unreal namings), struck at 400 N s on the torso: `hit_taken`
    names the rig's chest bone, `knocked_down`, the
    skeleton handed to the simulator (`handed_off_to`), the head bone starting with the simulated head's velocity
    along the push, the ragdoll falling where the limp simulated body would hang; after `recover()` the simulation
    stops, the modifier poses it again and the head is back where it stood. Its twin without a ragdoll shows the simulated body hanging limp."""
    make_characters(DEFAULT_OUT)
    script = PROJECT_ROOT / "tests" / "godot" / "knockdown_ragdoll.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script), "--",
                     f"--glb={DEFAULT_OUT / (character + '.glb')}"], check=False, timeout_s=120)
    line = next((line for line in run.log.splitlines() if line.startswith("KNOCKDOWN_RAGDOLL ")), None)
    assert run.returncode == 0 and line is not None and run.fatal_lines() == [], run.log[-3000:]
    assert "ERROR" not in run.log, run.log[-3000:]
    report = json.loads(line[len("KNOCKDOWN_RAGDOLL "):])
    ragdoll, limp = report["with_ragdoll"], report["without"]
    for fighter in (ragdoll, limp):
        assert fighter["knocked_down"] == [400.0], fighter
        assert fighter["hit_taken"] == ["torso", fighter["chest_bone"]] and fighter["chest_bone"], fighter  # the rig's bone
    assert ragdoll["handed_off"] and ragdoll["simulating"] and ragdoll["still_handed_off"], ragdoll
    # Started with the simulated head's velocity, then held back by the ragdoll's own joints.
    assert ragdoll["head_bone_speed_mps"] > 0.4 * ragdoll["simulated_head_speed_mps"] > 1.0, ragdoll
    assert ragdoll["head_bone_along_push"] > 0.5, ragdoll
    assert ragdoll["head_fell_m"] > 1.0 > limp["head_fell_m"], (ragdoll, limp)
    assert not limp["handed_off"] and not limp["simulating"] and limp["limp_blend_weight"] == 1.0, limp
    for fighter in (ragdoll, limp):
        assert not fighter["after_recover_handed_off"] and not fighter["after_recover_simulating"], fighter
        assert fighter["after_recover_blend_weight"] > 0.0 and fighter["recovered"], fighter
        assert abs(fighter["head_back_m"]) < 0.05, fighter
