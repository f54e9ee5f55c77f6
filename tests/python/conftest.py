"""Shared pytest setup. Tests marked `godot` start the real headless Godot through tools/godot; the
README's test command (./dev test) sets it up first."""

from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[2]
FIXTURES = PROJECT_ROOT / "tests" / "fixtures"


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "godot: starts a real headless Godot (Jolt) with the built extension")
