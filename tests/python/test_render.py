"""`punch render` films real punches through Godot's Movie Maker mode under Xvfb; the editor plugin loads."""

import shutil

import pytest
from PIL import Image

from punch_trainer.pipelines.render import RenderArgs, RenderError, render
from punch_trainer.sim.godot import ADDON_POLICIES, GODOT_PROJECT, run_godot

POLICY = ADDON_POLICIES / "straight.onnx"


@pytest.mark.godot
@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="no Xvfb on this machine (./dev setup-render installs it)")
def test_render_writes_a_gif_of_moving_characters(tmp_path):
    out = render(RenderArgs(policy=POLICY, out=tmp_path / "grid.gif", sigmas=[0.0, 0.5], seconds=1.0, width=320, height=180))
    gif = Image.open(out)
    assert gif.n_frames == 15 and gif.size == (320, 180)
    first, later = (gif.seek(i) or gif.convert("L").tobytes() for i in (0, 10))
    assert first != later, "the characters should move between frames"
    assert len(set(first)) > 8, "a rendered scene, not a blank frame"


def test_render_refuses_a_missing_policy(tmp_path):
    with pytest.raises(RenderError, match="not found"):
        render(RenderArgs(policy=tmp_path / "none.onnx", out=tmp_path / "x.gif"))


@pytest.mark.godot
def test_editor_opens_the_demo_with_the_plugin_enabled():
    run = run_godot(["--headless", "--editor", "--quit-after", "60", "--path", str(GODOT_PROJECT), "res://demo/demo.tscn"], timeout_s=180)
    assert "ERROR" not in run.log and "SCRIPT" not in run.log, run.log[-3000:]
