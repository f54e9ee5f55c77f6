"""A2C's arithmetic without a simulator: the advantage estimates against values computed by hand, and the
diagnostics an update writes into the run's metrics and plots."""

import csv

import torch

from punch_trainer.learn.a2c import A2CArgs, advantages_and_returns
from punch_trainer.report.a2c_report import METRICS_FILE, write_a2c_report

# Two characters, three decisions each: rewards[t, n] and the critic's values[t, n]. Every number here, and
# every sum and product below, is exact in float32, so the comparisons are exact.
REWARDS = torch.tensor([[1.0, 0.0],
                        [2.0, 0.0],
                        [4.0, 8.0]])
VALUES = torch.tensor([[0.5, 1.0],
                       [1.5, 2.0],
                       [3.0, 4.0]])


def test_generalised_advantage_estimates_match_a_hand_computation():
    """gamma 0.5, lambda 0.5. An episode ends at its last decision (every episode has the same length), so
    nothing is bootstrapped there: delta_t = r_t + gamma V_{t+1} - V_t with V_3 = 0, and
    A_t = delta_t + gamma lambda A_{t+1}."""
    # Character 0: delta_2 = 4 - 3 = 1,              A_2 = 1
    #              delta_1 = 2 + 0.5 * 3 - 1.5 = 2,  A_1 = 2 + 0.25 * 1 = 2.25
    #              delta_0 = 1 + 0.5 * 1.5 - 0.5 = 1.25, A_0 = 1.25 + 0.25 * 2.25 = 1.8125
    # Character 1: delta_2 = 8 - 4 = 4,              A_2 = 4
    #              delta_1 = 0 + 0.5 * 4 - 2 = 0,    A_1 = 0 + 0.25 * 4 = 1
    #              delta_0 = 0 + 0.5 * 2 - 1 = 0,    A_0 = 0 + 0.25 * 1 = 0.25
    expected = torch.tensor([[1.8125, 0.25],
                             [2.25, 1.0],
                             [1.0, 4.0]])
    advantages, critic_targets = advantages_and_returns(REWARDS, VALUES, best_episode_return=0.0,
                                                        args=A2CArgs(gamma=0.5, gae_lambda=0.5))
    assert torch.equal(advantages, expected)
    assert torch.equal(critic_targets, expected + VALUES)  # the critic learns V_t + A_t: [[2.3125, 1.25], [3.75, 3], [4, 8]]


def test_with_lambda_one_the_advantage_is_the_discounted_return_to_go_minus_the_value():
    # gamma 0.5: character 0's returns to go are 1 + 0.5 * (2 + 0.5 * 4) = 3, 2 + 0.5 * 4 = 4, 4;
    # character 1's are 0.25 * 8 = 2, 0.5 * 8 = 4, 8.
    advantages, critic_targets = advantages_and_returns(REWARDS, VALUES, 0.0, A2CArgs(gamma=0.5, gae_lambda=1.0))
    returns_to_go = torch.tensor([[3.0, 2.0], [4.0, 4.0], [4.0, 8.0]])
    assert torch.equal(advantages, returns_to_go - VALUES)
    assert torch.equal(critic_targets, returns_to_go)


def test_the_papers_advantage_is_the_best_return_so_far_minus_the_episodes_return():
    # Episode returns 7 and 8, best so far 10: every decision of character 0 gets 3, of character 1 gets 2;
    # the critic learns the undiscounted returns to go.
    advantages, critic_targets = advantages_and_returns(REWARDS, VALUES, 10.0, A2CArgs(advantage="paper"))
    assert torch.equal(advantages, torch.tensor([[3.0, 2.0]] * 3))
    assert torch.equal(critic_targets, torch.tensor([[7.0, 8.0], [6.0, 8.0], [4.0, 8.0]]))


def test_the_diagnostics_go_into_the_metrics_file_and_the_plot(tmp_path):
    """Row 0 (before the first update) has no losses; its cells stay empty. Every term has its column."""
    history = [{"update": 0, "episodes": 0, "env_steps": 0, "elapsed_s": 0.0, "mean_return": float("nan"), "eval_return": 0.5,
                "eval_success": None}]
    for update in (1, 2, 3):
        history.append({"update": update, "episodes": 8 * update, "env_steps": 80 * update, "elapsed_s": float(update),
                        "mean_return": 0.4 + 0.1 * update, "eval_return": 0.5 + 0.1 * update, "eval_success": None,
                        "policy_loss": -0.01 * update, "value_loss": 2.0 / update, "entropy": 5.0 - update, "sigma_mean": 0.3 / update,
                        "reward/forward": 0.3 * update, "reward/sideways": 0.1})
    plots = write_a2c_report(tmp_path, history)
    with open(tmp_path / METRICS_FILE) as handle:
        rows = list(csv.DictReader(handle))
    assert [row["update"] for row in rows] == ["0", "1", "2", "3"]
    assert rows[0]["policy_loss"] == "" and float(rows[2]["value_loss"]) == 1.0
    assert float(rows[3]["reward/forward"]) == history[3]["reward/forward"] and rows[3]["reward/sideways"] == "0.1"
    assert [p.name for p in plots] == ["a2c_diagnostics.png"] and plots[0].stat().st_size > 10_000


def test_a_style_caps_the_sampling_sigma_of_the_guard_where_it_narrows_the_search():
    """Noise on the guard arm alone costs a styled punch all it earns, so A2C samples there no wider than the
    style's search does, the sigma floor included; without a style nothing is capped."""
    from dataclasses import replace

    from punch_trainer.learn.a2c import style_sigma_cap
    from punch_trainer.learn.policy import ActorCritic
    from punch_trainer.reward.rewards import load_reward
    from punch_trainer.reward.style import style_named

    model = ActorCritic(54, 10, seed=0)
    obs = torch.zeros(3, 54)
    plain = load_reward("straight")
    styled = replace(plain, style=style_named("boxing"))
    assert style_sigma_cap(plain, 10) is None
    cap = style_sigma_cap(styled, 10)
    sigma = model.distribution(obs, 0.2, cap).stddev
    expected = torch.tensor(styled.style.search_sigma).clamp(max=1.0).minimum(model(obs)[1].clamp(min=0.2))
    assert torch.allclose(sigma, expected.expand_as(sigma))
    assert torch.all(sigma[:, 6:] == 0.05) and torch.all(sigma[:, 0] == 0.1)  # the guard arm, the waist's flexion
    assert torch.all(model.distribution(obs, 0.2).stddev >= 0.2)
