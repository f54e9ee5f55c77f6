"""What A2C leaves in a training run: its history per update as a CSV file and a plot of the diagnostics
that say why a run learns or does not (returns, losses, entropy, sigma, each reward term)."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

from punch_trainer.report.plots import plot_a2c

METRICS_FILE = "a2c_metrics.csv"


def write_a2c_metrics(out: Path, history: list[dict[str, Any]]) -> Path:
    """One row per update (row 0: before the first update), one column per key any row has; a value a row
    lacks (row 0 has no losses, a term absent from a batch) is left empty."""
    columns = list(dict.fromkeys(key for row in history for key in row))
    path = out / METRICS_FILE
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns, restval="")
        writer.writeheader()
        writer.writerows(history)
    return path


def write_a2c_report(out: Path, history: list[dict[str, Any]]) -> list[Path]:
    """The metrics file and the diagnostics plot; returns the plots, for the run's report to show."""
    write_a2c_metrics(out, history)
    return plot_a2c(out, history)
