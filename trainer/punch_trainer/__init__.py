"""punch_trainer: trains physics-based punching policies in headless Godot/Jolt.

Layers (each imports only those below it; ARCHITECTURE.md has the picture):
- `capture`: the motion capture (CMU 143/23, package data), its punches and the prior searches start from.
- `reward`: what a punch earns: the reward presets and scoring, the sandbox a user's reward runs in, the style.
- `sim`: the simulator: starting Godot, the wire protocol, training servers, rollout pools, episode conditions
  and the Gymnasium envs.
- `learn`: trajectory search, datasets, the actor-critic, pretraining, A2C, checkpoints and ONNX export.
- `report`: what a run did, for people: motion analysis, plots, the motion-capture comparison, Markdown.
- `pipelines`: the long-running work behind each command (search, train, recipe, evaluation, replay, render,
  bench, ...).
- `cli`: the `punch` command: options generated from the `*Args` dataclasses, the backend (`--ray`), output.
"""

import gymnasium

__version__ = "0.1.0"

# `gym.make("punch/Punch-v0")` (one character) and `gym.make_vec("punch/Punch-v0", num_envs=M)` (M characters
# in lockstep); importing the envs starts nothing until one is made.
if "punch/Punch-v0" not in gymnasium.registry:
    gymnasium.register("punch/Punch-v0", entry_point="punch_trainer.sim.env:PunchEnv",
                       vector_entry_point="punch_trainer.sim.env:make_vector_env")
