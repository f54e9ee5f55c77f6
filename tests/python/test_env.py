"""The Gymnasium environments over real Godot processes, and the processes' life cycle."""

import os

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from punch_trainer.reward.rewards import Reward
from punch_trainer.sim.env import PunchEnv, PunchVectorEnv
from punch_trainer.sim.server import TrainingServer

pytestmark = pytest.mark.godot


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie that was not reaped yet also counts as gone.
    with open(f"/proc/{pid}/stat") as stat:
        return stat.read().split()[2] != "Z"


def test_gymnasium_env_checker_passes():
    with PunchEnv() as env:
        check_env(env, skip_render_check=True)


def test_episode_shape_features_and_reward():
    feature_sum = Reward("feature_sum", lambda f: f.features[..., 0], frames=50)  # any function of the features
    with PunchEnv(frames=50, reward=feature_sum) as env:
        observation, info = env.reset(seed=3)
        assert observation.shape == (54,) and observation.dtype == np.float32
        assert info["features"].shape == (len(env.feature_names),)
        for decision in range(10):
            observation, reward, terminated, truncated, info = env.step(np.zeros(10, dtype=np.float32))
            assert info["features"].shape == (5, len(env.feature_names))
            assert reward == pytest.approx(info["features"][:, 0].sum())
            assert terminated == (decision == 9) and not truncated
        assert observation[-1] == pytest.approx(1.0)  # episode phase


def test_reset_with_seed_jitters_the_bag_reproducibly():
    with PunchEnv(bag_jitter_m=0.05) as env:
        first = env.reset(seed=5)[1]["bag"]
        again = env.reset(seed=5)[1]["bag"]
        other = env.reset(seed=6)[1]["bag"]
    assert first == again and first != other


def test_vector_env_over_two_processes():
    env = PunchVectorEnv(processes=2, characters_per_process=3, frames=10)
    try:
        assert env.num_envs == 6
        observations, info = env.reset(seed=0)
        assert observations.shape == (6, 54)
        for _ in range(2):
            observations, rewards, terminated, truncated, info = env.step(env.action_space.sample())
        assert terminated.all() and not truncated.any()
        assert info["features"].shape == (6, 5, len(env.feature_names))
        # Next-step autoreset: the following step starts new episodes.
        observations, rewards, terminated, truncated, _ = env.step(env.action_space.sample())
        assert not terminated.any() and np.all(observations[:, -1] == 0.0)
        pids = [server.pid for server in env.servers]
    finally:
        env.close()
    assert not any(alive(pid) for pid in pids)


def test_close_is_idempotent_and_kills_the_process():
    server = TrainingServer(1)
    pid = server.pid
    assert alive(pid)
    server.close()
    server.close()
    assert not alive(pid)


def test_env_is_registered_with_the_right_spaces():
    # Importing punch_trainer (here through its env module) registers the envs.
    with gym.make("punch/Punch-v0") as env:
        assert isinstance(env.action_space, gym.spaces.Box)
        assert env.action_space.low.min() == -1.0 and env.action_space.high.max() == 1.0


def test_episodes_may_start_with_the_bag_swinging_or_after_a_lead_in():
    """A placement's velocity sets the bag swinging; a lead-in's actions run before the episode, which then
    starts where they left the character (its right fist elsewhere, the phase 0) with the bag as placed."""
    names = None
    with PunchVectorEnv(1, 3, frames=50) as env:
        names = env.info.observation_names
        lead_in = np.zeros((3, 6, 10), dtype=np.float32)
        lead_in[1, :, 5] = 1.0  # slot 1 straightens its right elbow before its episode
        bags = [{"velocity_forward_mps": 0.8}, {}, {}]
        obs, info = env.reset(options={"bag": bags, "lead_in": lead_in})
        col = names.index
        assert obs[0, col("bag_vel_z")] == pytest.approx(0.8, abs=0.05) and obs[2, col("bag_vel_z")] == 0.0
        assert abs(obs[1, col("angle_elbow_r_extension")] - obs[2, col("angle_elbow_r_extension")]) > 0.5
        assert np.allclose(obs[1, col("bag_pos_x"):col("bag_pos_z") + 1], obs[2, col("bag_pos_x"):col("bag_pos_z") + 1], atol=1e-4)
        assert (obs[:, col("episode_phase")] == 0).all()
        obs, *_ = env.step(np.zeros((3, 10), dtype=np.float32))
        assert obs[0, col("bag_pos_z")] > obs[2, col("bag_pos_z")] + 0.005, "the swinging bag moved away"
