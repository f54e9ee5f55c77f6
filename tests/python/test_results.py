"""`punch results`: the shipped policies' figures in the docs are the evaluator's output, written by one command."""

import re
import shutil
from pathlib import Path

import pytest

from conftest import PROJECT_ROOT
from punch_trainer.cli import main as cli_main
from punch_trainer.pipelines import bench, results
from punch_trainer.pipelines.recipe import load_recipe
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
    assert f"<!-- {results.MOVES_SECTION}:start -->" in benchmarks, "run punch results: the six moves have no table"
    assert f"<!-- {results.COMBOS_SECTION}:start -->" in benchmarks, "run punch results: no combos and frame data"
    assert f"<!-- {results.HITS_SECTION}:start -->" in benchmarks, "run punch results: no taking hits"


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
    replaced whole by a second run (which reads the measurements back), the text around it kept."""
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
        Measurement("stance", {"placements": 2, "conditions": ["lead hand, orthodox (left)"]}),
        Measurement("body", {"placements": 2, "conditions": ["rear hand, orthodox (right)"]}),
        Measurement("stance_moving", {"placements": 2, "conditions": ["rear hand, moving: forward 0.7 m/s"]}),
    ))
    monkeypatch.setattr(results, "MOVESET_MEASUREMENTS", (
        Measurement("combos", {"placements": 2, "sigmas": [0.0], "conditions": ["1-2-3, southpaw"]}),
        Measurement("frame_data", {"placements": 2, "sigmas": [0.0], "conditions": ["1 jab"]}),
        Measurement("from_recovery", {"placements": 2, "sigmas": [0.0], "conditions": ["jab, then jab"]}),
        Measurement("blocks_uppercuts", {"placements": 2, "sigmas": [0.0], "conditions": ["lead uppercut, blocking 0.15 s before"]},
                    move="lead_uppercut"),
        Measurement("hits", {"placements": 2, "conditions": ["torso, front, 60 N s"]}),
    ))
    arguments = ["results", str(PROJECT_ROOT / "recipes" / "straight.toml"), "--out", str(tmp_path / "runs")]
    for _ in range(2):
        assert cli_main.main(arguments) == 0
    # The second run read every measurement back (the same policy file, the same commands) instead of playing it.
    assert capsys.readouterr().out.count("measured before") == len(results.MEASUREMENTS) + len(results.MOVESET_MEASUREMENTS)
    table = marked_table(readme.read_text())
    row = next(line for line in table.splitlines() if line.startswith("| `straight.onnx`"))
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert cells[2].endswith("of 3") and cells[3].endswith("of 6"), row
    assert cells[6].endswith("(arms 0.75)") or cells[6].endswith("(arms 1)"), row
    assert cells[7].endswith("of 4") and cells[8].endswith("of 2") and cells[9].endswith("(lead hand, orthodox (left))"), row
    assert "Measured by `punch results" in table and "hook.onnx" not in table
    text = benchmarks.read_text()
    assert "kept" in text and text.count("## The shipped straight") == 1 and text.count("## The shipped policies") == 1
    assert "--scenario moving --placements 2 --conditions standing 'forward 0.7 m/s'" in text
    assert "| standing | 0.00 | 2 |" in text and "![" not in text
    # The moveset's combos and frame data, with when each punch landed.
    assert text.count(f"## {results.COMBOS_SECTION}") == 1 and "| 1-2-3, southpaw | 0.00 | 2 |" in text
    combo_row = next(line for line in text.splitlines() if line.startswith("| 1-2-3, southpaw | 0.00 | 2 |"))
    assert "touched the target, each punch" in text and combo_row.rstrip(" |").count("%") >= 3 + 2, combo_row  # and which punch touched
    assert "| 1 jab | 0.00 | 2 |" in text and "contact to back in guard (s, median)" in text
    assert "| jab, then jab | 0.00 | 2 |" in text
    # The struck character, in its own section: both episodes back in guard, both staggered at 60 N s.
    hits = text.split(f"<!-- {results.HITS_SECTION}:start -->")[1].split(f"<!-- {results.HITS_SECTION}:end -->")[0]
    assert "| torso, front, 60 N s | 0.00 | 2 | 2 (100.0%) |" in hits and hits.rstrip().endswith("| 2 / 0 |"), hits
    assert "torso, front, 60 N s" not in text.split(f"<!-- {results.COMBOS_SECTION}:start -->")[1].split(":end -->")[0]
    # A measurement of one move's policy plays the moveset's file for it (the uppercut's), in the same section.
    assert "--policy addons/punch_controller/policies/uppercut.onnx --scenario blocks_uppercuts" in hits, hits
    assert "| lead uppercut, blocking 0.15 s before | 0.00 | 2 |" in hits, hits
    assert (tmp_path / "runs" / "straight" / "held_out" / "report.md").is_file()
    capsys.readouterr()


def test_the_moves_table_names_the_shape_each_move_misses():
    """`moves_table`: each move reads its policy's rows for its hand (the lead hand's move the lead row), and lists the
    boxer's figures it misses: here a hook that comes in straight and slow, and a jab slower than a cross. Where the
    controller said targets lay beyond the character's reach, the success over those in reach is shown beside."""
    def medians(**changes):
        base = {"time_to_contact_s": 0.12, "path_over_chord": 1.1, "fist_peak_speed_mps": 7.0, "side_angle_at_contact_deg": 40.0,
                "rise_share_at_contact": 0.6, "elbow_bend_at_contact_deg": 90.0, "off_fist_from_guard_m": 0.1, "trunk_flexion_deg": 10.0}
        return {**base, **changes}

    def runs(lead, rear, rate=0.97, out_of_reach=0):
        rows, natural = [], []
        for stance in ("orthodox", "southpaw"):
            for move, figures in (("jab", lead), ("cross", rear)):
                name = results.hand_row(move, stance)
                rows += [{"condition": name, "sigma": sigma, "success_rate": rate, "punches": 100, "out_of_reach": 0}
                         for sigma in (0.0, 0.3)]
                natural.append({"condition": name, "sigma": 0.0, "medians": figures})
        report = {"evaluations": [{"rows": rows, "naturalness": natural}]}
        # Out of reach: 100 punches, `out_of_reach` of them beyond the reach, every one in reach landed.
        around = [{"condition": f"{role} hand, {kind}: x", "sigma": 0.0, "success_rate": rate, "punches": 100,
                   "out_of_reach": out_of_reach if kind == "arms" else 0, "in_reach_successes": 100 - out_of_reach}
                  for role in ("lead", "rear") for kind in ("moving", "arms")]
        return [{"measurement": Measurement(scenario), "report": report} for scenario in ("stance", "body")] + \
            [{"measurement": Measurement("stance_moving"), "report": {"evaluations": [{"rows": around}]}}]

    reports = {"straight": runs(medians(time_to_contact_s=0.2), medians(time_to_contact_s=0.15)),
               "hook": runs(medians(side_angle_at_contact_deg=17.0, fist_peak_speed_mps=6.0), medians(), rate=0.5),
               "uppercut": runs(medians(), medians(rise_share_at_contact=0.48), rate=0.6, out_of_reach=40)}
    table = results.moves_table(reports, {"straight.onnx": "straight", "hook.onnx": "hook", "uppercut.onnx": "uppercut"},
                                results.MOVESET)
    rows = {line.split("|")[1].strip(): line for line in table.splitlines()[2:]}
    assert list(rows) == [f"`{move}`" for move in results.SIX_MOVES]
    assert rows["`jab`"].endswith("| the quickest to land |") and "| 97.0% | 97.0% |" in rows["`jab`"]
    assert "side_angle_at_contact_deg >= 35, fist_peak_speed_mps >= the cross's" in rows["`lead_hook`"]
    assert "| 50.0% |" in rows["`rear_hook`"] and rows["`rear_hook`"].endswith("| none |")
    assert rows["`rear_uppercut`"].endswith("| rise_share_at_contact >= 0.5 |") and rows["`lead_uppercut`"].endswith("| none |")
    assert "| 60.0% | 60.0% (100.0% in reach) |" in rows["`rear_uppercut`"] and "in reach" not in rows["`cross`"]
    assert results.moves_table({"straight": reports["straight"]}, {"straight.onnx": "straight"}, results.MOVESET) is None


def test_a_policy_of_one_stances_guard_is_measured_from_there_with_its_hand(tmp_path):
    """A recipe trained with `guard = "southpaw"` (a lead hand's move) is measured by the stance scenarios alone and
    only as the lead hand; a recipe of every start by every measurement."""
    recipe = tmp_path / "lead_move.toml"
    recipe.write_text('name = "lead_move"\npolicy = "addons/punch_controller/policies/lead_move.onnx"\n'
                      '[train]\nreward = "uppercut"\nguard = "southpaw"\n[[stage]]\nname = "volume"\na2c_updates = 10\n')
    chosen = results.measurements_for(load_recipe(recipe))
    assert [m.scenario for m in chosen] == list(results.STANCE_SCENARIOS)
    for measurement in chosen:
        names = measurement.options["conditions"]
        assert names and all(name.startswith("lead hand") for name in names), names
        assert "--conditions" in measurement.command(Path("p.onnx"))
    assert results.measurements_for(shipped_recipes()[0]) == results.MEASUREMENTS
