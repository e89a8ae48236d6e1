"""Build the installable extension zips, one per platform, with embreex, OpenImageIO, numba and
llvmlite bundled.

    python tools/build_extension.py                       # linux-x64, windows-x64, macos-arm64
    python tools/build_extension.py --platform linux-x64  # just one
    python tools/build_extension.py --no-wheels           # source only (needs the packages installed)

1. Downloads (``pip download --only-binary=:all: --no-deps --python-version 3.11
   --platform ...``) the embreex, OpenImageIO, numba and llvmlite (numba's compiler) wheels
   pinned in requirements.txt
   into ``wheels/`` (git-ignored; wheels already there are reused). numpy is not
   bundled: Blender ships its own.
2. Stages the extension in a temporary folder: the files Blender's own builder
   takes from this folder (the manifest's ``[build]`` rules), the wheels, and a
   copy of the manifest with ``platforms``, ``wheels`` and ``blender_version_max``
   (the wheels are for Python 3.11, i.e. Blender 4.2 to 5.0). The committed
   manifest stays source-only.
3. Runs the validator's ``build --split-platforms``: ``dist/smbs_caustics-<version>-<platform>.zip``.

The validator is ``blender --command extension`` with ``--blender PATH``, otherwise
``blender_ext.py`` from the ``bpy`` module. Install a zip with Blender's
preferences (Get Extensions > Install from Disk) or
``blender --command extension install-file -r user_default -e dist/<zip>``.

Exit codes: 0 built, 1 the build failed, 2 bad arguments, 4 a wheel could not be
downloaded (offline? try --no-wheels).
"""
from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MANIFEST = "blender_manifest.toml"
PYTHON_VERSION = "3.11"  # Blender 4.2 to 5.0
BLENDER_VERSION_MAX = "5.1.0"  # exclusive: Blender 5.1 moves to Python 3.13
PACKAGES = ("embreex", "OpenImageIO", "numba", "llvmlite")
# Blender platform -> the pip --platform tags to ask for (pip accepts older macOS tags, but not
# the legacy manylinux2014 name of manylinux_2_17, which numba 0.60's and llvmlite 0.43's wheels carry).
PLATFORMS = {
    "linux-x64": ("manylinux_2_28_x86_64", "manylinux2014_x86_64"),
    "windows-x64": ("win_amd64",),
    "macos-arm64": ("macosx_13_0_arm64",),  # embreex 4.4 needs macOS 13
}
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_DOWNLOAD = 0, 1, 2, 4


class BuildError(RuntimeError):
    def __init__(self, message, code=EXIT_FAILED):
        super().__init__(message)
        self.code = code


def say(*args):
    print("build_extension:", *args, flush=True)


# ---------------------------------------------------------------------------- the validator


def validator(blender: str | None) -> list[str]:
    """The command that runs Blender's extension builder (arguments follow)."""
    if blender:
        return [blender, "--factory-startup", "--command", "extension"]
    spec = importlib.util.find_spec("bpy")
    for location in (spec.submodule_search_locations or []) if spec else []:
        found = sorted(Path(location).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return [sys.executable, str(found[-1])]
    raise BuildError("Blender's extension builder not found: install the bpy module or pass --blender PATH")


def run(cmd: list[str]) -> str:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    output = (proc.stdout + proc.stderr).strip()
    if proc.returncode != 0:
        raise BuildError(f"{' '.join(cmd[-6:])} failed ({proc.returncode}):\n{output}")
    return output


# ---------------------------------------------------------------------------- wheels


def pins(requirements: Path = ROOT / "requirements.txt") -> dict[str, str]:
    """{package: version} for PACKAGES from requirements.txt (``name==version`` lines)."""
    found = {}
    for line in requirements.read_text().splitlines():
        m = re.match(r"\s*([A-Za-z0-9_.-]+)\s*==\s*([^\s;#]+)", line)
        if m:
            for pkg in PACKAGES:
                if m.group(1).lower() == pkg.lower():
                    found[pkg] = m.group(2)
    missing = [p for p in PACKAGES if p not in found]
    if missing:
        raise BuildError(f"{requirements} pins no version of {', '.join(missing)}")
    return found


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


def wheel_platform(filename: str) -> str | None:
    """The Blender platform of a wheel file name (None if not one we build)."""
    tag = filename[:-len(".whl")].split("-")[-1]
    if "manylinux" in tag and "x86_64" in tag:
        return "linux-x64"
    if tag == "win_amd64":
        return "windows-x64"
    if tag.startswith("macosx") and (tag.endswith("arm64") or tag.endswith("universal2")):
        return "macos-arm64"
    return None


def find_wheel(folder: Path, package: str, version: str, platform: str) -> Path | None:
    py = "cp" + PYTHON_VERSION.replace(".", "")
    for path in sorted(folder.glob("*.whl")):
        parts = path.name[:-4].split("-")
        if len(parts) < 5:
            continue
        if (_norm(parts[0]) == _norm(package) and parts[1] == version and py in parts[-3].split(".")
                and wheel_platform(path.name) == platform):
            return path
    return None


def fetch_wheels(folder: Path, platforms, download=True) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    wheels = []
    for platform in platforms:
        for package, version in pins().items():
            path = find_wheel(folder, package, version, platform)
            if path is None and download:
                say(f"downloading {package}=={version} for {platform}")
                cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                       "--only-binary=:all:", "--no-deps", "--python-version", PYTHON_VERSION,
                       *(a for tag in PLATFORMS[platform] for a in ("--platform", tag)),
                       "--dest", str(folder), f"{package}=={version}"]
                proc = subprocess.run(cmd, capture_output=True, text=True)
                if proc.returncode != 0:
                    raise BuildError(f"cannot download {package}=={version} for {platform}:\n"
                                     + (proc.stdout + proc.stderr).strip(), EXIT_DOWNLOAD)
                path = find_wheel(folder, package, version, platform)
            if path is None:
                raise BuildError(f"no {package}=={version} wheel for {platform} in {folder}", EXIT_DOWNLOAD)
            wheels.append(path)
    return wheels


# ---------------------------------------------------------------------------- staging


def staged_manifest(text: str, platforms, wheel_names) -> str:
    """The manifest with platforms, wheels and blender_version_max added before the first table."""
    def toml_list(items):
        return "[" + ", ".join(f'"{i}"' for i in items) + "]"

    lines = text.splitlines(keepends=True)
    keys = {m.group(1) for m in (re.match(r"\s*([A-Za-z_]+)\s*=", ln) for ln in lines) if m}
    for key in ("platforms", "wheels"):
        if key in keys:
            raise BuildError(f"{MANIFEST} already declares '{key}'; this script adds it for the build")
    added = [f"platforms = {toml_list(platforms)}\n",
             f"wheels = {toml_list('./wheels/' + n for n in wheel_names)}\n"]
    if "blender_version_max" not in keys:
        added.insert(0, f'blender_version_max = "{BLENDER_VERSION_MAX}"\n')
    first_table = next((i for i, ln in enumerate(lines) if ln.lstrip().startswith("[")), len(lines))
    block = ["# Added by tools/build_extension.py for this build.\n", *added, "\n"]
    return "".join(lines[:first_table] + block + lines[first_table:])


def stage(tmp: Path, ext: list[str], platforms, wheels: list[Path]) -> Path:
    """A folder holding what the builder would take from ROOT, plus the wheels and manifest."""
    source_zip_dir = tmp / "source"
    source_zip_dir.mkdir()
    run([*ext, "build", "--source-dir", str(ROOT), "--output-dir", str(source_zip_dir)])
    (source_zip,) = source_zip_dir.glob("*.zip")
    staged = tmp / "stage"
    with zipfile.ZipFile(source_zip) as zf:
        zf.extractall(staged)
    (staged / "wheels").mkdir(exist_ok=True)
    for wheel in wheels:
        shutil.copy2(wheel, staged / "wheels" / wheel.name)
    manifest = staged / MANIFEST
    manifest.write_text(staged_manifest(manifest.read_text(), platforms, [w.name for w in wheels]))
    return staged


def build(platforms, output_dir: Path, wheels_dir: Path, download=True, with_wheels=True,
          blender=None) -> list[Path]:
    ext = validator(blender)
    output_dir.mkdir(parents=True, exist_ok=True)
    if not with_wheels:
        before = set(output_dir.glob("*.zip"))
        say(run([*ext, "build", "--source-dir", str(ROOT), "--output-dir", str(output_dir)]).splitlines()[-1])
        return sorted(set(output_dir.glob("*.zip")) - before) or sorted(output_dir.glob("*.zip"))
    wheels = fetch_wheels(wheels_dir, platforms, download)
    with tempfile.TemporaryDirectory(prefix="smbs_build_") as tmp:
        staged = stage(Path(tmp), ext, platforms, wheels)
        run([*ext, "validate", str(staged)])
        output = run([*ext, "build", "--source-dir", str(staged), "--output-dir", str(output_dir),
                      "--split-platforms"])
    zips = []
    for line in output.splitlines():
        m = re.search(r'created: "(.+\.zip)"', line)
        if m:
            zips.append(Path(m.group(1)))
    for z in zips:
        say(f"built {z} ({z.stat().st_size / 1e6:.1f} MB)")
    return zips


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="tools/build_extension.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--platform", action="append", choices=sorted(PLATFORMS), dest="platforms",
                   help="build for this platform (repeatable; default: all three)")
    p.add_argument("--output-dir", type=Path, default=ROOT / "dist")
    p.add_argument("--wheels-dir", type=Path, default=ROOT / "wheels")
    p.add_argument("--no-download", action="store_true", help="use only the wheels already in --wheels-dir")
    p.add_argument("--no-wheels", action="store_true",
                   help="one source-only zip (embreex, OpenImageIO and numba must then be installed in Blender's Python)")
    p.add_argument("--blender", help="a Blender executable to build with (default: the bpy module's builder)")
    args = p.parse_args(argv)
    platforms = args.platforms or list(PLATFORMS)
    try:
        build(platforms, args.output_dir.resolve(), args.wheels_dir.resolve(), download=not args.no_download,
              with_wheels=not args.no_wheels, blender=args.blender)
    except BuildError as e:
        print(f"build_extension: error: {e}", file=sys.stderr)
        return e.code
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
