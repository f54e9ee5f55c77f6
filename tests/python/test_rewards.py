"""Rewards: presets against hand-computed values, user reward files, and clear errors."""

import numpy as np
import pytest

from punch_trainer.sim.rewards import RewardError, evaluate, load_reward, total

NAMES = ["fist_r_bag_distance", "fist_r_vel_x", "fist_r_vel_z", "fist_r_vel_y", "exploit_flags"]


def features(distance, vx, vz, flags=0.0):
    return np.array([[[distance, vx, vz, 0.0, flags]]], dtype=np.float32)


def test_presets_match_table_2():
    f = features(0.2, 1.0, 8.0)
    near = (0.3 - 0.2) ** 2
    assert total(evaluate(load_reward("straight"), f, NAMES))[0, 0] == pytest.approx(near * 10 * 8.0, rel=1e-5)
    assert total(evaluate(load_reward("hook"), f, NAMES))[0, 0] == pytest.approx(near * 10 * (8.0 + 0.75), rel=1e-5)
    assert total(evaluate(load_reward("swing"), f, NAMES))[0, 0] == pytest.approx(near * 500 * (8.0 + 0.5), rel=1e-5)
    assert load_reward("straight").frames == 50 and load_reward("straight100").frames == 100
    assert total(evaluate(load_reward("straight"), features(0.35, 0, 8.0), NAMES))[0, 0] == 0.0  # too far


def test_terms_are_separate_and_guarded_frames_earn_nothing():
    terms = evaluate(load_reward("hook"), features(0.1, 2.0, 5.0), NAMES)
    assert set(terms) == {"forward", "sideways"}
    guarded = evaluate(load_reward("hook"), features(0.1, 2.0, 5.0, flags=2.0), NAMES)
    assert all(v[0, 0] == 0.0 for v in guarded.values())


def test_user_reward_file(tmp_path):
    path = tmp_path / "my_rewards.py"
    path.write_text("import numpy as np\n\ndef uppercut(f):\n    return np.maximum(0, 0.3 - f['fist_r_bag_distance']) * f['fist_r_vel_y']\n")
    reward = load_reward(f"{path}:uppercut", frames=100)
    assert reward.frames == 100
    f = features(0.1, 0.0, 0.0)
    f[..., 3] = 4.0
    assert total(evaluate(reward, f, NAMES))[0, 0] == pytest.approx(0.2 * 4.0, rel=1e-5)


@pytest.mark.parametrize("body, message", [
    ("def r(f):\n    raise ValueError('boom')\n", "raised ValueError: boom"),
    ("def r(f):\n    return 1.0\n", "has shape"),
    ("import numpy as np\ndef r(f):\n    return f['fist_r_vel_z'] * np.nan\n", "NaN"),
    ("def r(f):\n    return f['no_such_feature']\n", "no feature 'no_such_feature'"),
])
def test_bad_rewards_are_named_in_the_error(tmp_path, body, message):
    path = tmp_path / "bad.py"
    path.write_text(body)
    with pytest.raises(RewardError, match=message) as error:
        evaluate(load_reward(f"{path}:r"), features(0.1, 0, 1.0), NAMES)
    assert "bad.py:r" in str(error.value)


@pytest.mark.parametrize("spec, message", [
    ("nonsense", "unknown reward"),
    ("missing_file.py:r", "not found"),
    ("punch_trainer.sim.rewards:no_such_function", "has no function"),
])
def test_unloadable_rewards(spec, message):
    with pytest.raises(RewardError, match=message):
        load_reward(spec)


@pytest.mark.parametrize("body, message", [
    ("import time\n    time.sleep(30)\n    return f['fist_r_vel_z']", "took longer than 0.5 s"),
    ("import time\n    try:\n        time.sleep(30)\n    except Exception:\n        pass\n    return f['fist_r_vel_z']",
     "took longer than 0.5 s"),
    ("raise TimeoutError('its own socket')", "raised TimeoutError: its own socket"),
    ("import sys\n    sys.exit(0)", "tried to exit the process"),
    ("import os\n    os._exit(3)", r"tried to exit the process \(exit code 3\)"),
    ("f['fist_r_vel_z'][...] = 1e6\n    return f['fist_r_vel_z']", "read-only"),
    ("f.features[..., 0] = 0\n    return f['fist_r_vel_z']", "read-only"),
    ("return 'a lot'", "returned str"),
    ("return {}", "empty dict"),
    ("return None", "returned NoneType"),
])
def test_misbehaving_user_rewards_get_an_error_naming_them(tmp_path, monkeypatch, body, message):
    """A reward that hangs, exits the process, writes into its features or returns no numbers ends with an
    error that names it; the features are untouched and the process goes on."""
    import punch_trainer.sim.rewards as rewards

    monkeypatch.setattr(rewards, "REWARD_TIME_LIMIT_S", 0.5)
    (tmp_path / "bad.py").write_text(f"def reward(f):\n    {body}\n")
    reward = load_reward(f"{tmp_path / 'bad.py'}:reward")
    f = features(0.2, 1.0, 8.0)
    before = f.copy()
    with pytest.raises(RewardError, match=message) as error:
        evaluate(reward, f, NAMES)
    assert "bad.py:reward" in str(error.value)
    np.testing.assert_array_equal(f, before)
    assert f.flags.writeable, "the caller's own array stays writable"
