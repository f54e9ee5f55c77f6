"""Writes dist/punch_controller-VERSION.zip: the addon as a user unzips it into a game (and as the Godot Asset
Library takes it), `addons/punch_controller/` only, with both libraries, the default policies, LICENSE,
third-party notices and the changelog. Run by `./dev package` after the setup has built both libraries.

Refuses (exit 1, with the reason) when the versions of the addon, extension, trainer and changelog disagree,
or when a library is missing."""

import re
import sys
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ADDON = ROOT / "addons" / "punch_controller"
# Files beside the addon's own that go into it, so the zip is complete on its own.
DOCUMENTS = ["LICENSE", "THIRD_PARTY_NOTICES.md", "CHANGELOG.md"]
LIBRARIES = ["libpunch_controller.linux.debug.x86_64.so", "libpunch_controller.linux.release.x86_64.so",
             "punch_controller.windows.debug.x86_64.dll", "punch_controller.windows.release.x86_64.dll", "onnxruntime.dll"]
# Made by Godot in each project that imports the addon.
LEFT_OUT_SUFFIXES = (".import",)


class PackageError(Exception):
    pass


def versions() -> dict[str, str]:
    """The version each part of the project declares."""
    cargo = tomllib.loads((ROOT / "gdextension" / "Cargo.toml").read_text())["workspace"]["package"]["version"]
    trainer = tomllib.loads((ROOT / "trainer" / "pyproject.toml").read_text())["project"]["version"]
    plugin = re.search(r'^version="([^"]+)"', (ADDON / "plugin.cfg").read_text(), re.MULTILINE)
    # The newest released version (an "Unreleased" section above it collects what comes next).
    changelog = re.search(r"^## (\d\S*)", (ROOT / "CHANGELOG.md").read_text(), re.MULTILINE)
    return {"gdextension/Cargo.toml": cargo, "trainer/pyproject.toml": trainer,
            "addons/punch_controller/plugin.cfg": plugin.group(1) if plugin else "(none)",
            "CHANGELOG.md": changelog.group(1) if changelog else "(none)"}


def agreed_version() -> str:
    found = versions()
    if len(set(found.values())) != 1:
        raise PackageError("the versions disagree: " + ", ".join(f"{k} {v}" for k, v in found.items()))
    return next(iter(found.values()))


def addon_files() -> list[Path]:
    files = [path for path in sorted(ADDON.rglob("*")) if path.is_file() and not path.name.endswith(LEFT_OUT_SUFFIXES)]
    names = {path.name for path in files if path.parent.name == "bin"}
    missing = [name for name in LIBRARIES if name not in names]
    if missing or not any(name.startswith("libonnxruntime.so.") for name in names):
        raise PackageError(f"addons/punch_controller/bin/ lacks {missing or 'libonnxruntime.so.*'}: build the "
                           "libraries first (./dev setup and ./dev setup-windows, or .venv/bin/scons with platform=windows)")
    return files


def write_package(out_dir: Path) -> Path:
    version = agreed_version()
    out_dir.mkdir(parents=True, exist_ok=True)
    package = out_dir / f"punch_controller-{version}.zip"
    with zipfile.ZipFile(package, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for path in addon_files():
            archive.write(path, Path("addons") / "punch_controller" / path.relative_to(ADDON))
        for document in DOCUMENTS:
            archive.write(ROOT / document, Path("addons") / "punch_controller" / document)
    return package


def main() -> int:
    try:
        package = write_package(ROOT / "dist")
    except PackageError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(f"{package.relative_to(ROOT)} ({package.stat().st_size / 2**20:.1f} MiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
