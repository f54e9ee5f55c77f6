"""The `punch` command (`main`) and the pipelines behind its subcommands: search, train, pretrain, replay,
render, selfcheck, bench and the experiments. The top layer: imports any other, and nothing imports it."""
