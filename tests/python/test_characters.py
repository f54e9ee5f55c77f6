"""The CC0 test characters (tests/fixtures/characters): the converter writes small, well-formed skinned glTF files,
and a headless Godot loads every one at run time (GLTFDocument) as a Skeleton3D with the rig's bones, a skinned
mesh of the requested height, bind poses that give back the mesh at rest, and a skin that follows a posed arm."""

import json
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from characters import CHARACTERS, DEFAULT_OUT, make_characters
from characters.build import ROLES
from punch_trainer.sim.godot import GODOT_PROJECT, PROJECT_ROOT, run_godot

LOADER = PROJECT_ROOT / "tests" / "godot" / "load_character_glb.gd"
BONE_COUNTS = {"mixamo": 52, "unreal": 53, "cmu": 31, "makehuman": 163}


@pytest.fixture(scope="module")
def manifest() -> dict[str, Any]:
    return make_characters(DEFAULT_OUT)  # cached: rebuilt only when the converter changes


def read_glb(path: Path) -> tuple[dict[str, Any], bytes]:
    blob = path.read_bytes()
    magic, version, length = struct.unpack_from("<III", blob, 0)
    assert (magic, version, length) == (0x46546C67, 2, len(blob))
    json_length, json_type = struct.unpack_from("<II", blob, 12)
    assert json_type == 0x4E4F534A
    document = json.loads(blob[20:20 + json_length])
    bin_length, bin_type = struct.unpack_from("<II", blob, 20 + json_length)
    assert bin_type == 0x004E4942
    return document, blob[28 + json_length:28 + json_length + bin_length]


def accessor(document: dict[str, Any], binary: bytes, index: int) -> np.ndarray:
    acc = document["accessors"][index]
    view = document["bufferViews"][acc["bufferView"]]
    dtype = {5126: np.float32, 5121: np.uint8, 5123: np.uint16, 5125: np.uint32}[acc["componentType"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
    data = np.frombuffer(binary, dtype=dtype, count=acc["count"] * width, offset=view["byteOffset"])
    return data.reshape(acc["count"], width)


def node_globals(document: dict[str, Any]) -> dict[int, np.ndarray]:
    """Every node's global transform, from the TRS chain (glTF quaternions are x, y, z, w)."""
    found: dict[int, np.ndarray] = {}

    def visit(index: int, parent: np.ndarray) -> None:
        node = document["nodes"][index]
        x, y, z, w = node.get("rotation", [0, 0, 0, 1])
        local = np.eye(4)
        local[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        local[:3, 3] = node.get("translation", [0, 0, 0])
        found[index] = parent @ local
        for child in node.get("children", []):
            visit(child, found[index])

    for root in document["scenes"][0]["nodes"]:
        visit(root, np.eye(4))
    return found


def test_converter_writes_small_consistent_skinned_glbs(manifest):
    assert [c["name"] for c in manifest["characters"]] == [c.name for c in CHARACTERS]
    assert {c["naming"] for c in manifest["characters"]} == set(ROLES)
    assert {c["height_m"] for c in manifest["characters"]} >= {1.60, 1.90}
    assert "CC0" in (DEFAULT_OUT / "NOTICE.md").read_text() and "CC0 1.0 Universal" in (DEFAULT_OUT / "LICENSE_CC0.md").read_text()
    for character in manifest["characters"]:
        path = DEFAULT_OUT / character["file"]
        assert path.stat().st_size < 2_000_000, f"{path} is larger than 2 MB"
        document, binary = read_glb(path)
        assert "CC0" in document["asset"]["copyright"]
        skin = document["skins"][0]
        names = [document["nodes"][j]["name"] for j in skin["joints"]]
        assert len(names) == BONE_COUNTS[character["naming"]] == character["bone_count"]
        assert set(ROLES[character["naming"]].values()) <= set(names)
        primitive = document["meshes"][0]["primitives"][0]
        weights = accessor(document, binary, primitive["attributes"]["WEIGHTS_0"])
        assert np.allclose(weights.sum(axis=1), 1.0, atol=1e-5) and (weights >= 0).all()
        assert accessor(document, binary, primitive["attributes"]["JOINTS_0"]).max() < len(names)
        # Bind pose = rest pose: each inverse bind matrix inverts its joint's global rest transform.
        inverse_binds = accessor(document, binary, skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
        globals_ = node_globals(document)
        for joint, inverse_bind in zip(skin["joints"], inverse_binds):
            assert np.allclose(globals_[joint] @ inverse_bind, np.eye(4), atol=1e-5), document["nodes"][joint]["name"]
        positions = accessor(document, binary, primitive["attributes"]["POSITION"])
        assert positions[:, 1].max() - positions[:, 1].min() == pytest.approx(character["height_m"], abs=1e-4)


def ancestors(parents: list[int], bone: int) -> set[int]:
    seen = set()
    while parents[bone] >= 0:
        bone = parents[bone]
        seen.add(bone)
    return seen


@pytest.mark.godot
def test_godot_loads_every_character_as_a_skinned_skeleton(manifest):
    characters = {c["file"]: c for c in manifest["characters"]}
    run = run_godot(["--headless", "--path", str(GODOT_PROJECT), "--script", str(LOADER), "--",
                     *[str(DEFAULT_OUT / name) for name in characters]], timeout_s=300)
    reports = [json.loads(line.split(" ", 1)[1]) for line in run.log.splitlines() if line.startswith("CHARACTER ")]
    assert [Path(r["path"]).name for r in reports] == list(characters), run.log
    for report in reports:
        character = characters[Path(report["path"]).name]
        name = character["name"]
        assert "error" not in report, f"{name}: {report.get('error')}"
        assert report["bone_count"] == report["skin_binds"] == BONE_COUNTS[character["naming"]], name
        assert report["has_skin"] and report["mesh_skeleton_is_skeleton"] and report["influences_per_vertex"] == 4, name
        assert report["height_m"] == pytest.approx(character["height_m"], abs=0.01), name
        # The rig's names come through (Godot turns `:` into `_`), each role bone is found, and the arm is a chain
        # below the chest below the hips: what punch_core::bone_map needs (its tests map these same namings).
        names, parents = report["bone_names"], report["bone_parents"]
        found = report["roles_found"]
        assert all(names[found[role]] == bone.replace(":", "_") for role, bone in ROLES[character["naming"]].items()), name
        for side in "lr":
            assert found[f"upper_arm_{side}"] in ancestors(parents, found[f"forearm_{side}"]), name
            assert found[f"forearm_{side}"] in ancestors(parents, found[f"hand_{side}"]), name
            assert found["chest"] in ancestors(parents, found[f"upper_arm_{side}"]), name
        assert found["hips"] in ancestors(parents, found["chest"]), name
        # Rest positions as the converter placed them; the character faces +Z, so its right hand is at -X.
        for role, position in report["rest_m"].items():
            assert np.allclose(position, character["rest_m"][role], atol=1e-4), f"{name} {role}"
        assert report["rest_m"]["hand_r"][0] < report["rest_m"]["upper_arm_r"][0] < 0 < report["rest_m"]["upper_arm_l"][0], name
        # Bone axes: identity rests (CMU) or Blender's, with the bone's Y axis along the bone.
        basis = np.array(report["rest_axes"]["upper_arm_r"]).reshape(3, 3)  # rows: the basis' x, y, z axes
        if character["bone_axes"] == "world":
            assert np.allclose(basis, np.eye(3), atol=1e-5), name
        else:
            along = np.subtract(report["rest_m"]["forearm_r"], report["rest_m"]["upper_arm_r"])
            assert basis[1] @ along / np.linalg.norm(along) > 0.99, name  # MakeHuman splits the upper arm in two
        # Skinning (Godot's formula, on the CPU): the bind poses give back the mesh at rest, and with the right arm
        # turned forward the hand lands where it should, the arm's skin follows it rigidly, and the mesh reaches forward.
        assert report["rest_skinning_error_m"] < 5e-4, name
        assert report["posed_hand_error_m"] < 1e-3, name
        assert report["arm_vertices"] > 1000 and report["arm_vertex_error_m"] < 5e-4, name
        rest_box, posed_box = report["rest_aabb"], report["posed_aabb"]
        reach = np.linalg.norm(np.subtract(character["rest_m"]["hand_r"], character["rest_m"]["upper_arm_r"]))
        assert posed_box[5] > character["rest_m"]["upper_arm_r"][2] + reach, f"{name}: the posed arm does not reach forward"
        assert posed_box[0] > rest_box[0] + 0.1, f"{name}: the right arm's skin stayed at the side"
