"""The actor-critic network (paper Fig. 5): fully connected, with the actor's mean and sigma as separate
heads so that replay can override sigma, and a critic for V. Observation normalisation is part of the
module, so it is part of the exported ONNX graph."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

SIGMA_MIN, SIGMA_MAX = 1e-3, 2.0


def layer(inputs: int, outputs: int, gain: float = np.sqrt(2)) -> nn.Linear:
    linear = nn.Linear(inputs, outputs)
    nn.init.orthogonal_(linear.weight, gain)
    nn.init.zeros_(linear.bias)
    return linear


class ActorCritic(nn.Module):
    obs_mean: torch.Tensor
    obs_std: torch.Tensor
    def __init__(self, obs_dim: int, act_dim: int, hidden: int = 128, *, seed: int = 0):
        """The initial weights depend on `seed` only (not on the global random state), so runs reproduce."""
        super().__init__()
        self.register_buffer("obs_mean", torch.zeros(obs_dim))
        self.register_buffer("obs_std", torch.ones(obs_dim))
        with torch.random.fork_rng():
            torch.manual_seed(seed)
            self.actor = nn.Sequential(layer(obs_dim, hidden), nn.Tanh(), layer(hidden, hidden), nn.Tanh())
            self.mean_head = layer(hidden, act_dim, gain=0.01)
            self.log_sigma_head = layer(hidden, act_dim, gain=0.01)
            self.critic = nn.Sequential(layer(obs_dim, hidden), nn.Tanh(), layer(hidden, hidden), nn.Tanh(), layer(hidden, 1, gain=1.0))

    def set_normalization(self, observations: np.ndarray) -> None:
        """Fixes the observation normalisation from sample observations [n, obs_dim]."""
        self.obs_mean.copy_(torch.as_tensor(observations.mean(axis=0), dtype=torch.float32))
        self.obs_std.copy_(torch.as_tensor(observations.std(axis=0) + 1e-3, dtype=torch.float32))

    def normalize(self, obs: torch.Tensor) -> torch.Tensor:
        return torch.clamp((obs - self.obs_mean) / self.obs_std, -10.0, 10.0)

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The policy: mean in [-1, 1] and sigma, each [batch, act_dim]. This is what is exported."""
        features = self.actor(self.normalize(obs))
        mean = torch.tanh(self.mean_head(features))
        sigma = torch.exp(torch.clamp(self.log_sigma_head(features), np.log(SIGMA_MIN), np.log(SIGMA_MAX)))
        return mean, sigma

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        value: torch.Tensor = self.critic(self.normalize(obs)).squeeze(-1)
        return value

    def distribution(self, obs: torch.Tensor, sigma_floor: float = 0.0,
                     sigma_cap: torch.Tensor | None = None) -> torch.distributions.Normal:
        """The action distribution; `sigma_floor` keeps its sigma from shrinking below that value (training
        noise the policy must learn to recover from; the exported sigma head is unchanged), and `sigma_cap`
        [act_dim], where given, holds each degree of freedom's sigma at most there (a style's narrow guard),
        the floor included."""
        mean, sigma = self(obs)
        sigma = sigma.clamp(min=sigma_floor)
        return torch.distributions.Normal(mean, sigma if sigma_cap is None else torch.minimum(sigma, sigma_cap))


class Actor(nn.Module):
    """The exported part: obs -> (mean, sigma)."""

    def __init__(self, model: ActorCritic):
        super().__init__()
        self.model = model

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.model.forward(obs)
