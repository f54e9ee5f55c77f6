"""The simulator layer: starting Godot, the wire protocol, training servers and their restarts, open-loop
rollout pools, rewards, and the Gymnasium envs. Imports nothing else of the trainer (but `errors`)."""
