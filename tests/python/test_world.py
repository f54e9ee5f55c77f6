"""The punching world on real headless Godot/Jolt: rest, actuation, stability under hostile actions,
contact sensing against the bag's momentum, and bitwise determinism across slots, N and processes."""

import numpy as np
import pytest

from punch_trainer.sim.protocol import ServerError
from punch_trainer.sim.server import TrainingServer

pytestmark = pytest.mark.godot

DECISIONS = 20  # 100 frames


@pytest.fixture(scope="module")
def server():
    with TrainingServer(6) as server:
        yield server


def column(server, name):
    return server.info.feature_names.index(name)


def test_character_stands_still_at_rest(server):
    features = server.rollout(np.zeros((6, DECISIONS, 10)))
    start = server.reset().arrays["features"]
    fists = [column(server, f"fist_{side}_pos_{axis}") for side in "rl" for axis in "xyz"]
    angles = slice(column(server, "angle_waist_flexion"), column(server, "angle_elbow_l_extension") + 1)
    assert np.abs(features[:, :, fists] - start[:, None, fists]).max() < 1e-3, "fists drift at rest"
    assert np.abs(features[:, :, angles]).max() < 5e-3, "joints drift at rest"
    assert features[:, :, column(server, "exploit_flags")].max() == 0


def test_each_dof_moves_only_as_asked(server):
    # Slot k drives DOF k to +0.5 (or -0.5); every other DOF is asked to hold.
    actions = np.zeros((6, DECISIONS, 10))
    dofs = [0, 1, 3, 5, 7, 9]
    for slot, dof in enumerate(dofs):
        actions[slot, :, dof] = 0.5 if slot % 2 == 0 else -0.5
    features = server.rollout(actions)
    first_angle = column(server, "angle_waist_flexion")
    lower, upper = np.array(server.info.action_lower_rad), np.array(server.info.action_upper_rad)
    for slot, dof in enumerate(dofs):
        angles = features[slot, -1, first_angle:first_angle + 10]
        action = actions[slot, 0, dof]
        target = action * (upper[dof] if action > 0 else -lower[dof])
        assert angles[dof] == pytest.approx(target, abs=0.05), f"DOF {server.info.action_names[dof]} missed its target"
        others = np.delete(angles, dof)
        assert np.abs(others).max() < 0.12, f"driving {server.info.action_names[dof]} moved other joints: {others}"


def test_targets_are_reached():
    with TrainingServer(1) as server:
        actions = np.zeros((1, DECISIONS, 10))
        actions[0, :, 5] = 1.0  # right elbow fully extended
        features = server.rollout(actions)[0]
    elbow = features[-1, column(server, "angle_elbow_r_extension")]
    assert elbow == pytest.approx(np.deg2rad(118.0), abs=0.01)


def test_hostile_actions_never_break_the_character(server):
    rng = np.random.default_rng(7)
    actions = np.empty((6, DECISIONS, 10))
    flip = np.where(np.arange(DECISIONS)[:, None] % 2 == 0, 1.0, -1.0)
    actions[0], actions[1] = flip, -flip
    actions[2:] = rng.choice([-1.0, 1.0], size=(4, DECISIONS, 10))
    features = server.rollout(actions)
    assert np.isfinite(features).all()
    # Ordinary motion keeps joints within a millimetre; only violent flipping stretches them transiently.
    assert features[2:, :, column(server, "joint_gap_max_m")].mean() < 0.01
    assert features[..., column(server, "joint_gap_max_m")].max() < 0.03, "a joint came apart"
    flags = features[..., column(server, "exploit_flags")].astype(int)
    assert (flags & 0b0010).max() == 0, "the guard saw a joint separate"
    speeds = np.linalg.norm(features[..., column(server, "fist_r_vel_x"):column(server, "fist_r_vel_z") + 1], axis=-1)
    assert speeds.max() < 15.0, "a fist moved faster than the drives can make it"


def test_hit_is_seen_by_contacts_and_by_the_bag(server):
    actions = np.zeros((6, DECISIONS // 2, 10))
    actions[:, :, 5] = 1.0   # extend the right elbow
    actions[:, :, 2] = -0.6  # raise the arm forward
    actions[:, :, 3] = 0.3   # turn it toward the bag's centre
    actions[:, :, 1] = 0.5   # turn the trunk left
    features = server.rollout(actions)[0]
    contact = features[:, column(server, "character_impulse_x"):column(server, "character_impulse_z") + 1]
    bag = features[:, column(server, "bag_momentum_change_x"):column(server, "bag_momentum_change_z") + 1]
    touching = np.flatnonzero(np.linalg.norm(contact, axis=1) > 1e-3)
    moving = np.flatnonzero(np.linalg.norm(bag[:, [0, 2]], axis=1) > 0.5)
    assert touching.size and moving.size, "the punch should reach the bag"
    assert abs(int(touching[0]) - int(moving[0])) <= 1, "the bag must start moving when the contact is reported"
    window = slice(touching[0], touching[0] + 3)
    reported, delivered = contact[window][:, [0, 2]].sum(0), bag[window][:, [0, 2]].sum(0)
    cosine = reported @ delivered / (np.linalg.norm(reported) * np.linalg.norm(delivered))
    assert cosine > 0.9, f"contact impulse {reported} and bag momentum change {delivered} disagree in direction"
    assert np.linalg.norm(features[:, column(server, "fist_r_impulse_x"):column(server, "fist_r_impulse_z") + 1]) > 0


def test_exact_mode_is_bitwise_identical_whatever_the_slot_n_or_process():
    rng = np.random.default_rng(11)
    sequence = rng.uniform(-1, 1, size=(DECISIONS, 10)).astype(np.float32)

    def run(slot_count, slot):
        actions = rng.uniform(-1, 1, size=(slot_count, DECISIONS, 10)).astype(np.float32)
        actions[slot] = sequence
        with TrainingServer(slot_count, slots_per_world=1) as server:
            first = server.rollout(actions)[slot]
            again = server.rollout(actions)[slot]
        assert np.array_equal(first, again), "the same process repeated differently"
        return first

    reference = run(1, 0)
    for slot_count, slot in [(5, 3), (40, 37)]:
        assert np.array_equal(run(slot_count, slot), reference), f"slot {slot} of {slot_count} differs"
    assert np.array_equal(run(1, 0), reference), "a second process differs"


def punches(count: int, seed: int) -> np.ndarray:
    """Right punches that all reach the bag at about the same time, each a little different."""
    rng = np.random.default_rng(seed)
    punch = np.zeros((DECISIONS // 2, 10), np.float32)
    punch[:, 5], punch[:, 2], punch[:, 3], punch[:, 1] = 1.0, -0.6, 0.3, 0.5
    return np.clip(punch + 0.15 * rng.standard_normal((count, *punch.shape)), -1, 1).astype(np.float32)


def test_exact_mode_simultaneous_punches_match_single_runs():
    # Contacts are where physics engines order work by body ids: every slot punches the bag at about the
    # same time, and each must match the same punch run alone.
    actions = punches(16, seed=3)
    with TrainingServer(16, slots_per_world=1) as server:
        together = server.rollout(actions, smoothing_window=3)
        impulse = column(server, "character_impulse_z")
    assert (np.abs(together[..., impulse]).max(axis=1) > 0).sum() >= 8, "most slots should hit the bag"
    with TrainingServer(1) as server:
        for slot in range(0, 16, 3):
            alone = server.rollout(actions[slot:slot + 1], smoothing_window=3)[0]
            assert np.array_equal(together[slot], alone), f"slot {slot} differs from the same punch alone"


def test_default_mode_repeats_bitwise_for_the_same_slot_and_n():
    actions = punches(16, seed=4)
    results = []
    for _ in range(2):  # two processes
        with TrainingServer(16) as server:
            results.append(server.rollout(actions, smoothing_window=3))
    assert np.array_equal(results[0], results[1])


def test_bag_position_is_configurable(server):
    bags = [{"distance_m": 0.9, "height_m": 1.2, "side_m": 0.1 * k} for k in range(6)]
    reply = server.reset(bags=bags)
    positions = reply.arrays["features"][:, column(server, "bag_pos_x"):column(server, "bag_pos_z") + 1]
    expected = np.array([[b["side_m"], b["height_m"], b["distance_m"]] for b in bags])
    np.testing.assert_allclose(positions, expected, atol=1e-5)


def test_smoothing_is_the_papers_weighted_moving_average(server):
    rng = np.random.default_rng(5)
    raw = rng.uniform(-1.5, 1.5, size=(6, 10, 10)).astype(np.float32)
    window = 3
    executed = server.rollout_reply(raw, smoothing_window=window).arrays["executed_actions"]
    clipped = np.clip(raw, -1, 1)
    expected = np.empty_like(clipped)
    for t in range(10):
        history = clipped[:, max(0, t - window + 1):t + 1]
        weights = np.arange(1, history.shape[1] + 1, dtype=np.float32)
        expected[:, t] = np.tensordot(history, weights, axes=([1], [0])) / weights.sum()
    np.testing.assert_allclose(executed, expected, atol=1e-6)
    assert np.array_equal(server.rollout_reply(raw).arrays["executed_actions"], clipped)


def test_a_carried_character_walks_turns_and_lunges_with_its_arms_in_guard(server):
    """The session moves each slot's kinematic pelvis along its body motion; the trunk and arms follow through
    the joints, and the features are in the frame of the root as it is at each frame."""
    turn = np.radians(120.0)
    bags = [{}, {"body_forward_mps": -1.4}, {"body_side_mps": -0.7, "body_turn_rad_s": turn, "body_bob_m": 0.03},
            {"body_lunge_m": 0.15}, {"bag_glides": True, "velocity_side_mps": 1.0},
            {"body_forward_mps": 0.7, "body_side_mps": 0.5, "body_bob_m": 0.03, "bag_rides": True}]
    features = server.rollout(np.zeros((6, 10, 10)), bags=bags)  # 50 frames, the guard held
    frame_s = 1 / 120
    at = lambda name: features[:, :, column(server, name)]  # noqa: E731
    root_velocity = np.stack([at(f"root_vel_{axis}") for axis in "xyz"], axis=-1)
    np.testing.assert_allclose(root_velocity[1], np.tile([0.0, 0.0, -1.4], (50, 1)), atol=1e-4)
    np.testing.assert_allclose(root_velocity[2][:, [0, 2]], np.tile([-0.7, 0.0], (50, 1)), atol=1e-3)
    np.testing.assert_allclose(at("root_spin_y")[2], turn, atol=1e-4)
    assert np.abs(root_velocity[0]).max() == 0.0 and np.abs(root_velocity[4]).max() == 0.0, "standing stays still"
    # The bag, still in the world, falls behind the character walking backward at its speed...
    times = np.arange(1, 51) * frame_s
    np.testing.assert_allclose(at("bag_pos_z")[1], 0.72 + 1.4 * times, atol=2e-3)
    np.testing.assert_allclose(at("bag_pos_z")[3, -1], 0.72 - 0.15, atol=2e-3)  # the lunge stepped 0.15 m in
    # ...a carried bag keeps its velocity (to the character's left), and one that rides along stays in place.
    np.testing.assert_allclose(at("bag_pos_x")[4, -1], 1.0 * 50 * frame_s, atol=0.01)
    bag_in_root = np.stack([at(f"bag_pos_{axis}")[5] for axis in "xyz"], axis=-1)
    np.testing.assert_allclose(bag_in_root, np.tile([0.0, 1.35, 0.72], (50, 1)), atol=0.01)  # rides as carried
    # The arms hold their guard in the moving frame, and no joint comes apart.
    fists = [column(server, f"fist_{side}_pos_{axis}") for side in "rl" for axis in "xyz"]
    guard = features[0, 0, fists]
    assert np.abs(features[:, :, fists] - guard).max() < 0.03, "a fist left its guard"
    assert at("joint_gap_max_m").max() < 5e-3
    assert at("exploit_flags").max() == 0


def test_a_placement_sizes_the_arms_as_a_rig_would_and_the_policy_sees_their_lengths():
    """Training draws arm sizes (`ArmRange`): the server sizes each slot's arms as `PunchCharacter.size_arms`
    sizes a game's character, and the `body_*` features report the lengths; a size no rig may have is refused
    with the range, and the server goes on."""
    scene = np.array([0.282, 0.337, 0.36])  # the character scene's upper arm, forearm, shoulder distance (m)
    sizes = [(1.0, 1.0, 0.0), (0.8, 0.75, -0.02), (1.3, 1.2, 0.04)]
    bags = [{"arms_upper_arm_scale": u, "arms_forearm_scale": f, "arms_shoulder_shift_m": s} for u, f, s in sizes]
    with TrainingServer(3) as server:
        guard = server.rollout(np.zeros((3, 10, 10)), bags=bags)
        names = ["body_upper_arm_m", "body_forearm_m", "body_shoulder_width_m"]
        lengths = guard[:, 0, [column(server, name) for name in names]]
        expected = np.array([[scene[0] * u, scene[1] * f, scene[2] + 2 * s] for u, f, s in sizes])
        np.testing.assert_allclose(lengths, expected, atol=2e-3)
        assert guard[:, :, column(server, "joint_gap_max_m")].max() < 2e-3, "a sized joint starts apart"
        assert guard[:, :, column(server, "exploit_flags")].max() == 0
        # The arm swung straight to the shoulder's limit, elbow extended: the longer arm's fist ends further out.
        reach = np.zeros((3, 20, 10))
        reach[:, :, [column(server, "angle_shoulder_r_flexion") - column(server, "angle_waist_flexion"),
                     column(server, "angle_elbow_r_extension") - column(server, "angle_waist_flexion")]] = 1.0
        out_m = np.abs(server.rollout(reach, bags=bags)[:, -1, column(server, "fist_r_pos_z")])
        assert out_m[1] < out_m[0] < out_m[2], out_m
        with pytest.raises(ServerError, match="0.75"):
            server.reset(bags={"arms_upper_arm_scale": 0.65, "arms_forearm_scale": 0.65})
        assert server.reset().arrays["features"].shape[0] == 3, "the server serves on after a refused size"
