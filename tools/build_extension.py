"""Build the shippable extension: one zip per platform with the wheels Photon Map needs.

    .venv/bin/python tools/build_extension.py                      # every platform -> dist/
    .venv/bin/python tools/build_extension.py --platform linux-x64 # one platform

For each platform and each CPython a supported Blender embeds (3.11: Blender 4.2 to 5.0;
3.13: 5.1 and later), pip downloads the wheels of numba, llvmlite, embreex and OpenEXR (the
versions installed in this Python, i.e. the tested set, pinned alike in both test
environments by requirements-common.txt; never numpy, which Blender ships) into a cache
(``dist/wheels/<platform>/cp311``, ``.../cp313``; a rerun downloads nothing). A staged copy
of the repository gets them in ``wheels/`` and a manifest listing them (``wheels = [...]``,
``platforms = [...]``); Blender's own ``blender_ext.py build --split-platforms`` then writes
``photon_map-<version>-<platform>.zip`` with only that platform's wheels, and
``blender_ext.py validate`` checks each zip. The committed manifest stays wheel-free, so
the repository itself remains a valid extension source without any download.

Blender installs the wheels into its user extensions folder
(``<extensions>/.local/lib/python3.X/site-packages``) when the zip is installed, only the
ones whose tags match its own Python (the other CPython's wheels are skipped).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]

# Distributions bundled as wheels (import names numba, llvmlite, embreex, OpenEXR).
# numpy is left out on purpose: Blender ships its own, and a second copy would shadow it.
WHEEL_PACKAGES = ("numba", "llvmlite", "embreex", "openexr")

# Blender platform -> pip platform tags, most specific first. Blender 4.2+ needs glibc 2.28
# on Linux; embreex publishes macOS wheels for macOS 13+ only, and numba stopped
# publishing Intel-macOS wheels after 0.62, so there is no macos-x64 build.
PLATFORMS = {
    "linux-x64": ("manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64",
                  "manylinux2014_x86_64"),
    "windows-x64": ("win_amd64",),
    "macos-arm64": ("macosx_13_0_arm64",),
}

DEFAULT_PYTHONS = ("3.11", "3.13")  # Blender 4.2 to 5.0 embed CPython 3.11, 5.1+ 3.13


class BuildError(Exception):
    """A step failed; the message says which and why."""


def pinned_versions(packages=WHEEL_PACKAGES) -> dict[str, str]:
    """{distribution: version} as installed in this Python (the set the tests ran with)."""
    versions = {}
    for name in packages:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            raise BuildError(f"{name} is not installed in {sys.executable}; run tools/setup.sh "
                             f"(the bundled wheels use the installed versions)") from None
    return versions


def _normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


def cached_wheel(folder: pathlib.Path, name: str, version: str) -> pathlib.Path | None:
    """The wheel of ``name==version`` in ``folder``, if already downloaded."""
    for path in sorted(folder.glob("*.whl")):
        fields = path.name.split("-")
        if _normalise(fields[0]) == _normalise(name) and fields[1] == version:
            return path
    return None


def fetch_wheels(platform: str, versions: dict[str, str], cache: pathlib.Path,
                 python: str = DEFAULT_PYTHONS[0]) -> list[pathlib.Path]:
    """Wheels of ``versions`` for ``platform`` and CPython ``python``, downloading only the
    missing ones (``pip download --only-binary=:all: --no-deps``). Returns their paths."""
    if platform not in PLATFORMS:
        raise BuildError(f"unknown platform {platform!r}; known: {', '.join(PLATFORMS)}")
    folder = cache / platform / ("cp" + python.replace(".", ""))
    folder.mkdir(parents=True, exist_ok=True)
    missing = [f"{name}=={version}" for name, version in versions.items()
               if cached_wheel(folder, name, version) is None]
    if missing:
        command = [sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                   "--only-binary=:all:", "--no-deps", "--implementation", "cp",
                   "--python-version", python, "--dest", str(folder)]
        for tag in PLATFORMS[platform]:
            command += ["--platform", tag]
        print(f"build_extension: downloading {', '.join(missing)} for {platform} (Python {python})",
              flush=True)
        done = subprocess.run(command + missing, capture_output=True, text=True)
        if done.returncode != 0:
            raise BuildError(f"pip could not download wheels for {platform}:\n{done.stderr.strip()}")
    wheels = []
    for name, version in versions.items():
        wheel = cached_wheel(folder, name, version)
        if wheel is None:
            raise BuildError(f"no {name}=={version} wheel for {platform} in {folder}")
        wheels.append(wheel)
    return wheels


def blender_ext_tool() -> pathlib.Path:
    """Blender's packaging tool, inside the installed ``bpy`` (found without importing it)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise BuildError("bpy is not installed here; pass --blender-ext PATH/TO/blender_ext.py")
    package = pathlib.Path(list(spec.submodule_search_locations)[0])
    found = sorted(package.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        raise BuildError(f"no blender_ext.py under {package}; pass --blender-ext")
    return found[-1]


def manifest_with_wheels(text: str, wheels: list[str], platforms: list[str]) -> str:
    """The manifest ``text`` with top-level ``platforms`` and ``wheels`` lists added."""
    if re.search(r"^\s*(wheels|platforms)\s*=", text, re.MULTILINE):
        raise BuildError("blender_manifest.toml already lists wheels or platforms; "
                         "the build adds them itself")
    table = re.search(r"^\[", text, re.MULTILINE)
    at = table.start() if table else len(text)
    lines = ["# Added by tools/build_extension.py.",
             "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]",
             "wheels = ["] + [f'  "./wheels/{w}",' for w in wheels] + ["]", "", ""]
    return text[:at] + "\n".join(lines) + text[at:]


def stage_source(stage: pathlib.Path, skip: set[pathlib.Path]) -> None:
    """Copy the repository into ``stage`` without version control, environments and
    outputs (blender_ext applies the manifest's own exclusions afterwards)."""

    def ignore(folder, names):
        folder = pathlib.Path(folder)
        ignored = {n for n in names if n == "__pycache__" or n.endswith((".pyc", ".blend1"))}
        if folder == ROOT:
            ignored |= {n for n in names if n.startswith(".") or n in ("dist", "out")}
        ignored |= {n for n in names if (folder / n).resolve() in skip}
        return ignored

    shutil.copytree(ROOT, stage, ignore=ignore, symlinks=False)


def _link_or_copy(source: pathlib.Path, target: pathlib.Path) -> None:
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)


def run_tool(tool: pathlib.Path, *args) -> str:
    done = subprocess.run([sys.executable, str(tool), *map(str, args)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise BuildError(f"blender_ext.py {args[0]} failed:\n{done.stdout}{done.stderr}")
    return done.stdout


def build(platforms, output_dir: pathlib.Path, cache: pathlib.Path, pythons=DEFAULT_PYTHONS,
          tool: pathlib.Path | None = None, split: bool = True) -> list[pathlib.Path]:
    """Build and validate the extension zips; returns their paths.

    platforms: Blender platform names (keys of PLATFORMS). split: one zip per platform
    (else one zip carrying every platform's wheels).
    """
    tool = tool or blender_ext_tool()
    versions = pinned_versions()
    wheels = [w for platform in platforms for python in pythons
              for w in fetch_wheels(platform, versions, cache, python)]
    output_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=output_dir, prefix=".stage-") as temp:
        stage = pathlib.Path(temp) / "photon_map"
        stage_source(stage, skip={output_dir.resolve(), cache.resolve()})
        (stage / "wheels").mkdir()
        for wheel in wheels:
            _link_or_copy(wheel, stage / "wheels" / wheel.name)
        manifest = stage / "blender_manifest.toml"
        manifest.write_text(manifest_with_wheels(manifest.read_text(),
                                                 sorted(w.name for w in wheels), list(platforms)))
        args = ["build", "--source-dir", stage, "--output-dir", output_dir]
        if split:
            args.append("--split-platforms")
        print(run_tool(tool, *args).strip(), flush=True)
    built = zip_paths(output_dir, platforms if split else None)
    for path in built:
        out = run_tool(tool, "validate", path)
        if "Success" not in out:
            raise BuildError(f"blender_ext.py validate {path}: {out}")
    return built


def zip_paths(output_dir: pathlib.Path, platforms=None) -> list[pathlib.Path]:
    """The zips blender_ext.py names ``<id>-<version>[-<platform>].zip``."""
    text = (ROOT / "blender_manifest.toml").read_text()
    ident = re.search(r'^id\s*=\s*"([^"]+)"', text, re.MULTILINE).group(1)
    version = re.search(r'^version\s*=\s*"([^"]+)"', text, re.MULTILINE).group(1)
    suffixes = [""] if platforms is None else ["-" + p.replace("-", "_") for p in platforms]
    paths = [output_dir / f"{ident}-{version}{suffix}.zip" for suffix in suffixes]
    for path in paths:
        if not path.is_file():
            raise BuildError(f"blender_ext.py did not write {path}")
    return paths


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="tools/build_extension.py",
        description="Build photon_map-<version>-<platform>.zip with bundled wheels.")
    parser.add_argument("--platform", dest="platforms", action="append", choices=list(PLATFORMS),
                        help="a platform to build (repeatable; default: all of them)")
    parser.add_argument("--python", dest="pythons", action="append", metavar="X.Y",
                        help=f"CPython version of the target Blenders (repeatable; default "
                             f"{' and '.join(DEFAULT_PYTHONS)}: Blender 4.2 to 5.0, 5.1 and later)")
    parser.add_argument("--output-dir", type=pathlib.Path, default=ROOT / "dist",
                        help="where the zips go (default: dist/)")
    parser.add_argument("--wheel-cache", type=pathlib.Path, default=ROOT / "dist" / "wheels",
                        help="downloaded wheels, reused by later builds (default: dist/wheels/)")
    parser.add_argument("--single-zip", action="store_true",
                        help="one zip with every platform's wheels instead of one per platform")
    parser.add_argument("--blender-ext", type=pathlib.Path,
                        help="path to blender_ext.py (default: the one inside bpy)")
    args = parser.parse_args(argv)
    try:
        zips = build(args.platforms or list(PLATFORMS), args.output_dir.resolve(),
                     args.wheel_cache.resolve(), tuple(args.pythons or DEFAULT_PYTHONS),
                     args.blender_ext, split=not args.single_zip)
    except BuildError as error:
        print(f"build_extension: error: {error}", file=sys.stderr)
        return 1
    for path in zips:
        print(f"build_extension: {path} ({path.stat().st_size / 1e6:.1f} MB, validated)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
