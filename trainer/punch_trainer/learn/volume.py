"""Training over the reach volume (the paper's future work, "multi-trajectory initialisation"):

1. Trajectory search at a grid of bag placements over the volume, all at once, warm-started from the search
   at the default placement, each placement also trying its neighbours' best (`placement_search`).
2. Every placement's best trajectory goes into one dataset; the actor-critic is pretrained on all of them,
   with observation statistics from the whole distribution of A2C's episodes (`distribution_observations`).
3. A2C with every episode's conditions drawn from the volume (`ConditionSampler`): a random placement and,
   in some, the bag already swinging; the policy's own sampling noise (sigma from 0.3, never below A2C's
   `sigma_floor`, 0.2 by default here) is the training-time action noise it learns to correct: without the
   floor the learned sigma shrank to 0.03-0.44 and the policies corrected less (BENCHMARKS.md). Every
   episode starts from the guard: a punch asked for in another pose (after an earlier punch, mid-recovery)
   goes to guard first in the game (`PunchController.guard_first`), which measured better than teaching the
   policy those starts (experiments/measurements.md, "Target-aware policies").
   Episodes that start after a lead-in of real actions remain an option (`lead_in_every`). A share of episodes
   may start in a boxing stance's guard instead (`stance_share`): a lead-in holds that guard's action first, so a
   policy learns to punch from where `PunchController.stance_pose` holds a character.

Success (`success`): a positive return and the right fist touched the bag, as `punch eval` counts it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.reach import ReachVolume
from punch_trainer.reward.rewards import EpisodeScorer, Reward, first_right_contact
from punch_trainer.sim.conditions import (
    ARM_SCALE_RANGE,
    SEGMENT_SCALE_RANGE,
    UPPER_ARM_SHARE,
    EpisodeConditions,
    EpisodeStart,
    arm_scale,
)
from punch_trainer.sim.env import PunchVectorEnv

STANCE_LEAD_IN_DECISIONS = 8
"""decisions a lead-in holds a stance's guard before the episode (0.33 s at 120 Hz and 5 frames a decision: the
trunk's 30 degree turn has settled)"""


def holding(action: np.ndarray | list[float]) -> np.ndarray:
    """A lead-in [STANCE_LEAD_IN_DECISIONS, A] that holds `action` (a stance's guard: the server's
    `stance_guard_actions`)."""
    return np.tile(np.asarray(action, dtype=np.float32), (STANCE_LEAD_IN_DECISIONS, 1))


DISTRIBUTION_DRAWS = 10**9
"""the first "update" number of the draws for the observation statistics (A2C updates count from 1)"""


@dataclass
class VolumeArgs:
    grid: tuple[int, int, int] = (3, 3, 3)
    """search placements along distance, height and side"""
    search_iterations: int = 60
    search_rollouts: int = 16
    """rollouts per placement and iteration"""
    search_sigma_init: float = 0.5
    """the warm-started tables' initial sigma (the default-placement search starts at 1)"""
    moving_share: float = 0.25
    """share of A2C episodes whose bag swings at the start"""
    default_share: float = 0.0
    """share of A2C episodes with the bag hanging still at the default placement (where
    `PunchSpec.default_target_offset()` and the demo put it)"""
    after_punch_share: float = 0.35
    """share of lead-in episodes that start where an earlier punch is: played up to a random decision of its second
    half (at its contact, drawing back, at its end), as a combo's next punch starts at the cancel window"""
    recovering_share: float = 0.2
    """share of lead-in episodes that start mid-recovery (a whole punch, then 1 to 4 decisions back toward guard)"""
    lead_in_every: int = 0
    """every k-th A2C update starts its episodes after lead-ins (0: never, the default since guard_first; they
    cost frames and, at 2, left the policies missing a swinging bag more often): a policy for punches started
    wherever the arms are (`PunchController.guard_first` off, combos)"""
    stance_share: float = 0.0
    """share of A2C episodes (and validation placements) that start in a boxing stance's guard, the orthodox and
    the southpaw alike (the right hand as the rear hand and as the lead), after a lead-in that holds it; the others
    start in the square guard"""
    validation_placements: int = 64
    motions: MotionRange | None = None
    """the body and target motions of A2C's episodes (None: every character stands, every target hangs)"""
    arms: ArmRange | None = None
    """the arm sizes of A2C's characters (None: every character has the scene's arms)"""


@dataclass(frozen=True)
class MotionRange:
    """What A2C's episodes draw when characters punch on the move (docs/moving.md): the character's own walk,
    turn, lunge and bob (`EpisodeConditions.body_*`, carried by the kinematic pelvis) and a target carried past it.
    Each range reaches a little beyond the figures the policies promise (1.4 m/s, 120 degrees/s, 1 m/s), so
    those are inside what they trained on, not at its edge."""

    moving_share: float = 0.6
    """share of episodes whose character moves"""
    walk_mps: float = 1.6
    """largest walking speed, in any horizontal direction (half the draws along the four axes)"""
    turn_share: float = 0.5
    """share of moving characters that also turn"""
    turn_rad_s: float = float(np.radians(135.0))
    """largest turning rate, either way"""
    lunge_share: float = 0.2
    lunge_m: tuple[float, float] = (0.1, 0.35)
    bob_share: float = 0.5
    bob_m: float = 0.035
    """largest bob amplitude (walking bobs about 3 cm)"""
    glide_share: float = 0.25
    """share of the other episodes whose target is carried past (its rope moving at a constant velocity)"""
    glide_mps: float = 1.2
    """largest speed of a carried target, in any horizontal direction"""
    ride_share: float = 0.4
    """share of moving characters whose target rides along with them (both moved as one, as a game moving a
    character and its opponent together, or two fighters circling: the target's place relative to the
    character hardly changes while both move)"""

    def draw(self, rng: np.random.Generator, bags: list[EpisodeConditions]) -> list[EpisodeConditions]:
        """`bags` with motions drawn for some of them (a swinging bag keeps its swing and gets no glide)."""
        out = []
        for bag in bags:
            changes: dict[str, float | bool] = {}
            if rng.uniform() < self.moving_share:
                speed = rng.uniform(0.0, self.walk_mps)
                angle = (rng.integers(4) * np.pi / 2) if rng.uniform() < 0.5 else rng.uniform(0.0, 2 * np.pi)
                changes["body_side_mps"], changes["body_forward_mps"] = speed * np.sin(angle), speed * np.cos(angle)
                if rng.uniform() < self.turn_share:
                    changes["body_turn_rad_s"] = rng.uniform(-self.turn_rad_s, self.turn_rad_s)
                if rng.uniform() < self.lunge_share:
                    changes["body_lunge_m"] = rng.uniform(*self.lunge_m)
                if rng.uniform() < self.bob_share:
                    changes["body_bob_m"] = rng.uniform(0.0, self.bob_m)
            swinging = bag.velocity_side_mps != 0.0 or bag.velocity_forward_mps != 0.0
            if not swinging and "body_side_mps" in changes and rng.uniform() < self.ride_share:
                changes["bag_rides"] = True
            elif not swinging and rng.uniform() < self.glide_share:
                speed, angle = rng.uniform(0.0, self.glide_mps), rng.uniform(0.0, 2 * np.pi)
                changes.update(bag_glides=True, velocity_side_mps=speed * np.sin(angle),
                               velocity_forward_mps=speed * np.cos(angle))
            out.append(bag.over({name: value if isinstance(value, bool) else float(value)
                                 for name, value in changes.items()}))
        return out


@dataclass(frozen=True)
class ArmRange:
    """The arm sizes A2C's characters get (`EpisodeConditions.arms_*`), so one policy punches with arms sized to any
    rig `PunchCharacter.size_arms` accepts (README, "Your own character"): the arm (shoulder to fist centre) 0.75 to
    1.25 times the scene's, each segment 0.65 to 1.35 times, the shoulders up to 4 cm wider or narrower each.
    Scales fall on a grid of `step`, so the training server builds each sized body once."""

    sized_share: float = 0.6
    """share of episodes whose character's arms are not the scene's"""
    arm_scale: tuple[float, float] = ARM_SCALE_RANGE
    segment_scale: tuple[float, float] = SEGMENT_SCALE_RANGE
    shoulder_shift_m: float = 0.04
    step: float = 0.05

    def draw(self, rng: np.random.Generator, bags: list[EpisodeConditions]) -> list[EpisodeConditions]:
        """`bags` with arm sizes drawn for some of them."""
        out = []
        for bag in bags:
            if rng.uniform() >= self.sized_share:
                out.append(bag)
                continue
            upper, forearm = self.segments(rng)
            shift = 0.01 * round(rng.uniform(-self.shoulder_shift_m, self.shoulder_shift_m) / 0.01)
            out.append(bag.over({"arms_upper_arm_scale": upper, "arms_forearm_scale": forearm,
                                 "arms_shoulder_shift_m": shift}))
        return out

    def segments(self, rng: np.random.Generator) -> tuple[float, float]:
        """(upper arm, forearm) scales on the grid: the arm's scale uniform over its range, then the forearm's
        uniform over what that arm allows. (Drawing the two segments uniformly instead puts an arm within 0.07 of
        either end of its range in only 17% of draws: the shortest arms were the hook's weakest.)"""
        share = UPPER_ARM_SHARE
        low, high = self.segment_scale
        while True:  # rounding to the grid may leave the ranges
            arm = rng.uniform(*self.arm_scale)
            forearm = rng.uniform(max(low, (arm - share * high) / (1 - share)),
                                  min(high, (arm - share * low) / (1 - share)))
            upper = (arm - (1 - share) * forearm) / share
            upper, forearm = (self.step * np.round(np.array([upper, forearm]) / self.step)).tolist()
            if low <= upper <= high and low <= forearm <= high and \
                    self.arm_scale[0] <= arm_scale(upper, forearm) <= self.arm_scale[1]:
                return upper, forearm


class ConditionSampler:
    """Draws the conditions of every A2C episode from the reach volume: `options` for `PunchVectorEnv.reset`."""

    def __init__(self, reach: ReachVolume, punches: np.ndarray, args: VolumeArgs, seed: int,
                 default_bag: EpisodeConditions, stance_guards: np.ndarray | None = None):
        """`punches`: raw action sequences [K, decisions, A] (the search's bests) that lead-ins replay;
        `default_bag`: the default placement, for `args.default_share`; `stance_guards`: [G, A], the actions that
        hold the orthodox and the southpaw guard (the server's `stance_guard_actions`), for `args.stance_share`."""
        if args.stance_share > 0 and stance_guards is None:
            raise ValueError("a stance share needs the stances' guard actions")
        self.reach, self.punches, self.args, self.seed, self.default_bag = reach, punches, args, seed, default_bag
        self.stance_guards = stance_guards

    def __call__(self, count: int, update: int) -> EpisodeStart:
        """The conditions of update `update`'s episodes (drawn from the seed and the update alone, so a resumed
        run draws what an uninterrupted one would)."""
        rng = np.random.default_rng([self.seed, update])
        lead_ins = bool(self.reach.any_start_pose and self.args.lead_in_every and update % self.args.lead_in_every == 0)
        bags = self.reach.sample(rng, count, moving=0.0 if lead_ins else self.args.moving_share)
        if self.args.default_share > 0:
            at_default = rng.uniform(size=count) < self.args.default_share
            bags = [self.default_bag if spot else bag for bag, spot in zip(bags, at_default, strict=True)]
        if self.args.motions is not None and not lead_ins:
            bags = self.args.motions.draw(rng, bags)
        if self.args.arms is not None:
            bags = self.args.arms.draw(rng, bags)
        if lead_ins:
            return EpisodeStart(bags, self.lead_ins(rng, count))
        if self.args.stance_share > 0:
            return EpisodeStart(bags, self.stance_lead_ins(rng, count))
        return EpisodeStart(bags)

    def stance_lead_ins(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """[count, STANCE_LEAD_IN_DECISIONS, A]: for `args.stance_share` of the characters, a stance's guard held
        (orthodox or southpaw, even odds); zeros (the square guard) for the others."""
        assert self.stance_guards is not None
        out = np.zeros((count, STANCE_LEAD_IN_DECISIONS, self.stance_guards.shape[1]), dtype=np.float32)
        in_stance = rng.uniform(size=count) < self.args.stance_share
        stances = rng.integers(len(self.stance_guards), size=count)
        out[in_stance] = self.stance_guards[stances[in_stance]][:, None, :]
        return out

    def lead_ins(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """[count, decisions + 4, A]: zeros (a start from the guard at rest), a punch played up to a random decision
        of its second half (`after_punch_share`), or a whole punch and 1 to 4 decisions of the guard target
        (mid-recovery); aligned to end together."""
        decisions, action_size = self.punches.shape[1:]
        out = np.zeros((count, decisions + 4, action_size), dtype=np.float32)
        kinds = rng.uniform(size=count)
        for slot in range(count):
            punch = self.punches[rng.integers(len(self.punches))]
            if kinds[slot] < self.args.after_punch_share:
                played = int(rng.integers(decisions // 2, decisions + 1))
                out[slot, decisions + 4 - played:] = punch[:played]
            elif kinds[slot] < self.args.after_punch_share + self.args.recovering_share:
                back = int(rng.integers(1, 5))
                out[slot, 4 - back:decisions + 4 - back] = punch  # then `back` decisions toward guard
        return out


def success(returns: np.ndarray, features: np.ndarray, names: list[str]) -> np.ndarray:
    """Per episode: a positive return and the right fist touched the bag (features [..., frames, F])."""
    touched, _ = first_right_contact(features, names)
    result: np.ndarray = (returns > 0) & touched
    return result


def success_interval(successes: int, punches: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson's score interval (95% at the default z) of a success rate from `successes` of `punches`: how far
    the rate of another set of placements could lie. At 128 punches a rate of 97% spans about 92-99%, so two
    policies a few points apart there are not yet measured apart; more placements narrow it (`punch eval`, `punch eval-sizes`)."""
    if punches <= 0:
        return (0.0, 1.0)
    rate = successes / punches
    centre = (rate + z * z / (2 * punches)) / (1 + z * z / punches)
    half = z * np.sqrt(rate * (1 - rate) / punches + z * z / (4 * punches * punches)) / (1 + z * z / punches)
    return (float(max(0.0, centre - half)), float(min(1.0, centre + half)))


def run_policy(model: ActorCritic, env: PunchVectorEnv, reward: Reward,
               options: EpisodeStart | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One episode on every character with the policy's mean actions: returns [N] and features [N, frames, F]."""
    obs, _ = env.reset(options=options)
    returns, frames, scorer = np.zeros(env.num_envs), [], EpisodeScorer(reward, env.feature_names)
    while True:
        with torch.no_grad():
            mean, _ = model(torch.as_tensor(obs))
        obs, _, terminated, truncated, info = env.step(mean.numpy())
        returns += scorer.add(info["features"])[0]
        frames.append(info["features"])
        if np.all(terminated | truncated):
            return returns, np.concatenate(frames, axis=1)


@dataclass(frozen=True)
class Validation:
    """A policy's noise-free episodes at fixed validation placements (`validate`)."""

    mean_return: float
    """the mean episode return"""
    success_rate: float
    """the share of episodes that succeeded (`success`), from 0 to 1"""

    def to_json(self) -> dict[str, float]:
        """As a policy's training summary stores it."""
        return {"return": self.mean_return, "success": self.success_rate}


def validate(model: ActorCritic, env: PunchVectorEnv, reward: Reward,
             placements: list[EpisodeConditions] | EpisodeStart) -> Validation:
    """Noise-free mean return and success rate over fixed validation placements (one per character; an
    `EpisodeStart` when they start after lead-ins)."""
    start = placements if isinstance(placements, EpisodeStart) else EpisodeStart(placements)
    returns, features = run_policy(model, env, reward, start)
    return Validation(float(returns.mean()), float(success(returns, features, env.feature_names).mean()))


def distribution_observations(env: PunchVectorEnv, conditions: ConditionSampler, punches: np.ndarray,
                              batches: int = 2) -> np.ndarray:
    """Observations of the search's best punches replayed open loop under A2C's conditions (placements,
    swinging bags, lead-ins): what the policy will see, for its normalisation."""
    observations = []
    for batch in range(batches):
        options = conditions(env.num_envs, DISTRIBUTION_DRAWS + batch)  # draws no A2C update makes
        obs, _ = env.reset(options=options)
        chosen = punches[np.arange(env.num_envs) % len(punches)]
        for decision in range(chosen.shape[1]):
            observations.append(obs)
            obs, *_ = env.step(chosen[:, decision])
    return np.concatenate(observations).astype(np.float32)
