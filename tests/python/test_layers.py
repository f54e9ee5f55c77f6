"""The trainer's layers: each subpackage imports only itself and those below it (capture <- reward <- sim <- learn
<- report <- pipelines <- cli, where `capture`, the motion capture and its reading, needs no other layer, and
`reward`, what a punch earns, only the capture's; `errors.py`, `options.py`, `policy_file.py`, `framing.py`,
`scene.py` and the package itself are shared), every import counted, at the top
of a module or inside a function; and no modules import one another in a circle. That every Godot process is
started in one place (sim/godot.py) is checked by test_godot_launcher.py."""

import ast
import re
from pathlib import Path

from conftest import PROJECT_ROOT

PACKAGE = PROJECT_ROOT / "trainer" / "punch_trainer"
LAYERS = ["capture", "reward", "sim", "learn", "report", "pipelines", "cli"]


def module_name(path: Path, package: Path) -> str:
    parts = [package.name, *path.relative_to(package).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(path: Path, package: Path) -> list[str]:
    """Every module of the package that `path` imports, relative imports resolved; `from X import Y` counts
    X.Y where Y is a module of the package (a subpackage's module), else X."""
    own = module_name(path, package)
    here = own if path.name == "__init__.py" else own.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = here.split(".")[:len(here.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            for alias in node.names:
                candidate = f"{base}.{alias.name}"
                is_module = (package.parent / candidate.replace(".", "/")).with_suffix(".py").exists() or \
                    (package.parent / candidate.replace(".", "/") / "__init__.py").exists()
                found.append(candidate if is_module else base)
    return [name for name in found if name == package.name or name.startswith(package.name + ".")]


def layer_violations(package: Path, layers: list[str]) -> list[str]:
    """'<module> imports <module>' for every import of a layer above the importer's own, of a module outside
    every layer, and for every module that is itself outside every layer and not shared."""
    shared = {package.name, *(f"{package.name}.{name}" for name in ("errors", "options", "policy_file", "framing", "scene"))}
    violations = []
    for path in sorted(package.rglob("*.py")):
        own = module_name(path, package)
        parts = own.split(".")
        in_layer = len(parts) > 1 and parts[1] in layers
        if not in_layer and own not in shared:
            violations.append(f"{own} belongs to no layer")
            continue
        rank = layers.index(parts[1]) if in_layer else -1  # shared modules import no layer
        for imported in imported_modules(path, package):
            if imported in shared:
                continue
            target = imported.split(".")
            if len(target) < 2 or target[1] not in layers or layers.index(target[1]) > rank:
                violations.append(f"{own} imports {imported}")
    return violations


def import_cycles(package: Path) -> list[list[str]]:
    """Every circle of imports among the package's modules (each found once, from its smallest member)."""
    graph = {module_name(path, package): set(imported_modules(path, package)) for path in package.rglob("*.py")}
    # A package's __init__ runs before its modules: importing a.b imports a too. Only module-to-module
    # edges matter here, so the package nodes are left out.
    packages = {module_name(path, package) for path in package.rglob("__init__.py")}
    graph = {name: {target for target in targets if target in graph and target not in packages and target != name}
             for name, targets in graph.items() if name not in packages}
    return cycles_of(graph)


def cycles_of(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every circle in a graph of imports (each found once, from its smallest member)."""
    cycles: list[list[str]] = []

    def walk(start: str, node: str, trail: list[str]) -> None:
        for target in sorted(graph[node]):
            if target == start:
                cycles.append(trail)
            elif target > start and target not in trail:
                walk(start, target, [*trail, target])

    for start in sorted(graph):
        walk(start, start, [start])
    return cycles


RUST_CRATES = [PROJECT_ROOT / "gdextension" / crate / "src" for crate in ("punch_core", "punch_godot", "punch_model_check")]


def rust_module_imports(source: Path) -> dict[str, set[str]]:
    """Each module of a Rust crate (a file under src/, named by its path: `contract::spec`; a folder's mod.rs is
    the folder) and the crate modules its code names (`crate::contract::spec`, `crate::error`); unit tests (from
    `#[cfg(test)]` on, and the `tests.rs` beside a module) and the test-only fake world are left out."""
    def module(path: Path) -> str:
        parts = list(path.relative_to(source).with_suffix("").parts)
        return "::".join(parts[:-1] if parts[-1] == "mod" else parts)

    code = {module(path): path.read_text().split("#[cfg(test)]")[0] for path in source.rglob("*.rs") if path.stem != "tests"}
    modules = set(code) - {"lib", "fake_world"}

    def named(text: str) -> set[str]:
        paths = re.findall(r"\bcrate::(\w+(?:::\w+)?)", text)
        return {path if path in modules else path.split("::")[0] for path in paths} & modules

    return {name: named(code[name]) - {name} for name in modules}


def subsystem_imports(imports: dict[str, set[str]]) -> dict[str, set[str]]:
    """The same imports between a crate's top-level modules (punch_core's subsystem folders)."""
    top: dict[str, set[str]] = {}
    for name, targets in imports.items():
        top.setdefault(name.split("::")[0], set()).update(t.split("::")[0] for t in targets)
    return {name: targets - {name} for name, targets in top.items()}


def test_no_rust_modules_import_one_another_in_a_circle():
    """In each crate: the game's classes, the training server and their helpers (punch_godot), the core's
    modules and its subsystem folders (punch_core), and the model check's modules import one another without a
    circle; the core's contract names no other subsystem; punch_core names no Godot type."""
    for source in RUST_CRATES:
        imports = rust_module_imports(source)
        assert len(imports) >= 3, source
        assert cycles_of(imports) == [], source
        assert cycles_of(subsystem_imports(imports)) == [], source
    core = subsystem_imports(rust_module_imports(RUST_CRATES[0]))
    assert {"contract", "game", "inference", "rig", "training"} <= set(core), core
    assert core["contract"] <= {"error"}, "the contract depends on no other subsystem"
    assert not core["rig"] & {"game", "training"} and not core["training"] & {"game", "rig"}, core
    core_manifest = (RUST_CRATES[0].parent / "Cargo.toml").read_text()
    assert "godot" not in core_manifest.split("[dependencies]")[1], "punch_core depends on no Godot crate"
    assert cycles_of({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_layer_imports_a_layer_above_it():
    assert layer_violations(PACKAGE, LAYERS) == []
    assert {path.parent.name for path in PACKAGE.glob("*/__init__.py")} == set(LAYERS), "every subpackage is a layer"


def test_no_modules_import_one_another_in_a_circle():
    assert import_cycles(PACKAGE) == []


def write_package(root: Path, modules: dict[str, str]) -> Path:
    for name, text in modules.items():
        path = root / (name.replace(".", "/") + ".py")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root / "pkg"


def test_the_checks_find_an_upward_import_a_stray_module_and_a_circle(tmp_path):
    """The checks above, on a small package that breaks each rule once, in each form an import can take."""
    package = write_package(tmp_path, {
        "pkg.__init__": "", "pkg.errors": "", "pkg.stray": "",
        "pkg.low.__init__": "", "pkg.high.__init__": "",
        "pkg.low.a": "from pkg.low import b\nfrom pkg.errors import Error\n",
        "pkg.low.b": "def f():\n    import pkg.high.c\n",  # inside a function, and upward
        "pkg.low.d": "from ..high import c\n",  # relative, upward
        "pkg.high.c": "from pkg.low.a import x\nfrom . import e\n",
        "pkg.high.e": "from pkg.high.c import y\n",  # c <-> e
    })
    assert layer_violations(package, ["low", "high"]) == [
        "pkg.low.b imports pkg.high.c", "pkg.low.d imports pkg.high.c", "pkg.stray belongs to no layer"]
    assert import_cycles(package) == [["pkg.high.c", "pkg.high.e"], ["pkg.high.c", "pkg.low.a", "pkg.low.b"]]
