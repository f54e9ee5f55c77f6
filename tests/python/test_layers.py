"""The trainer's layers: each subpackage imports only those below it (sim <- learn <- report <- cli), and
every Godot process is started in one place (sim/godot.py)."""

import ast

from conftest import PROJECT_ROOT

PACKAGE = PROJECT_ROOT / "trainer" / "punch_trainer"
LAYERS = ["sim", "learn", "report", "cli"]


def imported_modules(path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            yield node.module
        elif isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)


def test_no_layer_imports_a_layer_above_it():
    upward = []
    for rank, layer in enumerate(LAYERS):
        for path in sorted((PACKAGE / layer).glob("*.py")):
            for module in imported_modules(path):
                parts = module.split(".")
                if parts[0] == "punch_trainer" and len(parts) > 1 and parts[1] in LAYERS[rank + 1:]:
                    upward.append(f"{path.relative_to(PACKAGE)} imports {module}")
    assert upward == []
    assert sorted(p.name for p in PACKAGE.glob("*.py")) == ["__init__.py", "errors.py"], "every module belongs to a layer"


def test_godot_is_started_in_one_place():
    starters = [path.relative_to(PACKAGE) for path in PACKAGE.rglob("*.py")
                if "subprocess.Popen(godot_command()" in path.read_text() or "godot_command() +" in path.read_text()]
    assert [str(p) for p in starters] == ["sim/godot.py"]
