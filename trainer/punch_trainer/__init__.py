"""punch_trainer: trains physics-based punching policies in headless Godot/Jolt."""

__version__ = "0.1.0"
