"""The Windows x86_64 libraries (cross-built by `scons platform=windows`, which `./dev check` runs through
`./dev setup-windows`), tested under Wine: there is no Windows Godot here, so what runs is everything but the
engine. The core's whole test suite, ONNX Runtime inference with the wheel's onnxruntime.dll included, runs as
Windows programs; and both extension DLLs load with every DLL they import found, exporting Godot's entry point.
Skipped, with the reason, where the Windows toolchain or Wine is missing."""

import os
import re
import shutil
import subprocess

import pytest

from punch_trainer.sim.godot import PROJECT_ROOT

BIN = PROJECT_ROOT / "addons" / "punch_controller" / "bin"
RUN = PROJECT_ROOT / "tools" / "windows" / "run"
LIBRARIES = ["punch_controller.windows.debug.x86_64.dll", "punch_controller.windows.release.x86_64.dll"]


def wine_missing() -> str | None:
    if not any(shutil.which(name) for name in ("wine64", "/usr/lib/wine/wine64", "wine")):
        return "Wine is not installed (./dev setup-windows)"
    if shutil.which("x86_64-w64-mingw32-gcc") is None:
        return "MinGW-w64 is not installed (./dev setup-windows)"
    if not all((BIN / name).exists() for name in [*LIBRARIES, "onnxruntime.dll"]):
        return "the Windows libraries are not built (./dev setup-windows)"
    return None


pytestmark = pytest.mark.skipif(wine_missing() is not None, reason=str(wine_missing()))


def run(command: list[str], **kwargs) -> subprocess.CompletedProcess[str]:
    return subprocess.run(command, capture_output=True, text=True, timeout=600, cwd=PROJECT_ROOT, **kwargs)


@pytest.mark.expensive  # builds the core's tests for Windows and runs them under Wine: minutes
def test_the_core_passes_its_whole_test_suite_as_windows_programs():
    env = {**os.environ, "CARGO_TARGET_X86_64_PC_WINDOWS_GNU_RUNNER": str(RUN), "PUNCH_ONNXRUNTIME_DIR": str(BIN)}
    result = run(["cargo", "test", "--manifest-path", "gdextension/Cargo.toml", "-p", "punch_core", "--locked",
                  "--target", "x86_64-pc-windows-gnu"], env=env)
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-4000:]
    # The binaries really ran (as .exe files under Wine), the ONNX Runtime tests among them.
    assert re.search(r"Running .*x86_64-pc-windows-gnu.*policy-\w+\.exe", output), output[-4000:]
    passed = sum(int(count) for count in re.findall(r"test result: ok\. (\d+) passed", output))
    assert passed >= 70, output[-4000:]


@pytest.fixture(scope="module")
def load_library(tmp_path_factory) -> str:
    """tools/windows/load_library.c built as a Windows program."""
    exe = tmp_path_factory.mktemp("windows") / "load_library.exe"
    subprocess.run(["x86_64-w64-mingw32-gcc", "-O2", "-o", str(exe), str(PROJECT_ROOT / "tools" / "windows" / "load_library.c")],
                   check=True)
    return str(exe)


@pytest.mark.parametrize("library", LIBRARIES)
def test_the_extension_dll_loads_and_exports_godots_entry_point(load_library, library):
    result = run([str(RUN), load_library, str(BIN / library), "gdext_rust_init"])
    assert result.returncode == 0 and "SYMBOL gdext_rust_init" in result.stdout, result.stdout + result.stderr[-2000:]


def test_onnx_runtime_dll_loads_and_a_missing_symbol_is_seen(load_library):
    result = run([str(RUN), load_library, str(BIN / "onnxruntime.dll"), "OrtGetApiBase"])
    assert result.returncode == 0 and "SYMBOL OrtGetApiBase" in result.stdout, result.stdout + result.stderr[-2000:]
    # The check can fail: a symbol the DLL does not export is reported.
    result = run([str(RUN), load_library, str(BIN / LIBRARIES[1]), "no_such_entry_point"])
    assert result.returncode == 1 and "SYMBOL_MISSING no_such_entry_point" in result.stdout, result.stdout
