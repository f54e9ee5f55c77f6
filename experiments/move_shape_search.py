"""What shape the trajectory search finds for a reward from a stance's guard, placement by placement.

    .venv/bin/python experiments/move_shape_search.py --reward experiments/rewards.py:hook_bent --guard southpaw \
        --distances 0.55 0.625 0.7 0.775 0.85 --sides -0.15 0 0.15

Runs TTR at every placement at once (the rollouts after a lead-in holding the guard, the search's mean starting at
that guard), then prints each placement's best punch: whether it touched, the time to contact, the fist's peak speed,
the side approach and the elbow bend at contact (the naturalness report's figures, docs/naturalness.md)."""

import argparse

import numpy as np

from punch_trainer.learn.search import SearchArgs, placement_search
from punch_trainer.learn.volume import holding
from punch_trainer.report.naturalness import punch_naturalness
from punch_trainer.reward.rewards import load_reward
from punch_trainer.reward.style import style_named
from punch_trainer.sim.conditions import EpisodeConditions
from punch_trainer.sim.rollouts import RolloutPool


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--reward", required=True)
    parser.add_argument("--style", default="boxing")
    parser.add_argument("--guard", default="southpaw")
    parser.add_argument("--distances", type=float, nargs="+", default=[0.55, 0.625, 0.7, 0.775, 0.85])
    parser.add_argument("--sides", type=float, nargs="+", default=[-0.15, 0.0, 0.15])
    parser.add_argument("--height", type=float, default=1.35)
    parser.add_argument("--iterations", type=int, default=80)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    reward = load_reward(args.reward, style=style_named(args.style, 1.0))
    placements = [EpisodeConditions(distance_m=d, height_m=args.height, side_m=s) for d in args.distances for s in args.sides]
    with RolloutPool(2, 64) as pool:
        guard = np.asarray(pool.info.stance_guard_actions[args.guard], dtype=np.float32)
        decisions = reward.frames // pool.info.decision_period
        search = SearchArgs(reward=args.reward, style=args.style, frames=reward.frames, seed=args.seed,
                            iterations=args.iterations, rollouts=64, processes=2, characters_per_process=64)
        bests = placement_search(search, reward, pool, True, placements=placements,
                                 init_mu=np.tile(guard, (decisions, 1)), lead_in=holding(guard))
        names, hz = pool.info.feature_names, pool.info.physics_hz
    print("distance side | return touched time_s speed_mps side_deg elbow_deg rise path/chord")
    for placement, best in zip(placements, bests, strict=True):
        n = punch_naturalness(best.best_features, names, hz)
        print(f"{placement.distance_m:.3f} {placement.side_m:+.2f} | {best.best_return:7.2f} {n.time_to_contact_s is not None!s:5} "
              f"{n.time_to_contact_s or 0:.3f} {n.fist_peak_speed_mps:.2f} {n.side_angle_at_contact_deg:4.0f} "
              f"{n.elbow_bend_at_contact_deg:4.0f} {n.rise_share_at_contact:+.2f} {n.path_over_chord:.2f}")


if __name__ == "__main__":
    main()
