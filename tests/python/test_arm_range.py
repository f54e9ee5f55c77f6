"""The arm sizes A2C draws (`ArmRange`, `punch train --arm-range`): on the grid, inside what `size_arms` accepts,
the arm's length spread evenly over its range (so its ends are trained as often as its middle)."""

import numpy as np
import pytest

from punch_trainer.learn.volume import ArmRange
from punch_trainer.pipelines.train import arm_range
from punch_trainer.sim.conditions import ARM_SCALE_RANGE, SEGMENT_SCALE_RANGE, arm_scale


def draws(arms: ArmRange, count: int = 4000) -> np.ndarray:
    rng = np.random.default_rng(0)
    return np.array([arms.segments(rng) for _ in range(count)])


def test_sizes_lie_on_the_grid_inside_the_accepted_ranges_and_cover_the_arm_evenly():
    sizes = draws(ArmRange())
    arm = arm_scale(sizes[:, 0], sizes[:, 1])
    assert SEGMENT_SCALE_RANGE[0] <= sizes.min() and sizes.max() <= SEGMENT_SCALE_RANGE[1]
    assert ARM_SCALE_RANGE[0] <= arm.min() and arm.max() <= ARM_SCALE_RANGE[1]
    np.testing.assert_allclose(sizes / 0.05, np.round(sizes / 0.05), atol=1e-9)
    # Even over the arm: each fifth of its range holds about a fifth of the draws (segments drawn each evenly
    # put 13% of arms in either end's fifth and 28% in the middle one).
    fifths = np.histogram(arm, bins=5, range=ARM_SCALE_RANGE)[0] / len(arm)
    assert fifths.min() > 0.17 and fifths.max() < 0.23, fifths
    assert len({tuple(s) for s in sizes}) > 50, "upper arm and forearm vary independently of the arm's length"


def test_a_narrower_arm_range_keeps_every_arm_inside_it():
    arm = arm_scale(*draws(ArmRange(arm_scale=(0.75, 1.0))).T)
    assert arm.min() >= 0.75 and arm.max() <= 1.0
    assert arm_range([0.75, 1.0]) == (0.75, 1.0)
    for bad in ([1.0, 0.75], [0.8], [0.75, 0.9, 1.0]):
        with pytest.raises(ValueError, match="two arm scales"):
            arm_range(bad)
