"""The editor plugin's Project > Tools > "Make Selected Skeleton Punch" (`addons/punch_controller/own_character_setup.gd`),
run headless on converted CC0 characters with a plain UndoRedo in place of the editor's: the README's "Your own
character" set-up in one undoable action, and a clear refusal for a skeleton without the bones."""

import json

import pytest

from characters import DEFAULT_OUT, make_characters
from punch_trainer.sim.godot import GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot

ROLES = ["hips", "chest", "neck", "head"] + [f"{part}_{side}" for side in "lr" for part in ["shoulder", "upper_arm", "forearm", "hand"]]


def set_up(character: str) -> dict:
    make_characters(DEFAULT_OUT)
    script = PROJECT_ROOT / "tests" / "godot" / "own_character_setup.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script), "--",
                     f"--glb={DEFAULT_OUT / (character + '.glb')}"], check=False, timeout_s=120)
    assert run.returncode == 0 and run.fatal_lines() == [], run.log[-3000:]
    # The one error: the modifier's own, for the skeleton with meaningless bone names.
    errors = [line for line in run.log.splitlines() if "ERROR" in line]
    assert len(errors) == 1 and "lacks bones the punching body needs" in errors[0], run.log[-3000:]
    line = next(line for line in run.log.splitlines() if line.startswith("OWN_CHARACTER_SETUP "))
    report: dict = json.loads(line[len("OWN_CHARACTER_SETUP "):])
    return report


@pytest.fixture(scope="module", params=["mixamo_190", "unreal_160"])
def report(request: pytest.FixtureRequest) -> dict:
    return set_up(request.param)


def test_one_action_adds_the_wired_nodes(report):
    assert report["found_alone"] and report["found_from_model"], report
    assert report["ok"], report.get("message")
    assert report["added"] == 3  # the character, the sandbag and the controller; the modifier goes under the skeleton
    for nodes in [report["nodes"], report["after_redo"]]:
        assert all(nodes["parents"]) and all(nodes["owners"]), nodes
        assert nodes["character_class"] == "PunchCharacter"
        assert nodes["controller_character"] and nodes["controller_target"] and nodes["modifier_controller"], nodes
        assert nodes["policy"] == "res://addons/punch_controller/policies/straight.onnx"
        assert nodes["size_to_rig"] and nodes["modifiers"] == 1 and nodes["player_physics"], nodes
        assert nodes["mapped"] and nodes["warnings"] == [], nodes
        assert sorted(role for role, bone in nodes["bone_map"].items() if bone) == sorted(ROLES), nodes["bone_map"]
        # The bag where the policies were trained to find it, in the simulated character's frame.
        assert nodes["bag_in_character"] == pytest.approx(nodes["default_offset"], abs=1e-4)


def test_the_action_undoes_redoes_and_saves(report):
    assert report["after_undo"] == {"added": 0, "in_tree": [False] * 4, "modifiers": 0, "player_physics": False}
    assert report["saved"] == {"packed": True, "modifiers": 1, "controllers": 1, "modifier_under_skeleton": True,
                               "characters": 1, "bags": 1}


def test_an_instanced_model_gets_editable_children_so_its_modifier_is_saved(report):
    # Without Editable Children, the scene would be saved without the modifier under the model's Skeleton3D.
    assert report["instanced"] == {"ok": True, "made_editable": ["Model"], "editable": True, "saved_modifiers": 1,
                                   "undone_editable": False}


def test_the_character_is_placed_on_the_rig_and_punches_the_bag(report):
    # The modifier's follow_rig moves the simulated body when it is more than 1 cm or 1 degree off the rig.
    assert report["placement_gap_m"] < 0.01 and report["placement_turn_rad"] < 0.0175, report
    assert report["punch_started"] and report["punch"]["finished"], report["punch"]
    assert report["punch"]["on_bag"] >= 1, report["punch"]
    assert report["written_bones"] > 13  # spine, clavicles, arms, hands, and the fingers curled into fists


def test_a_skeleton_without_the_bones_is_refused_saying_which_and_nothing_is_added(report):
    unnamed = report["unnamed"]
    assert not unnamed["ok"] and unnamed["added"] == 0 and unnamed["skeleton_children"] == 0, unnamed
    assert unnamed["history"] == 1  # only the first action
    for role in ["left upper arm", "right upper arm", "head"]:
        assert role in unnamed["message"], unnamed["message"]
    assert "bone_map" in unnamed["message"]


def test_no_skeleton_or_two_are_refused_saying_so(report):
    assert "no Skeleton3D" in report["no_skeleton"]
    assert "2 Skeleton3D nodes" in report["two_skeletons"] and "select" in report["two_skeletons"]
