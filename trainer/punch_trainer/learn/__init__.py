"""The learning layer: trajectory search (TTR) and its baselines, trajectory datasets, the actor-critic,
pretraining, A2C, checkpoints and ONNX export. Imports `sim` only."""
