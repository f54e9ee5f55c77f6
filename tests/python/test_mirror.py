"""The mirror of the character's world (punch_core::contract::mirror, read from the training server's handshake)
against real Jolt: the shipped straight plays a right-hand punch at a placement off the centre line, and the same
policy plays mirrored (its observation mirrored in, its action mirrored out) at the mirrored placement, closed
loop, in the same server; the mirrored episode's features, mirrored back, are the first episode's frame by frame,
and the right fist's hit becomes the left fist's. The physics is not bit-symmetric (Jolt solves the bodies and
contacts in an order), so the two agree to a tolerance measured here (docs/env.md, "Mirror")."""

from pathlib import Path

import numpy as np
import onnxruntime
import pytest

from punch_trainer.policy_file import read_policy_metadata
from punch_trainer.sim.conditions import EpisodeConditions
from punch_trainer.sim.mirror import MirrorRules, VectorMirror
from punch_trainer.sim.server import TrainingServer

STRAIGHT = Path(__file__).resolve().parents[2] / "addons/punch_controller/policies/straight.onnx"
PLACEMENTS = [
    EpisodeConditions(distance_m=0.72, height_m=1.40, side_m=-0.12),
    # Walking sideways and turning while it punches: the root's velocity and spin mirror too.
    EpisodeConditions(distance_m=0.68, height_m=1.30, side_m=0.18, velocity_side_mps=0.3, bag_rides=True,
                      body_side_mps=0.4, body_forward_mps=0.3, body_turn_rad_s=0.8),
]
# Until the first contact, the largest difference between a feature and its mirror image's, by quantity (measured on
# Godot 4.6 / Jolt at the shipped solver settings, printed by the test: positions 1.7 mm, velocities 0.06 m/s,
# joint angles 0.005 rad, joint speeds 0.13 rad/s, the rest 0.6 mm; about twice that here). Contact is chaotic:
# after it only the punch's outcome is compared.
BEFORE_CONTACT = {"pos": 3e-3, "vel": 0.12, "angle": 0.01, "speed": 0.25, "other": 3e-3}
AT_CONTACT_FIST_M = 0.005
"""the punching fist's place at the first contact (measured: 1.3 mm)"""
SHARE = 0.03
"""the punching fist's total impulse on the bag and its peak speed, a share of them (measured: 0.5% and 0.2%)"""
WHOLE_EPISODE_FIST_M = 0.15
"""the fists through the whole episode, after contact too (measured since the head hangs on its neck: 10.4 cm standing
and 1.6 cm walking and turning, by the last frame, 3 cm until then; before, with the head welded to the chest, 9 mm and
5.5 cm: the policy plays closed loop, and the rebound from the bag is chaotic). A wrong sign puts a fist tens of
centimetres away from the first frames on."""


def quantity(name: str) -> str:
    """The tolerance group of a feature: positions, velocities, joint angles, joint speeds, the rest."""
    for group in ("angle", "speed"):
        if name.startswith(group):
            return group
    for group in ("pos", "vel"):
        if f"_{group}_" in name:
            return group
    return "other"


def test_a_table_must_pair_every_entry_with_its_partner():
    table = VectorMirror.from_wire({"partner": [1, 0, 2], "sign": [1.0, 1.0, -1.0]})
    values = np.array([[1.0, 2.0, 3.0]], np.float32)
    assert table(values).tolist() == [[2.0, 1.0, -3.0]] and table(values).dtype == np.float32
    assert np.array_equal(table(table(values)), values)
    with pytest.raises(ValueError, match="partner"):
        VectorMirror.from_wire({"partner": [1, 2, 0], "sign": [1.0, 1.0, 1.0]})


@pytest.mark.godot
def test_a_mirrored_policy_plays_the_mirrored_punch_with_the_other_hand():
    metadata = read_policy_metadata(STRAIGHT)
    session = onnxruntime.InferenceSession(str(STRAIGHT), providers=["CPUExecutionProvider"])

    def act(observations: np.ndarray) -> np.ndarray:
        return np.clip(session.run(None, {"obs": observations.astype(np.float32)})[0], -1, 1)

    with TrainingServer(2 * len(PLACEMENTS), decision_period=metadata.decision_period, slots_per_world=1) as server:
        info = server.info
        rules: MirrorRules = info.mirror
        assert rules.conditions(rules.conditions(PLACEMENTS[1])) == PLACEMENTS[1]
        bags = [bag for placement in PLACEMENTS for bag in (placement, rules.conditions(placement))]
        reply = server.reset(metadata.frames, bags=bags, smoothing_window=metadata.smoothing_window)
        observations = reply.arrays["observations"]
        frames = []
        for _ in range(metadata.frames // metadata.decision_period):
            actions = act(observations)
            actions[1::2] = rules.actions(act(rules.observations(observations[1::2])))
            reply = server.step(actions)
            frames.append(reply.arrays["features"])
            observations = reply.arrays["observations"]
        features = np.concatenate(frames, axis=1)  # [slots, frames, F]

    names = info.feature_names

    def norm(episode: np.ndarray, first: str) -> np.ndarray:
        column = names.index(first)
        return np.linalg.norm(episode[:, column:column + 3], axis=1)

    def impulse(episode: np.ndarray, side: str) -> np.ndarray:
        return norm(episode, f"fist_{side}_impulse_x")

    def speed(episode: np.ndarray, side: str) -> np.ndarray:
        return norm(episode, f"fist_{side}_vel_x")

    fists = [names.index(f"fist_{side}_pos_{axis}") for side in "rl" for axis in "xyz"]
    for placement, (right_hand, other) in enumerate(zip(features[0::2], features[1::2], strict=True)):
        mirrored_back = rules.features(other)
        hits = np.flatnonzero(impulse(right_hand, "r") > 1e-3)
        assert hits.size, f"placement {placement}: the straight should land with its right fist"
        contact = int(hits[0])
        difference = np.abs(right_hand - mirrored_back)[:contact].max(axis=0)
        by_quantity = {group: max(float(v) for n, v in zip(names, difference, strict=True) if quantity(n) == group)
                       for group in BEFORE_CONTACT}
        fist_after = float(np.abs(right_hand - mirrored_back)[:, fists].max())
        at_contact = float(np.linalg.norm((right_hand - mirrored_back)[contact, fists[:3]]))
        totals = impulse(right_hand, "r").sum(), impulse(other, "l").sum()
        peaks = speed(right_hand, "r").max(), speed(other, "l").max()
        print(f"placement {placement}: contact at frame {contact}; before it, largest difference by quantity",
              {k: f"{v:.2e}" for k, v in by_quantity.items()}, f"; the fist at contact {at_contact * 1000:.1f} mm off,",
              f"through the episode {fist_after:.4f} m; impulse {totals[0]:.3f} vs {totals[1]:.3f} N s;",
              f"peak speed {peaks[0]:.3f} vs {peaks[1]:.3f} m/s")
        for name, value in zip(names, difference, strict=True):
            assert value <= BEFORE_CONTACT[quantity(name)], f"placement {placement}: {name} differs by {value:.3g} before contact"
        assert at_contact <= AT_CONTACT_FIST_M, f"placement {placement}: the fist lands {at_contact:.4f} m from its mirror image"
        assert fist_after <= WHOLE_EPISODE_FIST_M, f"placement {placement}: a fist is {fist_after:.3f} m from its mirror image"
        assert impulse(right_hand, "l").max() == 0 and impulse(other, "r").max() == 0, "only the punching fist hits"
        mirrored_hits = np.flatnonzero(impulse(other, "l") > 1e-3)
        assert mirrored_hits.size and abs(int(mirrored_hits[0]) - contact) <= 1, \
            f"placement {placement}: the right fist hits at frame {contact}, the mirrored left at {mirrored_hits[:1]}"
        assert abs(totals[0] - totals[1]) <= SHARE * totals[0], f"placement {placement}: impulses {totals}"
        assert abs(peaks[0] - peaks[1]) <= SHARE * peaks[0], f"placement {placement}: peak speeds {peaks}"
