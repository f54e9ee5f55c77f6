"""Typed exceptions: the trainer raises these, never prints-and-returns-None."""


class PunchError(Exception):
    """Base class of every error the trainer raises on purpose."""


class GodotNotFoundError(PunchError):
    """No usable Godot >= 4.6 (or the project's tools/godot wrapper is missing)."""


class GodotRunError(PunchError):
    """A Godot process failed: non-zero exit, timeout, or a fatal problem in its log."""

    def __init__(self, message: str, log: str = ""):
        super().__init__(message)
        self.log = log


class ExportError(PunchError):
    """An ONNX export did not verify (torch and onnxruntime disagree, or the file is unusable)."""


class SelfCheckError(PunchError):
    """The stack self-check found Godot, Jolt, the extension or ONNX Runtime not working as required."""


class PolicyFileError(PunchError):
    """A policy file cannot be read, or an entry of its metadata does not read as its type (`key` names it)."""

    def __init__(self, message: str, key: str | None = None):
        super().__init__(message)
        self.key = key


class MissingMetadataError(PolicyFileError):
    """A policy file's metadata lacks a required entry (`key`; punch_trainer/policy_file.py lists them)."""
