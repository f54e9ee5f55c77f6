"""`punch recipe`: each shipped policy's recipe reads and plans; a small recipe runs, resumes and refuses what
would not make the same policy."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from punch_trainer.cli.main import main
from punch_trainer.pipelines.recipe import RecipeError, SoupStage, TrainStage, load_recipe, run_recipe
from punch_trainer.policy_file import read_policy_metadata
from punch_trainer.reward.style import style_named

ROOT = Path(__file__).resolve().parents[2]
RECIPES = sorted((ROOT / "recipes").glob("*.toml"))
SHIPPED = ROOT / "addons" / "punch_controller" / "policies"


def shipped_recipes() -> list[Path]:
    return [path for path in RECIPES if path.name != "styles.toml"]


def test_every_shipped_policy_has_a_recipe_and_every_recipe_plans(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    recipes = [load_recipe(path) for path in shipped_recipes()]
    assert sorted(recipe.policy.name for recipe in recipes) == sorted(path.name for path in SHIPPED.glob("*.onnx"))
    for recipe in recipes:
        assert (ROOT / recipe.policy).is_file()
        assert main(["recipe", str(recipe.path), "--dry-run", "--out", str(tmp_path / recipe.name)]) == 0
        planned = capsys.readouterr().out.splitlines()
        assert len(planned) == len(recipe.stages)
        for line, stage in zip(planned, recipe.stages, strict=True):
            assert f"] {stage.name}: punch {'soup' if isinstance(stage, SoupStage) else 'train'}" in line
            if isinstance(stage, TrainStage):
                # fixed updates, never a wall-time budget: a stage run again gives the same policy
                assert f"--a2c-updates {stage.updates} " in line and "--a2c-time-budget-s 0" in line
                style_named(line.split("--style ")[1].split()[0])  # every style it names is known
    assert not list(tmp_path.iterdir()), "a dry run writes nothing"


def test_the_straights_recipe_ends_in_the_soup_its_file_records() -> None:
    recipe = load_recipe(ROOT / "recipes" / "straight.toml")
    last = recipe.stages[-1]
    assert isinstance(last, SoupStage)
    soup = (read_policy_metadata(SHIPPED / "straight.onnx").training_summary or {})["soup"]
    styles = [f"{recipe.stage(name).args['style']}@1" for name in last.ingredients]  # type: ignore[union-attr]
    assert styles == [ingredient["style"] for ingredient in soup]
    updates = [recipe.stage(name).updates for name in last.ingredients]  # type: ignore[union-attr]
    assert updates == [ingredient["summary"]["a2c_snapshot_update"] for ingredient in soup]


@pytest.mark.parametrize("text, complaint", [
    ("name = 'x'\npolicy = 'p.onnx'\n[train]\nreward = 'straight'\n[[stage]]\nname = 'a'\na2c_updates = 5\nseed = 'one'\n"
     "frobnicate = 1\n", "frobnicate is not a recipe's to set"),
    ("name = 'x'\npolicy = 'p.onnx'\n[train]\n[[stage]]\nname = 'a'\na2c_updates = 5\na2c_time_budget_s = 60\n",
     "the runner sets"),
    ("name = 'x'\npolicy = 'p.onnx'\n[train]\n[[stage]]\nname = 'a'\n", "a2c_updates must be a whole number"),
    ("name = 'x'\npolicy = 'p.onnx'\n[train]\n[[stage]]\nname = 'a'\na2c_updates = 5\ninit_from = 'later'\n",
     "'later' is neither an earlier stage"),
    ("name = 'x'\npolicy = 'p.onnx'\n[train]\n[[stage]]\nname = 'a'\na2c_updates = 5\nstyle = 'boxing_chain'\n",
     "style 'boxing_chain' is neither a product style"),
    ("name = 'x'\npolicy = 'p.onnx'\n[train]\n[[stage]]\nname = 'a'\na2c_updates = 5\n[[stage]]\nname = 's'\nsoup = ['a']\n",
     "at least two sources"),
    ("name = 'x'\npolicy = 'p.onnx'\n[train]\n[[stage]]\nname = 'a'\na2c_updates = 5\n[[stage]]\nname = 'a'\na2c_updates = 5\n",
     "two stages are named 'a'"),
    ("name = 'x'\n[[stage]\n", "not a readable recipe"),
])
def test_a_malformed_recipe_is_refused_naming_what_is_wrong(tmp_path: Path, text: str, complaint: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(RecipeError, match=complaint):
        load_recipe(path)


SMALL = """
name = "small"
policy = "small.onnx"
[train]
reward = "straight"
reach = "spot"
search_iterations = 3
search_rollouts = 16
pretrain_epochs = 20
a2c_characters = 4
[[stage]]
name = "first"
style = "boxing"
seed = 0
a2c_updates = 2
take = "best"
[[stage]]
name = "second"
init_from = "first"
style = "boxing"
seed = 1
a2c_updates = 2
[[stage]]
name = "mean"
soup = ["first", "second"]
"""


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.godot
@pytest.mark.expensive
def test_a_recipe_runs_its_stages_in_order_and_a_second_run_keeps_them(tmp_path: Path) -> None:
    recipe_path = tmp_path / "small.toml"
    recipe_path.write_text(SMALL)
    recipe = load_recipe(recipe_path)
    out = tmp_path / "run"
    first = run_recipe(recipe, out, progress=False, say=lambda _: None)
    assert [result.reused for result in first] == [False, False, False]
    policy = out / "policy.onnx"
    assert sha256(policy) == sha256(out / "mean" / "policy.onnx")
    assert (out / "second" / "a2c" / "snapshots" / "update_00002" / "policy.onnx").is_file()
    report = (out / "report.md").read_text()
    assert all(f"| {name} |" in report for name in ("first", "second", "mean"))

    again = run_recipe(recipe, out, progress=False, say=lambda _: None)
    assert [result.reused for result in again] == [True, True, True]
    assert sha256(out / "policy.onnx") == sha256(policy)

    # a stage folder made with other options is not taken for this recipe's
    recipe_path.write_text(SMALL.replace("seed = 1", "seed = 2"))
    with pytest.raises(RecipeError, match="made with other options \\(seed\\)"):
        run_recipe(load_recipe(recipe_path), out, progress=False, say=lambda _: None)


def test_a_stage_handed_in_spares_the_stages_it_was_made_from(tmp_path: Path) -> None:
    recipe = load_recipe(ROOT / "recipes" / "straight.toml")
    handed_in = tmp_path / "in_order.onnx"
    handed_in.write_bytes((SHIPPED / "straight.onnx").read_bytes())
    lines: list[str] = []
    results = run_recipe(recipe, tmp_path / "run", use={"ordered_floor": handed_in}, dry_run=True, say=lines.append)
    run = [result.name for result in results]
    assert run == ["ordered_floor", "clean", "blend", "clean_blend", "noise", "noise2", "noise3", "shipped"]
    assert sum("not needed" in line for line in lines) == 7
    with pytest.raises(RecipeError, match="no stage 'sloppy'"):
        run_recipe(recipe, tmp_path / "run", use={"sloppy": handed_in}, dry_run=True, say=lines.append)


def test_a_recipe_whose_last_stage_is_handed_in_makes_its_run_folder_and_policy(tmp_path: Path) -> None:
    recipe = load_recipe(ROOT / "recipes" / "straight.toml")
    handed_in = tmp_path / "shipped.onnx"
    handed_in.write_bytes((SHIPPED / "straight.onnx").read_bytes())
    out = tmp_path / "new" / "run"
    results = run_recipe(recipe, out, use={"shipped": handed_in}, say=lambda _: None)
    assert [result.name for result in results] == ["shipped"]
    assert sha256(out / "policy.onnx") == sha256(handed_in)
    assert "| shipped |" in (out / "report.md").read_text()
