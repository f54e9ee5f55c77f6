"""The captured punches retargeted onto the character's joints (punch_trainer.capture.prior), from the capture
shipped with the trainer (punch_trainer/data)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import punch_trainer
from punch_trainer.capture.prior import CapturePriorError, captured_actions, captured_joint_angles
from punch_trainer.capture.punches import captured_punches
from punch_trainer.learn.reach import placement
from punch_trainer.reward.rewards import first_right_contact
from punch_trainer.sim.rollouts import RolloutPool

NAMES = ["waist_flexion", "waist_rotation", "shoulder_r_flexion", "shoulder_r_rotation", "shoulder_r_abduction",
         "elbow_r_extension", "shoulder_l_flexion", "shoulder_l_rotation", "shoulder_l_abduction", "elbow_l_extension"]
LOWER_DEG = [-15, -45, -120, -60, -110, -25, -120, -80, -30, -25]
UPPER_DEG = [30, 45, 90, 80, 30, 118, 90, 60, 110, 118]
"""the action table of docs/env.md"""


def test_every_captured_punch_is_a_straight_from_the_guard_in_the_characters_joints() -> None:
    """0 at movement onset; at full reach the trunk has turned left and barely leaned, the upper arm has swung
    forward (negative flexion) and the elbow has opened, as a straight does with the character's signs."""
    for punch in captured_punches():
        angles = captured_joint_angles(punch)
        np.testing.assert_allclose(angles[punch.onset], 0.0, atol=1e-6)
        flexion, turn, shoulder_flexion, _, _, elbow = np.degrees(angles[punch.reach])
        assert abs(flexion) < 10.0 and 5.0 < turn < 25.0
        assert -120.0 < shoulder_flexion < -70.0 and 80.0 < elbow < 135.0


def test_the_actions_are_shares_of_each_range_and_the_guard_arm_holds() -> None:
    punch = captured_punches()[1]
    lower, upper = np.radians(LOWER_DEG).tolist(), np.radians(UPPER_DEG).tolist()
    actions = captured_actions(punch, NAMES, lower, upper, decisions=10, decision_period=5, physics_hz=120.0)
    assert actions.shape == (10, 10) and np.all(np.abs(actions) <= 1.0)
    assert np.all(actions[:, 6:] == 0.0)
    assert actions[:, 2].min() < -0.5 and actions[:, 5].max() > 0.5  # the arm swings forward and the elbow opens
    wider = captured_actions(punch, NAMES, [2 * v for v in lower], [2 * v for v in upper], 10, 5, 120.0)
    np.testing.assert_allclose(wider[np.abs(actions) < 1.0], actions[np.abs(actions) < 1.0] / 2)
    with pytest.raises(CapturePriorError, match="not"):
        captured_actions(punch, NAMES[::-1], lower, upper, 10, 5, 120.0)


@pytest.mark.godot
def test_played_open_loop_most_captured_punches_reach_the_bag_and_the_guard_holds() -> None:
    """In the simulator, three of the four retargeted punches carry the right fist forward onto a bag in front at
    the capture's pace (0.12-0.21 s), the left fist near its guard; the second, whose upper arm turns 30 degrees
    across the body, stalls (experiments/notebook.md)."""
    with RolloutPool(1, 4) as pool:
        info, names = pool.info, pool.info.feature_names
        actions = np.stack([captured_actions(p, info.action_names, info.action_lower_rad, info.action_upper_rad, 10,
                                             info.decision_period, info.physics_hz) for p in captured_punches()])
        features, _ = pool.run(actions, 3, [placement(0.72, 1.35, 0.0)] * len(actions))
    column = names.index
    touched = [bool(first_right_contact(punch, names)[0]) for punch in features]
    assert sum(touched) >= 3, touched
    for punch, touch in zip(features, touched, strict=True):
        off = punch[:, column("fist_l_pos_x"):column("fist_l_pos_z") + 1]
        assert np.linalg.norm(off - off[0], axis=1).max() < 0.15
        if touch:
            contact_s = (first_right_contact(punch, names)[1] + 1) / info.physics_hz
            assert 0.1 < contact_s < 0.25
            assert punch[:, column("fist_r_pos_z")].max() - punch[0, column("fist_r_pos_z")] > 0.05


def test_the_capture_ships_inside_the_package_with_its_credit() -> None:
    """The file is package data (an installed `punch` reads it too), unchanged from the CMU conversion, credited."""
    import hashlib
    import tomllib

    from punch_trainer.capture.bvh import DEFAULT_BVH

    package = Path(punch_trainer.__file__).parent
    assert DEFAULT_BVH.is_relative_to(package) and DEFAULT_BVH.is_file()
    patterns = tomllib.loads((package.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["punch_trainer"]
    assert any(DEFAULT_BVH.relative_to(package).match(pattern) for pattern in patterns)
    readme = (DEFAULT_BVH.parent / "README.md").read_text()
    assert hashlib.sha256(DEFAULT_BVH.read_bytes()).hexdigest() in readme
    assert "The data used in this project was obtained from mocap.cs.cmu.edu" in readme
