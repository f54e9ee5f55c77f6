"""Exported games: the demo exported with its own preset keeps its policies (they are PunchPolicy resources,
so no export filter is needed), and the exported game punches with the debug library and with the release
library an exported game ships.

No export templates can be had on this machine (they are not on any package registry it reaches), so the
executable of a full export is not tested; the pack is what `--export-pack` writes with the same preset
(the files and their conversion are those of a full export), run by this Godot with `--main-pack`, with the
libraries where an exported game's `res://` finds them."""

import json
import shutil

import pytest

from punch_trainer.sim.godot import GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot
ADDON_BIN = PROJECT_ROOT / "addons" / "punch_controller" / "bin"
POLICIES = [f"res://addons/punch_controller/policies/{style}.onnx" for style in ("straight", "hook", "swing")]


@pytest.fixture(scope="module")
def pack(tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "demo.pck"
    run_godot(["--headless", "--path", str(GODOT_PROJECT), "--export-pack", "Linux", str(out)], timeout_s=300)
    return out


def test_the_export_packs_the_policies_without_a_filter(pack):
    preset = (GODOT_PROJECT / "export_presets.cfg").read_text()
    assert 'include_filter=""' in preset, "no *.onnx filter: the policies go in as resources"
    directory = pack.read_bytes()  # the pack's file names are stored as plain text
    for policy in POLICIES:
        assert policy.encode() in directory, policy


@pytest.mark.parametrize("build", ["debug", "release"])
def test_the_exported_game_punches_with_each_library(pack, tmp_path, build):
    """The editor's Godot loads the `.gdextension`'s debug entry; for the release library, it is put in that
    place (the release library is what an exported game's release template loads)."""
    game = tmp_path / "game"
    libraries = game / "addons" / "punch_controller" / "bin"
    libraries.mkdir(parents=True)
    shutil.copy(pack, game / "demo.pck")
    shutil.copy(ADDON_BIN / f"libpunch_controller.linux.{build}.x86_64.so",
                libraries / "libpunch_controller.linux.debug.x86_64.so")
    for runtime in ADDON_BIN.glob("libonnxruntime.so.*"):
        shutil.copy(runtime, libraries / runtime.name)
    run = run_godot(["--headless", "--fixed-fps", "120", "--main-pack", str(game / "demo.pck"), "res://demo/duel.tscn",
                     "--", "--punches=4"], cwd=game, timeout_s=120, check=False)
    assert run.returncode == 0 and run.fatal_lines() == [] and "ERROR" not in run.log, run.log[-3000:]
    line = next(line for line in run.log.splitlines() if line.startswith("HIT_RATE "))
    result = json.loads(line[len("HIT_RATE "):])
    assert result["punches"] == 4 and result["hits"] >= 3, result
