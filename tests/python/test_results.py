"""`punch results`: the shipped policies' figures in the docs are the evaluator's output, written by one command."""

import re
import shutil

import pytest

from conftest import PROJECT_ROOT
from punch_trainer.cli import main as cli_main
from punch_trainer.pipelines import bench, results
from punch_trainer.pipelines.results import Measurement, ResultsError, shipped_recipes, write_results


def marked_table(text: str) -> str:
    start, end = results.SUMMARY_MARKERS
    found = re.search(rf"{re.escape(start)}(.*?){re.escape(end)}", text, re.S)
    assert found, "the policies' README has lost its punch results markers"
    return found.group(1)


def test_every_shipped_policy_has_its_generated_row_and_section():
    """A recipe added (a new move) without `punch results` run again leaves the docs behind: this says so."""
    table = marked_table(results.POLICIES_README.read_text())
    benchmarks = bench.BENCHMARKS_FILE.read_text()
    for recipe in shipped_recipes():
        assert f"`{recipe.policy.name}`" in table, f"run punch results: {recipe.policy.name} has no row"
        assert f"<!-- The shipped {recipe.name}:start -->" in benchmarks, f"run punch results: no section for {recipe.name}"
    assert "<!-- The shipped policies:start -->" in benchmarks


def test_a_readme_without_its_markers_is_refused(tmp_path, monkeypatch):
    readme = tmp_path / "README.md"
    readme.write_text("# Default policies\n\nno table here\n")
    monkeypatch.setattr(results, "POLICIES_README", readme)
    monkeypatch.setattr(bench, "BENCHMARKS_FILE", tmp_path / "BENCHMARKS.md")
    with pytest.raises(ResultsError, match="markers"):
        write_results([], {}, "punch results")
    assert readme.read_text() == "# Default policies\n\nno table here\n"


@pytest.mark.godot
def test_results_measure_a_recipes_policy_and_rewrite_the_docs(tmp_path, monkeypatch, capsys):
    """A real (small) run: every measurement through Godot, the summary row in both files, one section per policy,
    replaced whole by a second run, the text around it kept."""
    readme = tmp_path / "README.md"
    shutil.copyfile(results.POLICIES_README, readme)
    benchmarks = tmp_path / "BENCHMARKS.md"
    benchmarks.write_text("# Benchmarks\n\nkept\n")
    monkeypatch.setattr(results, "POLICIES_README", readme)
    monkeypatch.setattr(bench, "BENCHMARKS_FILE", benchmarks)
    monkeypatch.setattr(results, "MEASUREMENTS", (
        Measurement("held_out", {"placements": 3, "sigmas": [0.0, 0.3], "search_iterations": 0, "conditions": ["every decision"]}),
        Measurement("moving", {"placements": 2, "conditions": ["standing", "forward 0.7 m/s"]}),
        Measurement("sizes", {"placements": 2, "conditions": ["0.75", "1"]}),
        Measurement("hands", {"placements": 2, "sigmas": [0.0, 0.3]}),
        Measurement("stance", {"placements": 2, "conditions": ["jab, orthodox (left, lead)"]}),
    ))
    arguments = ["results", str(PROJECT_ROOT / "recipes" / "straight.toml"), "--out", str(tmp_path / "runs")]
    for _ in range(2):
        assert cli_main.main(arguments) == 0
    table = marked_table(readme.read_text())
    row = next(line for line in table.splitlines() if line.startswith("| `straight.onnx`"))
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert cells[2].endswith("of 3") and cells[3].endswith("of 6"), row
    assert cells[6].endswith("(arms 0.75)") or cells[6].endswith("(arms 1)"), row
    assert cells[7].endswith("of 4") and cells[8].endswith("of 2") and cells[9].endswith("(jab, orthodox (left, lead))"), row
    assert "Measured by `punch results" in table and "hook.onnx" not in table
    text = benchmarks.read_text()
    assert "kept" in text and text.count("## The shipped straight") == 1 and text.count("## The shipped policies") == 1
    assert "--scenario moving --placements 2 --conditions standing 'forward 0.7 m/s'" in text
    assert "| standing | 0.00 | 2 |" in text and "![" not in text
    assert (tmp_path / "runs" / "straight" / "held_out" / "report.md").is_file()
    capsys.readouterr()
