"""The reward layer: what a punch earns. The reward presets and the scoring of a user's reward function
(`rewards`), the sandbox its code runs in, another process (`sandbox`), and the motion style the product adds to
any reward (`style`). Below the simulator, whose envs score their steps with it; it imports no other layer."""
