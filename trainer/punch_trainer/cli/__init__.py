"""The `punch` command: its argument parsers, generated from the `*Args` dataclasses (`arguments`), and what
each subcommand prints (`main`). The top layer: imports any other, and nothing imports it; the work itself is
in `pipelines`."""
