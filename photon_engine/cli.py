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

Progress goes to stdout as one line per stage ("frame 1: photon pass: ...", "frame 1:
camera pass: ...", at most one a second within a stage), for people and farm managers.

Cancelling: SIGINT (Ctrl-C) or SIGTERM (what farm managers send) only sets a flag
(``render.HEADLESS``; raising inside ``bpy.ops.render.render`` crashes Blender); the
render's next progress call answers "stop", so the core stops between batches (well
within a second). Blender writes the frame to ``<name>.partial.<ext>`` beside the
output, and the CLI deletes it (``--keep-partial`` keeps it), prints that the render was
cancelled and exits 130 (SIGINT) or 143 (SIGTERM): a cancelled frame never carries the
output's name. A complete frame is renamed to its name only once written, so the name
never holds a half-written file either. A second signal quits at once.

The output folders are checked before the first frame: one that cannot be created or
written to is an error before any rendering.

Exit status: 0 on success, 1 on a clear error (missing file, bad setting, a scene the
engine cannot render, an output folder that cannot be written), 2 on bad command-line
usage, 130 / 143 when cancelled by SIGINT / SIGTERM.
"""

import argparse
import os
import re
import signal
import sys
import tempfile
import time

PROG = "python -m photon_engine"
FORMATS = ("OPEN_EXR_MULTILAYER", "OPEN_EXR", "PNG")


class CliError(Exception):
    """A user error: printed as one line, exit status 1."""


class Cancelled(Exception):
    """The render was stopped by a signal (``signum``); exit status 128 + signum."""

    def __init__(self, signum, frame=None, partial=None):
        name = signal.Signals(signum).name
        where = f" during frame {frame}" if frame is not None else ""
        kept = (f"; the partial frame is in {partial}" if partial
                else "; no output written for it")
        super().__init__(f"cancelled by {name}{where}{kept}")
        self.signum = signum


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
    render.add_argument("--keep-partial", action="store_true",
                        help="when cancelled (SIGINT, SIGTERM), keep the frame rendered so "
                             "far as <name>.partial.<ext> (default: write nothing)")
    render.add_argument("--dask", metavar="ADDRESS",
                        help="spread the progressive passes of each frame over a Dask cluster: "
                             "tcp://host:8786 (a scheduler) or local:N (N worker processes "
                             "here); needs --set integrator=progressive and dask[distributed]")
    return parser


def main(argv=None):
    """Run the CLI; returns the exit status."""
    args = build_parser().parse_args(argv)
    from .render import HEADLESS

    previous = install_signal_handlers(HEADLESS.cancel)
    try:
        render_command(args, on_written=lambda path: print(f"{PROG}: wrote {path}", flush=True))
    except CliError as error:
        print(f"{PROG}: error: {error}", file=sys.stderr)
        return 1
    except Cancelled as cancelled:
        print(f"{PROG}: {cancelled}", file=sys.stderr, flush=True)
        return 128 + cancelled.signum
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return 0


CANCEL_SIGNALS = (signal.SIGINT, signal.SIGTERM)
received = []
"""The cancelling signals received, in order (the first one sets the exit status)."""


def install_signal_handlers(cancel):
    """SIGINT and SIGTERM set ``cancel`` (a threading.Event) and nothing else: Python runs
    the handler between two bytecodes of the main thread, which during a render is
    between two batches, never inside a numba kernel or Embree. A second signal exits at
    once (os._exit, no cleanup). Returns the previous handlers."""

    def handler(signum, _frame):
        if received:
            os._exit(128 + received[0])
        received.append(signum)
        cancel.set()
        print(f"{PROG}: {signal.Signals(signum).name} received: cancelling (again to quit "
              f"at once)", file=sys.stderr, flush=True)

    received.clear()
    cancel.clear()
    return {signum: signal.signal(signum, handler) for signum in CANCEL_SIGNALS}


def _check_cancel(frame=None):
    if received:
        raise Cancelled(received[0], frame)


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

    # write_still does not expand '#'; frame_path does (and adds the extension).
    paths = [bpy.path.abspath(scene.render.frame_path(frame=frame)) for frame in frames]
    check_writable(paths)
    from .render import HEADLESS

    keep_partial = bool(getattr(args, "keep_partial", False))
    written = []
    try:
        for frame, path in zip(frames, paths):
            _check_cancel(frame)
            # frame_set re-evaluates animation, drivers and the camera: the render exports
            # this frame's depsgraph.
            scene.frame_set(frame)
            HEADLESS.on_progress = StagePrinter(frame)
            written.append(_render_still(bpy, scene, frame, path, keep_partial))
            if on_written is not None:
                on_written(written[-1])
    finally:
        HEADLESS.on_progress = None
        scene.render.filepath = pattern
    return written


def partial_path(path):
    """Where a frame is written until it is complete: ``frame_0001.exr`` ->
    ``frame_0001.partial.exr`` (Blender keeps an extension it recognises)."""
    stem, ext = os.path.splitext(path)
    return f"{stem}.partial{ext}"


def _render_still(bpy, scene, frame, path, keep_partial=False):
    """Render the current frame and write it to ``path``; returns the path. Blender writes
    it to ``partial_path(path)``, renamed to ``path`` once complete; when a signal
    cancelled the render the partial file is removed (kept with ``keep_partial``) and
    Cancelled is raised."""
    partial = partial_path(path)
    scene.render.filepath = partial
    try:
        try:
            bpy.ops.render.render(write_still=True)
        except RuntimeError as error:
            _check_cancel(frame)
            raise CliError(str(error).removeprefix("Error: ").strip()) from None
        if received:
            if keep_partial and os.path.isfile(partial):
                kept, partial = partial, None
                raise Cancelled(received[0], frame, kept)
            raise Cancelled(received[0], frame)
        if not os.path.isfile(partial):
            raise CliError(f"the render finished but {path} was not written (see the "
                           f"messages above)")
        os.replace(partial, path)
        partial = None
    finally:
        if partial is not None and os.path.isfile(partial):
            os.remove(partial)
    return path


def check_writable(paths):
    """Raise CliError naming the first output folder of ``paths`` that cannot be created
    or written to (checked by creating and removing a file in it: permission bits do not
    tell for root, read-only file systems or full disks)."""
    for folder in dict.fromkeys(os.path.dirname(p) or "." for p in paths):
        try:
            os.makedirs(folder, exist_ok=True)
            with tempfile.TemporaryFile(dir=folder):
                pass
        except OSError as error:
            reason = error.strerror or str(error)
            raise CliError(f"cannot write the output to {folder}: {reason} (choose another "
                           f"folder with -o)") from None


class StagePrinter:
    """The render's progress as lines on stdout: "frame 1: photon pass: Traced 262144/
    3000000 photons (8%)", one when the stage changes and at most one a second within a
    stage. Stages: photon pass (tracing, the radiance cache), camera pass (tiles),
    progressive pass (SPPM)."""

    INTERVAL = 1.0

    def __init__(self, frame):
        self.frame, self.stage, self.last = frame, None, 0.0

    def __call__(self, fraction, message):
        stage = stage_of(message)
        now = time.monotonic()
        if stage == self.stage and now - self.last < self.INTERVAL:
            return
        self.stage, self.last = stage, now
        print(f"{PROG}: frame {self.frame}: {stage}: {message} ({fraction:.0%})", flush=True)


def stage_of(message) -> str:
    """The stage a core progress message belongs to."""
    if message.startswith(("Rendering", "Gathering", "Done")):
        return "camera pass"
    if message.startswith("Pass "):
        return "progressive pass"
    return "photon pass"


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
