"""A minimal glTF 2.0 binary (.glb) writer for one skinned mesh: numpy arrays in, one file out.

Scene layout (what Blender's exporter writes, and what Godot's importer turns into Node3D > Skeleton3D >
MeshInstance3D with a Skin): a root node `Armature` holding the skeleton's root joints and the mesh node. Joint
nodes carry their local rest transform (translation + rotation); the skin's inverse bind matrices are the
inverses of the joints' global rest transforms, so the bind pose is the rest pose.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

# glTF constants
FLOAT, UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5121, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
GLB_MAGIC, GLB_VERSION, CHUNK_JSON, CHUNK_BIN = 0x46546C67, 2, 0x4E4F534A, 0x004E4942


@dataclass
class SkinnedMesh:
    """Everything one skinned character needs. Transforms are 4x4 row-major numpy matrices (column vectors)."""

    name: str
    positions: FloatArray  # (V, 3) metres
    normals: FloatArray  # (V, 3) unit
    triangles: npt.NDArray[np.int64]  # (T, 3)
    joints: npt.NDArray[np.int64]  # (V, 4) indices into bone_names
    weights: FloatArray  # (V, 4), rows sum to 1
    bone_names: list[str]
    bone_parents: list[int]  # -1 for a root; parents come before their children
    bone_globals: list[FloatArray]  # rest (= bind) transform of each bone, in the model's frame
    base_color: tuple[float, float, float, float] = (0.80, 0.62, 0.52, 1.0)
    copyright: str = ""
    extras: dict[str, Any] = field(default_factory=dict)


def quaternion_xyzw(rotation: FloatArray) -> list[float]:
    """The unit quaternion (x, y, z, w) of a 3x3 rotation matrix (Shepperd's method: stable for any angle)."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    norm = float(np.linalg.norm(q))
    return [float(c) / norm for c in q]


class _Buffer:
    """The binary chunk and the bufferViews/accessors that index it."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []

    def add(self, array: npt.NDArray[Any], component: int, kind: str, target: int | None = None, bounds: bool = False) -> int:
        while len(self.data) % 4:
            self.data.append(0)
        raw = np.ascontiguousarray(array).tobytes()
        view: dict[str, Any] = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if target is not None:
            view["target"] = target
        self.data += raw
        self.views.append(view)
        accessor: dict[str, Any] = {"bufferView": len(self.views) - 1, "componentType": component, "count": int(array.shape[0]), "type": kind}
        if bounds:
            accessor["min"] = [float(v) for v in array.min(axis=0)]
            accessor["max"] = [float(v) for v in array.max(axis=0)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def write_glb(path: Path, mesh: SkinnedMesh) -> int:
    """Writes `mesh` as a .glb at `path`; returns the file's size in bytes."""
    buffer = _Buffer()
    position = buffer.add(mesh.positions.astype(np.float32), FLOAT, "VEC3", ARRAY_BUFFER, bounds=True)
    normal = buffer.add(mesh.normals.astype(np.float32), FLOAT, "VEC3", ARRAY_BUFFER)
    joint_type = (np.uint8, UNSIGNED_BYTE) if len(mesh.bone_names) <= 256 else (np.uint16, UNSIGNED_SHORT)
    joints = buffer.add(mesh.joints.astype(joint_type[0]), joint_type[1], "VEC4", ARRAY_BUFFER)
    weights = buffer.add(mesh.weights.astype(np.float32), FLOAT, "VEC4", ARRAY_BUFFER)
    index_type = (np.uint16, UNSIGNED_SHORT) if len(mesh.positions) < 65536 else (np.uint32, UNSIGNED_INT)
    indices = buffer.add(mesh.triangles.reshape(-1).astype(index_type[0]), index_type[1], "SCALAR", ELEMENT_ARRAY_BUFFER)
    # glTF matrices are column-major: transposing a row-major matrix lays its columns out in order.
    inverse_binds = np.array([np.linalg.inv(g).T.reshape(16) for g in mesh.bone_globals], dtype=np.float32)
    ibm = buffer.add(inverse_binds, FLOAT, "MAT4")

    # Node 0 is the Armature, nodes 1..n the bones, node n+1 the mesh.
    bone_nodes: list[dict[str, Any]] = []
    for index, (name, parent) in enumerate(zip(mesh.bone_names, mesh.bone_parents)):
        parent_global = mesh.bone_globals[parent] if parent >= 0 else np.eye(4)
        local = np.linalg.inv(parent_global) @ mesh.bone_globals[index]
        node: dict[str, Any] = {"name": name, "translation": [float(v) for v in local[:3, 3]], "rotation": quaternion_xyzw(local[:3, :3])}
        children = [1 + child for child, p in enumerate(mesh.bone_parents) if p == index]
        if children:
            node["children"] = children
        bone_nodes.append(node)
    mesh_node = 1 + len(bone_nodes)
    roots = [1 + index for index, parent in enumerate(mesh.bone_parents) if parent < 0]
    document: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": "punch_trainer.characters", **({"copyright": mesh.copyright} if mesh.copyright else {})},
        "scene": 0,
        "scenes": [{"name": mesh.name, "nodes": [0]}],
        "nodes": [{"name": "Armature", "children": roots + [mesh_node]}, *bone_nodes, {"name": "Body", "mesh": 0, "skin": 0}],
        "meshes": [{"name": "Body", "primitives": [{
            "attributes": {"POSITION": position, "NORMAL": normal, "JOINTS_0": joints, "WEIGHTS_0": weights},
            "indices": indices, "material": 0}]}],
        "materials": [{"name": "Skin", "pbrMetallicRoughness": {"baseColorFactor": list(mesh.base_color), "metallicFactor": 0.0, "roughnessFactor": 0.7}}],
        "skins": [{"name": "Skin", "joints": [1 + i for i in range(len(bone_nodes))], "inverseBindMatrices": ibm,
                   **({"skeleton": roots[0]} if len(roots) == 1 else {})}],
        "accessors": buffer.accessors,
        "bufferViews": buffer.views,
        "buffers": [{"byteLength": len(buffer.data)}],
    }
    if mesh.extras:
        document["extras"] = mesh.extras
    while len(buffer.data) % 4:
        buffer.data.append(0)
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    blob = (struct.pack("<III", GLB_MAGIC, GLB_VERSION, 12 + 8 + len(text) + 8 + len(buffer.data))
            + struct.pack("<II", len(text), CHUNK_JSON) + text + struct.pack("<II", len(buffer.data), CHUNK_BIN) + bytes(buffer.data))
    path.write_bytes(blob)
    return len(blob)
