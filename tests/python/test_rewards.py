"""Rewards: presets against hand-computed values, user reward files, and clear errors."""

import os
import time
from pathlib import Path

import numpy as np
import pytest

from punch_trainer.reward.rewards import RewardError, evaluate, load_reward, total

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


HOOK_NAMES = ["fist_r_bag_distance", "fist_r_vel_x", "fist_r_vel_y", "fist_r_vel_z", "fist_r_impulse_x", "fist_r_impulse_z",
              "bag_pos_x", "bag_pos_z", "angle_waist_flexion", "angle_waist_rotation", "angle_elbow_r_extension", "exploit_flags"]


def hook_frame(vx, vz, jx, jz, elbow_bend_deg):
    """One frame of a right fist near a bag straight ahead of its shoulder (the scene's: 0.18 m right of the middle)."""
    return np.array([[[0.1, vx, 0.0, vz, jx, jz, -0.18, 0.8, 0.0, 0.0, np.radians(120.0 - elbow_bend_deg), 0.0]]], dtype=np.float32)


def test_the_bent_hook_earns_most_from_the_side_and_lands_only_with_the_elbow_bent():
    """`hook_bent`: along and 1.5 times across the shoulder-to-bag line (across: toward the body's middle, +x for the
    right fist), near the bag; the landing impulse counts none of it at 50 degrees of elbow bend or less, all from 80."""
    reward = load_reward("hook_bent")
    near = (0.3 - 0.1) ** 2
    terms = evaluate(reward, hook_frame(3.0, 4.0, 0.0, 0.0, 90.0), HOOK_NAMES)
    assert terms["sweep"][0, 0] == pytest.approx(near * 10 * (4.0 + 1.5 * 3.0), rel=1e-4)
    speed = 5.0
    straight, from_side = (total(evaluate(reward, hook_frame(speed * np.sin(a), speed * np.cos(a), 0, 0, 90), HOOK_NAMES))[0, 0]
                           for a in (0.0, np.radians(56.0)))
    assert from_side > 1.5 * straight
    landing = [evaluate(reward, hook_frame(0.0, 0.0, 0.5, 1.0, bend), HOOK_NAMES)["landing"][0, 0] for bend in (40, 65, 85, 110)]
    assert landing[0] == 0.0 and landing[1] == pytest.approx(0.5 * landing[2], rel=1e-4)
    assert landing[2] == landing[3] == pytest.approx(5.0 * (1.0 + 1.5 * 0.5), rel=1e-4)


def test_the_outside_hook_lands_only_coming_from_outside_the_line():
    """`hook_outside`: `hook_bent` whose landing counts none with the fist 20 degrees or less off the shoulder-to-bag
    line, all of it from 35 (the right fist coming in toward the body's middle: +x)."""
    bent, outside = load_reward("hook_bent"), load_reward("hook_outside")
    speed = 5.0

    def landing(reward, angle_deg):
        a = np.radians(angle_deg)
        return evaluate(reward, hook_frame(speed * np.sin(a), speed * np.cos(a), 0.5, 1.0, 90.0), HOOK_NAMES)["landing"][0, 0]

    assert landing(outside, 10.0) == 0.0 and landing(bent, 10.0) > 0.0
    assert landing(outside, 27.5) == pytest.approx(0.5 * landing(bent, 27.5), rel=1e-3)
    assert landing(outside, 45.0) == pytest.approx(landing(bent, 45.0), rel=1e-5)


UPPERCUT_NAMES = HOOK_NAMES + ["fist_r_impulse_y"]


def uppercut_frames(vx, vy, vz, jy, jz, elbow_bend_deg):
    """Two like frames of a right fist near a bag straight ahead of its shoulder (the rise is read the frame before)."""
    frame = [0.1, vx, vy, vz, 0.0, jz, -0.18, 0.8, 0.0, 0.0, np.radians(120.0 - elbow_bend_deg), 0.0, jy]
    return np.array([[frame, frame]], dtype=np.float32)


def test_the_bent_uppercut_lands_in_full_only_rising_with_the_elbow_bent():
    """`uppercut_bent`: along the shoulder-to-bag line and 1.5 times up, near the bag, never below 0; its landing
    (along the line and 1.5 times up) counts in full with the fist rising (the upward share of its speed from 0.6) and
    the elbow bent 70 degrees or more, a quarter of it otherwise; `uppercut_gated` none of it otherwise."""
    bent, gated = load_reward("uppercut_bent"), load_reward("uppercut_gated")
    near = (0.3 - 0.1) ** 2
    rising = evaluate(bent, uppercut_frames(0.0, 4.0, 2.0, 0.4, 0.2, 90.0), UPPERCUT_NAMES)
    assert rising["rise"][0, 1] == pytest.approx(near * 10 * (2.0 + 1.5 * 4.0), rel=1e-4)
    assert rising["landing"][0, 1] == pytest.approx(5.0 * (0.2 + 1.5 * 0.4), rel=1e-4)
    assert evaluate(bent, uppercut_frames(0.0, -4.0, 2.0, 0.0, 0.0, 90.0), UPPERCUT_NAMES)["rise"][0, 1] == 0.0
    for frames in (uppercut_frames(0.0, 0.0, 5.0, 0.4, 0.2, 90.0), uppercut_frames(0.0, 4.0, 2.0, 0.4, 0.2, 30.0)):
        assert evaluate(bent, frames, UPPERCUT_NAMES)["landing"][0, 1] == pytest.approx(0.25 * rising["landing"][0, 1], rel=1e-4)
        assert evaluate(gated, frames, UPPERCUT_NAMES)["landing"][0, 1] == 0.0
    assert evaluate(gated, uppercut_frames(0.0, 4.0, 2.0, 0.4, 0.2, 90.0), UPPERCUT_NAMES)["landing"][0, 1] == \
        pytest.approx(rising["landing"][0, 1], rel=1e-4)


def test_the_rising_uppercut_counts_its_approach_only_for_a_rising_fist():
    """`uppercut_rising`: `uppercut_gated` with its approach near the bag counted in full from an upward share of the
    fist's speed of 0.6, none at 0.35 or below; its landing as the gated one's."""
    gated, rising = load_reward("uppercut_gated"), load_reward("uppercut_rising")
    up = uppercut_frames(0.0, 4.0, 2.0, 0.4, 0.2, 90.0)  # rising 0.89 of its speed
    for name in ("rise", "landing"):
        assert evaluate(rising, up, UPPERCUT_NAMES)[name][0, 1] == pytest.approx(
            evaluate(gated, up, UPPERCUT_NAMES)[name][0, 1], rel=1e-4)
    level = uppercut_frames(0.0, 1.0, 5.0, 0.0, 0.0, 90.0)  # rising 0.2 of its speed
    assert evaluate(gated, level, UPPERCUT_NAMES)["rise"][0, 1] > 0.0
    assert evaluate(rising, level, UPPERCUT_NAMES)["rise"][0, 1] == 0.0


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
    ("punch_trainer.reward.rewards:no_such_function", "has no function"),
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
    import punch_trainer.reward.rewards as rewards

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


ATTACKS = {
    "os._exit bound at import": ("from os import _exit as quit_\ndef reward(f):\n    quit_(3)\n",
                                 r"tried to exit the process \(exit code 3\)"),
    "bare except retry loop": ("import time\ndef reward(f):\n    while True:\n        try:\n            time.sleep(30)\n"
                               "        except:\n            pass\n", "took longer than 0.5 s"),
    "SIGALRM ignored": ("import signal, time\ndef reward(f):\n    signal.signal(signal.SIGALRM, signal.SIG_IGN)\n"
                        "    time.sleep(30)\n", "took longer than 0.5 s"),
    "timer switched off": ("import signal, time\ndef reward(f):\n    signal.setitimer(signal.ITIMER_REAL, 0)\n"
                           "    signal.signal(signal.SIGALRM, lambda *a: None)\n    time.sleep(30)\n", "took longer than 0.5 s"),
    "kills itself": ("import os, signal\ndef reward(f):\n    os.kill(os.getpid(), signal.SIGKILL)\n", "signal SIGKILL"),
    "writes re-enabled": ("def reward(f):\n    f.features.flags.writeable = True\n    f.features[...] = 0\n"
                          "    return f['fist_r_vel_z']\n", "WRITEABLE|read-only"),
    "writes through .base": ("import numpy as np\ndef reward(f):\n    base = f.features\n    while getattr(base, 'base', None) is not None:\n"
                             "        base = base.base\n    np.frombuffer(base, dtype=np.uint8)[:] = 0\n"
                             "    return f['fist_r_vel_z']\n", "read-only"),
    "complex": ("def reward(f):\n    return f['fist_r_vel_z'] + 1j\n", r"returned complex numbers \(complex"),
    "complex term": ("def reward(f):\n    return {'a': f['fist_r_vel_z'] * (1 + 0j)}\n", "term 'a' returned complex"),
    "strings": ("import numpy as np\ndef reward(f):\n    return np.full(f['fist_r_vel_z'].shape, '1.5')\n", "returned strings"),
    "objects": ("import numpy as np\nfrom decimal import Decimal\ndef reward(f):\n"
                "    return np.full(f['fist_r_vel_z'].shape, Decimal(1), dtype=object)\n", "Python objects"),
    "hangs at import": ("import time\ntime.sleep(60)\ndef reward(f):\n    return f['fist_r_vel_z']\n", "longer than 5.5 s importing"),
}


ENDS_THE_WORKER = {"os._exit bound at import", "bare except retry loop", "SIGALRM ignored", "timer switched off", "kills itself"}


@pytest.mark.parametrize("name", list(ATTACKS))
def test_reward_attacks_end_only_their_worker(tmp_path, monkeypatch, name):
    """Each way a reward could end, hang or corrupt the run ends with a RewardError saying what it did; the
    caller's features are unchanged and the trainer goes on (the worker is gone)."""
    import punch_trainer.reward.rewards as rewards
    import punch_trainer.reward.sandbox as worker

    source, message = ATTACKS[name]
    monkeypatch.setattr(rewards, "REWARD_TIME_LIMIT_S", 0.5)
    if name == "hangs at import":
        monkeypatch.setattr(worker, "STARTUP_ALLOWANCE_S", 5.0)
    path = tmp_path / "attack.py"
    path.write_text(source)
    f = features(0.2, 1.0, 8.0)
    before = f.copy()
    with pytest.raises(RewardError, match=message) as error:
        reward = load_reward(f"{path}:reward")
        pid = reward.function._process.pid
        evaluate(reward, f, NAMES)
    assert "attack.py:reward" in str(error.value)
    np.testing.assert_array_equal(f, before)
    if name in ENDS_THE_WORKER:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)  # reaped: no worker left running



def test_a_reward_that_forks_then_exits_is_named_and_its_child_is_gone(tmp_path, monkeypatch):
    """A child process the reward started keeps the worker's pipes open after the worker exits: the error still
    says what the reward did (not a time-out), and the child goes with the worker (its process group)."""
    import punch_trainer.reward.rewards as rewards

    monkeypatch.setattr(rewards, "REWARD_TIME_LIMIT_S", 0.5)
    child_file = tmp_path / "child"
    path = tmp_path / "forks.py"
    path.write_text(f"import os, time\ndef reward(f):\n    child = os.fork()\n    if child == 0:\n        time.sleep(60)\n"
                    f"        os._exit(0)\n    open({str(child_file)!r}, 'w').write(str(child))\n    os._exit(3)\n")
    with pytest.raises(RewardError, match=r"tried to exit the process \(exit code 3\)"):
        evaluate(load_reward(f"{path}:reward"), features(0.2, 1.0, 8.0), NAMES)
    child, deadline = int(child_file.read_text()), time.monotonic() + 5
    while running(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not running(child), "the reward's child still runs"


def running(pid: int) -> bool:
    """Whether process `pid` runs (a zombie waiting for its parent to reap it does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[-1].split()[0] not in "ZX"
    except (FileNotFoundError, ProcessLookupError):
        return False


def test_a_worker_that_died_is_replaced_and_results_match_in_process(tmp_path):
    """A user's reward in its worker gives bitwise the values the same function gives in-process."""
    path = tmp_path / "mine.py"
    path.write_text("import numpy as np\ndef reward(f):\n    return {'a': np.sqrt(np.abs(f['fist_r_vel_z'])) * 1.1, "
                    "'b': f['fist_r_bag_distance'] > 0.1}\n")
    reward = load_reward(f"{path}:reward")
    rng = np.random.default_rng(0)
    f = rng.standard_normal((7, 5, len(NAMES))).astype(np.float32)
    f[..., -1] = 0
    first = evaluate(reward, f, NAMES)
    assert np.array_equal(first["a"], (np.sqrt(np.abs(f[..., 2])) * 1.1).astype(np.float64))
    assert np.array_equal(first["b"], (f[..., 0] > 0.1).astype(np.float64))
    reward.function._process.kill()
    reward.function._process.wait()
    again = evaluate(reward, f, NAMES)
    assert all(np.array_equal(first[k], again[k]) for k in first)


def test_reward_source_is_fingerprinted(tmp_path):
    from punch_trainer.reward.rewards import reward_fingerprint

    path = tmp_path / "mine.py"
    path.write_text("def reward(f):\n    return f['fist_r_vel_z']\n")
    first = reward_fingerprint(load_reward(f"{path}:reward"))
    path.write_text("def reward(f):\n    return 2 * f['fist_r_vel_z']\n")
    assert first.startswith("sha256:") and first != reward_fingerprint(load_reward(f"{path}:reward"))
    assert reward_fingerprint(load_reward("hook")) == "preset:hook"


@pytest.mark.parametrize("frames", ["0", "1201", "99999999999", "-5", "5.0", "\u0663"])
def test_a_policy_frame_count_of_no_sense_is_refused(frames):
    from punch_trainer.reward.rewards import metadata_reward

    assert metadata_reward({"punch_frames": "100", "punch_reward": "straight"}, "p.onnx").frames == 100
    with pytest.raises(RewardError, match="is not a frame count"):
        metadata_reward({"punch_frames": frames, "punch_reward": "straight"}, "p.onnx")
