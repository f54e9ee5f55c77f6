"""`punch render`: a GIF of a policy's punches, one character per noise sigma side by side, filmed by Godot's
Movie Maker mode under a virtual X display (Xvfb), so it works on a machine without a screen or GPU.

    punch render --policy addons/punch_controller/policies/hook.onnx --sigmas 0,0.3,0.6 --out docs/hook.gif
    punch render --scene own_character --seconds 6 --out docs/own_character.gif   # a demo scene instead
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from PIL import Image

from punch_trainer.errors import GodotRunError, PunchError
from punch_trainer.sim.godot import ADDON_POLICIES, GODOT_PROJECT, run_godot, tail

FPS = 30
# The GIF keeps every second frame (15 fps) and 64 colours: a few hundred kB for a few seconds.
GIF_FRAME_STEP = 2
GIF_COLORS = 64


class RenderError(PunchError):
    """Rendering is not possible here (no Xvfb, no OpenGL drivers) or Godot failed to film."""


@dataclass
class RenderArgs:
    policy: Path = ADDON_POLICIES / "straight.onnx"
    """an exported policy.onnx (default: the demo's straight punch)"""
    out: Path = Path("punch.gif")
    """the GIF to write"""
    sigmas: list[float] = field(default_factory=lambda: [0.0])
    """one character per sigma, side by side: a,b,c or start:stop:step"""
    noise_decisions: int = -1
    """noise on the first k decisions only (-1: all)"""
    seconds: float = 3.0
    """length of the GIF"""
    width: int = 640
    """width of the GIF in pixels"""
    height: int = 360
    """height of the GIF in pixels"""
    seed: int = 0
    """noise seed"""
    bags: str = ""
    """each character's bag placement, `distance,height,side;...` in metres, cycled (default: the spec's)"""
    scene: str = ""
    """film a demo scene instead (godot_project/demo/SCENE.tscn: own_character, duel, moving_duel, crowd, moves, pads, combos, hits, bout); --policy, --sigmas,
    --noise-decisions, --seed and --bags are then not used"""


def _free_display() -> int:
    for number in range(99, 160):
        if not Path(f"/tmp/.X{number}-lock").exists() and not Path(f"/tmp/.X11-unix/X{number}").exists():
            return number
    raise RenderError("no free X display number between :99 and :159")


class VirtualDisplay:
    """An Xvfb server for the duration of a `with` block."""

    def __init__(self, width: int, height: int):
        xvfb = shutil.which("Xvfb")
        if not xvfb:
            raise RenderError("rendering needs Xvfb: run ./dev setup-render (installs it with the OpenGL drivers), "
                              "or install the 'xvfb' package yourself")
        self.display = f":{_free_display()}"
        self._process = subprocess.Popen([xvfb, self.display, "-screen", "0", f"{width}x{height}x24", "-nolisten", "tcp"],
                                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        deadline = time.monotonic() + 10
        socket = Path(f"/tmp/.X11-unix/X{self.display[1:]}")
        while not socket.exists():
            if self._process.poll() is not None or time.monotonic() > deadline:
                stderr = self._process.stderr
                error = stderr.read().decode(errors="replace") if stderr is not None and self._process.poll() is not None else ""
                self.close()
                raise RenderError(f"Xvfb did not start on {self.display}: {error[-500:]}")
            time.sleep(0.05)

    def close(self) -> None:
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()

    def __enter__(self) -> VirtualDisplay:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


BAG_LIMIT_M = 3.0
"""A rendered bag is placed within this of the character (m), as every reach volume is (learn/reach.py)."""


def parse_bags(text: str) -> str:
    """`--bags` as given, once every `distance,height,side` in it is three finite numbers within BAG_LIMIT_M
    (distance and height not negative), at most 256 placements; RenderError otherwise."""
    if not text:
        return text
    placements = text.split(";")
    if len(placements) > 256:
        raise RenderError(f"--bags holds {len(placements)} placements; at most 256")
    for placement in placements:
        try:
            values = [float(v) for v in placement.split(",")]
        except ValueError:
            values = []
        if (len(values) != 3 or not all(math.isfinite(v) and abs(v) <= BAG_LIMIT_M for v in values)
                or values[0] < 0 or values[1] < 0):
            raise RenderError(f"--bags placement {placement[:60]!r} is not distance,height,side in metres (finite, distance "
                              f"and height from 0 to {BAG_LIMIT_M:g}, side within {BAG_LIMIT_M:g})")
    return text


def render(args: RenderArgs) -> Path:
    """Films the punches and writes a looping GIF to `args.out`; returns its path."""
    if args.scene:
        if not re.fullmatch(r"[a-z0-9_]+", args.scene) or not (GODOT_PROJECT / "demo" / f"{args.scene}.tscn").is_file():
            scenes = sorted(p.stem for p in (GODOT_PROJECT / "demo").glob("*.tscn"))
            raise RenderError(f"no demo scene '{args.scene}' (there are: {', '.join(scenes)})")
        scene, scene_args = f"res://demo/{args.scene}.tscn", []
    elif not Path(args.policy).is_file():
        raise RenderError(f"policy file not found: {args.policy}")
    else:
        scene = "res://tools/render.tscn"
        scene_args = [f"--policy={Path(args.policy).resolve()}", f"--sigmas={','.join(map(str, args.sigmas))}",
                      f"--noise-decisions={args.noise_decisions}", f"--seed={args.seed}", f"--bags={args.bags}"]
    frames = max(1, round(args.seconds * FPS))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as movie_dir, VirtualDisplay(args.width, args.height) as display:
        movie = Path(movie_dir) / "frame.png"
        environment = {**os.environ, "DISPLAY": display.display}
        try:
            run_godot(["--rendering-driver", "opengl3", "--path", str(GODOT_PROJECT),
                       "--write-movie", str(movie), "--fixed-fps", str(FPS), "--quit-after", str(frames), "--disable-vsync",
                       scene, "--", *scene_args], timeout_s=120 + 2 * frames, env=environment)
        except GodotRunError as error:
            if "OpenGL" in error.log or "MESA" in error.log or "glx" in error.log.lower():
                raise RenderError("Godot could not open OpenGL on the virtual display: run ./dev setup-render "
                                  f"(it adds Mesa's drivers to the private Godot)\n{tail(error.log)}") from error
            raise
        pngs = sorted(Path(movie_dir).glob("frame*.png"))
        if not pngs:
            raise RenderError("Godot wrote no frames")
        # Movie Maker films at the project's window size; the GIF gets the size asked for.
        images = [Image.open(p).convert("RGB").resize((args.width, args.height), Image.Resampling.LANCZOS)
                  .quantize(colors=GIF_COLORS, method=Image.Quantize.MEDIANCUT) for p in pngs[::GIF_FRAME_STEP]]
        images[0].save(out, save_all=True, append_images=images[1:], duration=round(1000 * GIF_FRAME_STEP / FPS), loop=0,
                       optimize=True)
    return out
