"""`./dev setup` with $GODOT pointing at something that is not Godot stops with a clear message."""

import os
import subprocess

from conftest import PROJECT_ROOT


def test_setup_refuses_a_godot_variable_that_is_not_godot(tmp_path) -> None:
    fake = tmp_path / "not-godot"
    fake.write_text("#!/bin/sh\necho 'I am a text editor'\n")
    fake.chmod(0o755)
    result = subprocess.run(
        [PROJECT_ROOT / "dev", "setup"], capture_output=True, text=True, timeout=120,
        env={**os.environ, "GODOT": str(fake)},
    )
    assert result.returncode != 0
    assert f"GODOT={fake} is not a Godot executable" in result.stderr
