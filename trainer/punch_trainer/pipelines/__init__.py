"""The pipelines: the long-running work behind each command (search, train, evaluate, replay, render, bench,
experiments, selfcheck), made of the layers below (`sim`, `learn`, `report`) and driven by `cli`."""
