"""The pipelines: the long-running work behind each command (search, train, recipe, evaluation and
its scenarios, replay, render, bench, experiments, selfcheck), made of the layers below and driven by `cli`."""
