"""The simulator layer: starting Godot, the wire protocol, training servers and their restarts, open-loop
rollout pools, episode conditions, and the Gymnasium envs, which score their steps with the reward layer below."""
