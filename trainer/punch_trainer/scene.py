"""Facts of the addon's character and sandbag scenes that the reward and the simulator both measure against."""

from typing import Any

import numpy as np

SCENE_ARM_LENGTHS_M = (0.282, 0.337, 0.36)
"""the character scene's own upper arm, forearm (elbow to fist centre) and shoulder width, m"""
SCENE_BAG_RADIUS_M = 0.175
"""the sandbag scene's radius, m (an upright cylinder)"""
SCENE_WAIST_HEIGHT_M = 1.056
"""the character scene's waist joint above its root, m"""
SCENE_SHOULDER_HEIGHT_M = 1.42
"""the character scene's shoulder joints above its root, m"""
GUARD_ELBOW_BEND_DEG = 120.0
"""the elbows' bend in the guard pose, which `angle_elbow_*_extension` counts from (docs/env.md), degrees"""


def shoulder_positions(f: np.ndarray, col: Any, side: str = "r") -> np.ndarray:
    """The shoulder's position per frame in the character's frame: the scene's shoulder (its joint's offset from the
    waist joint, the arm's own shoulder width) carried by the waist's flexion and rotation (rotation vector
    (flexion, rotation, 0): +X the character's left, +Y up, +Z toward the target)."""
    half_width = 0.5 * SCENE_ARM_LENGTHS_M[2] * (1.0 if side == "l" else -1.0)
    offset = np.array([half_width, SCENE_SHOULDER_HEIGHT_M - SCENE_WAIST_HEIGHT_M, 0.0])
    vectors = np.stack([f[:, col("angle_waist_flexion")], f[:, col("angle_waist_rotation")], np.zeros(len(f))], axis=1)
    angles = np.linalg.norm(vectors, axis=1, keepdims=True)
    axes = np.divide(vectors, angles, out=np.zeros_like(vectors), where=angles > 0)
    cos, sin = np.cos(angles), np.sin(angles)
    # Rodrigues: v cos + (k x v) sin + k (k.v)(1 - cos)
    turned = offset * cos + np.cross(axes, offset) * sin + axes * (axes @ offset)[:, None] * (1 - cos)
    return np.asarray(turned + np.array([0.0, SCENE_WAIST_HEIGHT_M, 0.0]), dtype=np.float64)
