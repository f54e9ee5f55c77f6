"""`punch experiment style`: what the motion style (reward/style.py) does to the trajectory search's punches.

Each style searches at the same placements inside the shipped policies' reach volume, with the same seeds and
budget; the table gives the naturalness figures (docs/naturalness.md) of every placement's best punch, as
medians, beside the capture's, and how many hit with the reward alone (the style's discount taken out)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from punch_trainer.learn.reach import placement
from punch_trainer.learn.search import SearchArgs, placement_search
from punch_trainer.options import bounds
from punch_trainer.report.naturalness import capture_figures, naturalness_table, punch_naturalness, summarise
from punch_trainer.reward.rewards import first_right_contact, load_reward, score
from punch_trainer.reward.style import style_label, style_named
from punch_trainer.sim.rollouts import RolloutPool

PLACEMENTS_M = ((0.72, 1.35, 0.0), (0.62, 1.2, -0.2), (0.82, 1.5, 0.2), (0.7, 1.45, -0.1))
"""distance, height and side (m) of the bag, inside the shipped policies' reach volume: its middle, near and
low to the right, far and high to the left, and one more"""


@dataclass
class StyleExperimentArgs:
    """The options of `punch experiment style`."""

    reward: str = "straight"
    """the reward every style is added to"""
    styles: list[str] = field(default_factory=lambda: ["none", "boxing"])
    """the styles to compare: none, boxing, or FILE.toml:NAME (experiments/styles.toml holds the ones tried)"""
    seeds: list[int] = field(default_factory=lambda: [0, 1], metadata=bounds(0, 2**32 - 1, max_items=16))
    """search seeds"""
    iterations: int = field(default=100, metadata=bounds(1, 10_000))
    """most iterations of each search"""
    rollouts: int = field(default=32, metadata=bounds(1, 4096))
    """rollouts per placement and iteration"""


@dataclass(frozen=True)
class StyleRow:
    style: str
    punches: int
    hits: int
    """punches whose right fist touched the bag with a positive return of the reward alone"""
    median_return: float
    """median return of the reward alone (without the style's discount)"""


def style_experiment(args: StyleExperimentArgs, progress: bool = True) -> tuple[list[StyleRow], list[str]]:
    """Runs every style's searches; returns its rows and the naturalness table (markdown lines)."""
    placements = [placement(*p) for p in PLACEMENTS_M]
    rows, columns = [], []
    with RolloutPool(1, 64) as pool:
        names = pool.info.feature_names
        for name in args.styles:
            style = style_named(name)
            reward = load_reward(args.reward, style=style)
            plain = load_reward(args.reward)
            punches, returns, hits = [], [], 0
            for seed in args.seeds:
                search_args = SearchArgs(reward=args.reward, style=name, seed=seed, iterations=args.iterations,
                                         rollouts=args.rollouts, plateau_iterations=30)
                for best in placement_search(search_args, reward, pool, progress, placements=placements):
                    plain_return = float(score(plain, best.best_features, names))
                    touched = bool(first_right_contact(best.best_features, names)[0])
                    hits += int(touched and plain_return > 0)
                    returns.append(plain_return)
                    punches.append(punch_naturalness(best.best_features, names, float(pool.info.physics_hz)))
            summary = summarise(punches)
            label = style_label(style)
            columns.append((label, summary))
            rows.append(StyleRow(label, len(punches), hits, float(np.median(returns))))
    return rows, naturalness_table(columns, capture_figures())
