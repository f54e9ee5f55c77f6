"""The `punch` console command is installed and answers."""

import subprocess
import sys
from pathlib import Path

from punch_trainer import __version__

PUNCH = Path(sys.executable).with_name("punch")


def test_version() -> None:
    result = subprocess.run([PUNCH, "--version"], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == f"punch {__version__}"


def test_unknown_command_is_a_usage_error() -> None:
    result = subprocess.run([PUNCH, "no-such-command"], capture_output=True, text=True)
    assert result.returncode == 2
    assert "invalid choice" in result.stderr
