"""One way to start Godot: every Godot process of the trainer, the tests and the tools is started by
`sim/godot.py`'s `start_godot` (through tools/godot, in a session of its own, with a parent-death signal), so
that a killed trainer leaves no Godot behind and every start picks the same Godot.

The check reads every Python source's syntax tree for calls that start a process (subprocess, os.system,
os.exec*, os.spawn*, asyncio's subprocesses, pty.spawn, under any alias they are imported as). Such a call
starts Godot when its command mentions Godot: a name or a string with "godot" in it (`godot_command()`,
`GODOT_WRAPPER`, "tools/godot"), directly or through a variable assigned from one in the same function. Only
`start_godot` may make that call. A command built in another function and passed in escapes this reading;
the tests' recording stand-in for $GODOT (conftest.py) sees every start at run time."""

import ast
from pathlib import Path

from conftest import PROJECT_ROOT

SOURCES = [*sorted((PROJECT_ROOT / "trainer" / "punch_trainer").rglob("*.py")),
           *sorted((PROJECT_ROOT / "tests").rglob("*.py")),
           *sorted((PROJECT_ROOT / "tools").rglob("*.py"))]
LAUNCHER = (PROJECT_ROOT / "trainer" / "punch_trainer" / "sim" / "godot.py", "start_godot")

PROCESS_STARTERS = {
    "subprocess": {"Popen", "run", "call", "check_call", "check_output", "getoutput", "getstatusoutput"},
    "os": {"system", "popen", "execl", "execle", "execlp", "execlpe", "execv", "execve", "execvp", "execvpe",
           "spawnl", "spawnle", "spawnlp", "spawnlpe", "spawnv", "spawnve", "spawnvp", "spawnvpe", "posix_spawn", "posix_spawnp"},
    "asyncio": {"create_subprocess_exec", "create_subprocess_shell"},
    "pty": {"spawn"},
}

COMMAND_KEYWORDS = {"args", "executable", "cmd", "file", "path", "argv", "program"}
"""the keywords that name the program a call starts (its env, cwd or output do not make it a Godot start)"""


def mentions_godot(node: ast.AST, godot_variables: set[str]) -> bool:
    for part in ast.walk(node):
        if isinstance(part, ast.Name) and ("godot" in part.id.lower() or part.id in godot_variables):
            return True
        if isinstance(part, ast.Attribute) and "godot" in part.attr.lower():
            return True
        if isinstance(part, ast.Constant) and isinstance(part.value, str) and "godot" in part.value.lower():
            return True
    return False


class Launches(ast.NodeVisitor):
    """Collects the calls in one module that start a process given something that mentions Godot, with the
    function each is in."""

    def __init__(self) -> None:
        self.modules: dict[str, str] = {}    # local name -> module (import subprocess as sp: sp -> subprocess)
        self.functions: dict[str, str] = {}  # local name -> "module.function" (from os import system as sh)
        self.scopes: list[tuple[str, set[str]]] = [("<module>", set())]  # function name, its Godot variables
        self.found: list[tuple[str, int]] = []

    def visit_Import(self, node: ast.Import) -> None:
        for alias in node.names:
            if alias.name in PROCESS_STARTERS:
                self.modules[alias.asname or alias.name] = alias.name

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        for alias in node.names:
            if node.module in PROCESS_STARTERS and alias.name in PROCESS_STARTERS[node.module]:
                self.functions[alias.asname or alias.name] = f"{node.module}.{alias.name}"

    def visit_FunctionDef(self, node: ast.FunctionDef | ast.AsyncFunctionDef) -> None:
        self.scopes.append((node.name, set()))
        self.generic_visit(node)
        self.scopes.pop()

    def visit_AsyncFunctionDef(self, node: ast.AsyncFunctionDef) -> None:
        self.visit_FunctionDef(node)

    def visit_Assign(self, node: ast.Assign | ast.AnnAssign | ast.AugAssign) -> None:
        if node.value is not None and mentions_godot(node.value, self.scopes[-1][1]):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            self.scopes[-1][1].update(name.id for target in targets for name in ast.walk(target) if isinstance(name, ast.Name))
        self.generic_visit(node)

    def visit_AnnAssign(self, node: ast.AnnAssign) -> None:
        self.visit_Assign(node)

    def visit_AugAssign(self, node: ast.AugAssign) -> None:
        self.visit_Assign(node)

    def starts_a_process(self, call: ast.Call) -> bool:
        function = call.func
        if isinstance(function, ast.Name):
            return function.id in self.functions
        return (isinstance(function, ast.Attribute) and isinstance(function.value, ast.Name)
                and function.attr in PROCESS_STARTERS.get(self.modules.get(function.value.id, ""), set()))

    def visit_Call(self, node: ast.Call) -> None:
        given = [*node.args, *(keyword.value for keyword in node.keywords if keyword.arg in COMMAND_KEYWORDS)]
        if self.starts_a_process(node) and any(mentions_godot(argument, self.scopes[-1][1]) for argument in given):
            self.found.append((self.scopes[-1][0], node.lineno))
        self.generic_visit(node)


def godot_launches(path: Path) -> list[tuple[str, int]]:
    """(function, line) of every call in `path` that starts a process given something that mentions Godot."""
    launches = Launches()
    launches.visit(ast.parse(path.read_text(), str(path)))
    return launches.found


def test_every_godot_process_is_started_by_start_godot():
    launcher_path, launcher = LAUNCHER
    elsewhere = [f"{path.relative_to(PROJECT_ROOT)}:{line} ({function})" for path in SOURCES
                 for function, line in godot_launches(path) if (path, function) != LAUNCHER]
    assert elsewhere == [], "Godot started outside start_godot: use sim/godot.py's start_godot or run_godot"
    assert [function for function, _ in godot_launches(launcher_path)] == [launcher], "start_godot starts Godot, once"
    # ... in a session of its own, dying with its parent (the promise above).
    definition = next(node for node in ast.walk(ast.parse(launcher_path.read_text()))
                      if isinstance(node, ast.FunctionDef) and node.name == launcher)
    popen = next(node for node in ast.walk(definition)
                 if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "Popen")
    keywords = {keyword.arg: keyword.value for keyword in popen.keywords}
    assert isinstance(keywords.get("start_new_session"), ast.Constant) and keywords["start_new_session"].value is True
    assert "_die_with_parent" in ast.unparse(keywords["preexec_fn"])


def test_the_check_finds_godot_started_any_other_way(tmp_path):
    """Godot started on purpose in every way the check reads: each is found, and a process that is not Godot
    is not."""
    source = tmp_path / "sneaky.py"
    source.write_text(
        "import os\n"
        "import subprocess as sp\n"
        "from subprocess import run as sh\n"
        "from punch_trainer.sim.godot import GODOT_WRAPPER, godot_command\n"
        "def popen():\n    return sp.Popen(godot_command() + ['--headless'])\n"
        "def by_path():\n    sh([str(GODOT_WRAPPER), '--headless'])\n"
        "def by_variable():\n    command = ['tools/godot', '--headless']\n    sp.check_call(command)\n"
        "def by_shell():\n    os.system('godot --headless --quit')\n"
        "def not_godot():\n    command = ['xvfb']\n    sp.Popen(command, env={'GODOT': 'x'})\n    sh(['punch', '--version'])\n")
    assert godot_launches(source) == [("popen", 6), ("by_path", 8), ("by_variable", 11), ("by_shell", 13)]
