"""Headless rendering: ``python -m photon_engine render SCENE.blend -o OUT -f FRAMES``.

Does what ``blender -b SCENE.blend -E PHOTON_MAP -o OUT -f FRAMES`` does, with Blender as a
Python module (bpy): register the engine before opening the file (otherwise the scene's
engine falls back to EEVEE), select Photon Map, apply ``--quality NAME`` (a preset of
core/presets.py) and then ``--set KEY=VALUE`` to ``scene.photon_map`` (a --set of a
setting the preset governs makes the quality Custom, keeping the preset's other values),
then render each frame (``1``, ``1-3``, ``1..3``, ``1,3,5``) from its
own depsgraph and write it to ``OUT`` with ``#`` expanded to the frame number. Unlike
``blender -b`` (which keeps the file's output format), the default format is a 32-bit float
multilayer EXR holding every pass; ``-F PNG`` gives a display image.

Exit status: 0 on success, 1 on a clear error (missing file, bad setting, a scene the
engine cannot render), 2 on bad command-line usage.
"""

import argparse
import os
import re
import sys

PROG = "python -m photon_engine"
FORMATS = ("OPEN_EXR_MULTILAYER", "OPEN_EXR", "PNG")


class CliError(Exception):
    """A user error: printed as one line, exit status 1."""


def build_parser():
    parser = argparse.ArgumentParser(prog=PROG, description="Photon Map headless renderer.")
    commands = parser.add_subparsers(dest="command", required=True)
    render = commands.add_parser(
        "render", help="render frames of a .blend file",
        description="Render frames of SCENE.blend with Photon Map and write them to OUT.")
    render.add_argument("blend", metavar="SCENE.blend", help="the .blend file to render")
    render.add_argument(
        "-o", "--output", metavar="OUT",
        help="output path; '#' characters become the zero-padded frame number (appended "
             "when there are none), '//' is relative to the .blend file, the extension is "
             "added (default: the file's own output path)")
    render.add_argument("-f", "--frame", "--frames", dest="frames", type=parse_frames,
                        metavar="FRAMES",
                        help="frames to render: 7, a range 1-3 or 1..3 (inclusive), or a "
                             "comma list 1,3,5-8 (default: the file's current frame)")
    render.add_argument("-F", "--format", choices=FORMATS, default=FORMATS[0],
                        help="image format (default: %(default)s, 32-bit float, all passes)")
    render.add_argument("--quality", metavar="NAME",
                        help="a quality preset: draft, preview, final, converged (applied "
                             "before --set; default: the file's own settings)")
    render.add_argument("--set", dest="settings", action="append", default=[],
                        metavar="KEY=VALUE",
                        help="a Photon Map setting (scene.photon_map.KEY), repeatable, "
                             "e.g. --set samples=64")
    render.add_argument("--dask", metavar="ADDRESS",
                        help="spread the progressive passes of each frame over a Dask cluster: "
                             "tcp://host:8786 (a scheduler) or local:N (N worker processes "
                             "here); needs --set integrator=progressive and dask[distributed]")
    return parser


def main(argv=None):
    """Run the CLI; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        render_command(args, on_written=lambda path: print(f"{PROG}: wrote {path}", flush=True))
    except CliError as error:
        print(f"{PROG}: error: {error}", file=sys.stderr)
        return 1
    return 0


FRAME_ITEM = re.compile(r"^(-?\d+)(?:(?:\.\.|(?<=\d)-)(-?\d+))?$")
MAX_FRAMES = 1_048_574  # Blender's MAXFRAME: no range can be longer


def parse_frames(text):
    """"7", "1-3", "1..3", "1,3,5-8" -> [7], [1, 2, 3], [1, 2, 3], [1, 3, 5, 6, 7, 8].

    Ranges are inclusive and kept in the order given; a negative start needs ".."
    ("-2..2"). Raises argparse.ArgumentTypeError naming the bad item.
    """
    frames = []
    for item in text.replace(" ", "").split(","):
        match = FRAME_ITEM.match(item)
        if match is None:
            raise argparse.ArgumentTypeError(
                f"bad frame {item!r} in {text!r}: expected N, A-B, A..B or a comma list")
        first = int(match.group(1))
        last = first if match.group(2) is None else int(match.group(2))
        if last < first:
            raise argparse.ArgumentTypeError(f"frame range {item!r} ends before it starts")
        if len(frames) + last - first + 1 > MAX_FRAMES:
            raise argparse.ArgumentTypeError(f"too many frames in {text!r}")
        frames.extend(range(first, last + 1))
    return frames


def render_command(args, on_written=None):
    """Render the frames of ``args.blend``, each from its own depsgraph; returns the paths
    written, in order. ``on_written(path)`` is called after each frame. Raises CliError on
    user errors (frames written before the error stay on disk)."""
    blend = os.path.abspath(args.blend)
    if not os.path.isfile(blend):
        raise CliError(f"no such .blend file: {args.blend}")
    overrides = parse_settings(args.settings)

    import bpy
    from . import register

    if not hasattr(bpy.types.Scene, "photon_map"):
        register()
    bpy.ops.wm.open_mainfile(filepath=blend)
    scene = bpy.context.scene
    scene.render.engine = 'PHOTON_MAP'
    if getattr(args, "quality", None) is not None:
        apply_quality(scene.photon_map, args.quality)
    apply_settings(scene.photon_map, overrides)
    address = getattr(args, "dask", None)
    if address:
        if scene.photon_map.integrator != 'progressive':
            raise CliError(f"--dask {address} needs the progressive integrator (--set "
                           f"integrator=progressive); the scene's is "
                           f"{scene.photon_map.integrator!r}")
        try:
            import importlib
            importlib.import_module("dask.distributed")
        except ImportError as error:
            raise CliError(f"--dask {address}: dask.distributed is not installed "
                           f"(pip install 'dask[distributed]'): {error}") from None
        scene.photon_map.dask_scheduler = address

    frames = [scene.frame_current] if args.frames is None else args.frames
    set_format(scene.render.image_settings, args.format)
    if args.output is not None:
        # Like blender's -o: relative to the working directory unless it starts with //.
        output = args.output if args.output.startswith("//") else os.path.abspath(args.output)
        scene.render.filepath = output
    pattern = scene.render.filepath

    written = []
    for frame in frames:
        # frame_set re-evaluates animation, drivers and the camera: the render exports
        # this frame's depsgraph.
        scene.frame_set(frame)
        scene.render.filepath = pattern
        written.append(_render_still(bpy, scene, frame))
        if on_written is not None:
            on_written(written[-1])
    scene.render.filepath = pattern
    return written


def _render_still(bpy, scene, frame):
    """Render the current frame to the output pattern expanded for ``frame``; returns the path."""
    # write_still does not expand '#'; frame_path does (and adds the extension).
    path = bpy.path.abspath(scene.render.frame_path(frame=frame))
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    scene.render.filepath = path
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as error:
        raise CliError(str(error).removeprefix("Error: ").strip()) from None
    if not os.path.isfile(path):
        raise CliError(f"the render finished but {path} was not written (see the messages above)")
    return path


def parse_settings(pairs):
    """["samples=4", ...] -> {"samples": "4", ...}; a malformed pair raises CliError."""
    settings = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key.strip():
            raise CliError(f"--set expects KEY=VALUE, got {pair!r}")
        settings[key.strip()] = value.strip()
    return settings


def apply_quality(props, name):
    """Select the quality preset ``name``: its values go into the settings it governs."""
    choices = [item.identifier for item in props.bl_rna.properties["quality"].enum_items
               if item.identifier != 'custom']
    if name not in choices:
        raise CliError(f'--quality must be one of {", ".join(choices)}, got {name!r}')
    props.quality = name


def apply_settings(props, overrides):
    """Set ``scene.photon_map`` values from strings, checked against the property's type
    and hard limits (Blender would clamp out-of-range values silently)."""
    from .properties import setting_names

    known = setting_names()
    for key, text in overrides.items():
        if key not in known:
            raise CliError(f'unknown setting "{key}"; known settings: {", ".join(known)}')
        rna = props.bl_rna.properties[key]
        value = _parse_value(key, rna, text)
        setattr(props, key, value)


def _parse_value(key, rna, text):
    try:
        if rna.type == 'INT':
            value = int(text)
        elif rna.type == 'FLOAT':
            value = float(text)
        elif rna.type == 'BOOLEAN':
            lowered = text.lower()
            if lowered not in ("1", "0", "true", "false", "yes", "no", "on", "off"):
                raise ValueError
            return lowered in ("1", "true", "yes", "on")
        elif rna.type == 'ENUM':
            choices = [item.identifier for item in rna.enum_items]
            if text not in choices:
                raise CliError(f'setting "{key}" must be one of {", ".join(choices)}, got {text!r}')
            return text
        else:
            return text
    except ValueError:
        raise CliError(f'setting "{key}" expects {rna.type.lower()}, got {text!r}') from None
    if not (rna.hard_min <= value <= rna.hard_max):
        raise CliError(f'setting "{key}" must be in [{rna.hard_min}, {rna.hard_max}], got {text}')
    return value


def set_format(image_settings, file_format):
    """Select the output format; EXRs are written at 32-bit float (Blender's default is half)."""
    if file_format == "OPEN_EXR_MULTILAYER":
        # Blender 5.0 lists the multilayer format only under the multi-layer media type.
        if hasattr(image_settings, "media_type"):
            image_settings.media_type = 'MULTI_LAYER_IMAGE'
    elif hasattr(image_settings, "media_type"):
        image_settings.media_type = 'IMAGE'
    image_settings.file_format = file_format
    if file_format.startswith("OPEN_EXR"):
        image_settings.color_depth = '32'
        image_settings.color_mode = 'RGBA'
