"""The headless CLI, run as a user types it: ``python -m photon_engine render ...`` from
the repository root, in a fresh process."""

import subprocess
import sys

import bpy
import numpy as np
import OpenEXR
import pytest

from tests.blender import scenes
from tests.conftest import ROOT

pytestmark = [pytest.mark.blender, pytest.mark.api]


def cli(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "photon_engine", *map(str, args)],
                          cwd=ROOT, capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def blend_file(tmp_path_factory):
    """A saved .blend: lit plane, 32x24, engine left at EEVEE and a PNG output format
    (the CLI must select Photon Map and a 32-bit EXR itself)."""
    path = tmp_path_factory.mktemp("cli") / "plane.blend"
    scene = scenes.plane_and_point_light(width=32, height=24)
    scenes.photon_map()
    scene.render.engine = scenes.eevee_id()
    scene.render.image_settings.file_format = 'PNG'
    scene.photon_map.samples = 2
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def test_renders_frame_to_32bit_multilayer_exr(blend_file, tmp_path):
    done = cli("render", blend_file, "-o", tmp_path / "out_####", "-f", 1, "--set", "samples=1")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    written = sorted(p.name for p in tmp_path.iterdir())
    assert written == ["out_0001.exr"], written
    path = tmp_path / "out_0001.exr"
    assert f"wrote {path}" in done.stdout

    with OpenEXR.File(str(path), separate_channels=True) as exr:
        channels = {name: ch for part in exr.parts for name, ch in part.channels.items()}
        for name, channel in channels.items():
            assert channel.pixels.dtype == np.float32, name  # 32-bit, not half
    passes = scenes.read_multilayer_exr(path)
    assert {"Combined", "Emission", "Direct", "Specular"} <= set(passes)
    combined = passes["Combined"]
    assert combined.shape == (24, 32, 4)
    assert np.isfinite(combined).all() and combined[..., :3].min() >= 0.0
    assert combined[..., :3].max() > 0.0
    assert np.all(combined[..., 3] == 1.0)


def test_png_output_and_frame_number(blend_file, tmp_path):
    done = cli("render", blend_file, "-o", tmp_path / "frame_", "-f", 7, "-F", "PNG")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    # Without '#' Blender appends the frame number, as `blender -b -o ... -f 7` does.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frame_0007.png"]
    image = bpy.data.images.load(str(tmp_path / "frame_0007.png"))
    try:
        assert tuple(image.size) == (32, 24)
        pixels = np.array(image.pixels[:]).reshape(24, 32, 4)
        assert pixels[..., :3].max() > 0.0
    finally:
        bpy.data.images.remove(image)


@pytest.mark.parametrize("setting, message", [
    ("nope=3", 'unknown setting "nope"; known settings: samples'),
    ("samples=abc", 'setting "samples" expects int, got \'abc\''),
    ("samples=0", 'setting "samples" must be in [1, '),
    ("samples", "--set expects KEY=VALUE, got 'samples'"),
])
def test_bad_setting_is_named(blend_file, tmp_path, setting, message):
    done = cli("render", blend_file, "-o", tmp_path / "x_####", "--set", setting, timeout=120)
    assert done.returncode == 1
    assert message in done.stderr
    assert "Traceback" not in done.stderr
    assert not any(tmp_path.iterdir())


def test_missing_file(tmp_path):
    done = cli("render", tmp_path / "missing.blend", "-o", tmp_path / "x", timeout=60)
    assert done.returncode == 1
    assert "no such .blend file" in done.stderr and "missing.blend" in done.stderr
    assert "Traceback" not in done.stderr


def test_scene_error_exits_with_the_message(tmp_path):
    """A scene the engine refuses (NaN in a transform) ends the CLI with its message."""
    path = tmp_path / "nan.blend"
    scenes.plane_and_point_light(width=8, height=6)
    bpy.data.objects["Plane"].location.x = float("nan")
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    done = cli("render", path, "-o", tmp_path / "nan_####", "-f", 1, timeout=120)
    assert done.returncode == 1, done.stdout[-2000:]
    assert "Plane" in done.stderr and "Traceback" not in done.stderr
    assert not list(tmp_path.glob("nan_*"))


def test_quality_and_progressive_settings_from_the_command_line(blend_file, tmp_path):
    """--quality applies a preset, --set picks the progressive integrator and its pass
    count, and the EXR then holds Combined only; the log says what the render chose."""
    done = cli("render", blend_file, "-o", tmp_path / "p_####", "-f", 1, "--quality", "draft",
               "--set", "integrator=progressive", "--set", "progressive_passes=2",
               "--set", "photons_per_pass=1500")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "Progressive: 2 passes in " in done.stdout and "1,500 photons per pass" in done.stdout
    passes = scenes.read_multilayer_exr(tmp_path / "p_0001.exr")
    assert set(passes) == {"Combined"} and passes["Combined"][..., :3].max() > 0
    bad = cli("render", blend_file, "-o", tmp_path / "x_####", "--quality", "ultra", timeout=120)
    assert bad.returncode == 1 and "--quality must be one of draft, preview, final, converged" in bad.stderr
    assert "Traceback" not in bad.stderr


# --- cancelling and output failures (issue 11) ------------------------------------------

def cli_until(line_part, signum, *args, timeout=300):
    """Start the CLI, send ``signum`` to it when a stdout line contains ``line_part``;
    returns (returncode, stdout, stderr, seconds from the signal to the "cancelled by"
    line, or None when no signal was sent)."""
    import signal as signal_module
    import threading
    import time

    proc = subprocess.Popen([sys.executable, "-m", "photon_engine", *map(str, args)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    err_lines, out_lines, sent = [], [], {}

    def read_err():
        for line in proc.stderr:
            err_lines.append(line)
            if "cancelled by" in line and "at" in sent:
                sent["done"] = time.monotonic()

    reader = threading.Thread(target=read_err, daemon=True)
    reader.start()
    timer = threading.Timer(timeout, proc.kill)
    timer.start()
    try:
        for line in proc.stdout:
            out_lines.append(line)
            if "at" not in sent and line_part in line:
                proc.send_signal(signum)
                sent["at"] = time.monotonic()
        proc.wait()
        reader.join(10)
    finally:
        timer.cancel()
    latency = sent["done"] - sent["at"] if "done" in sent else None
    assert signum in (signal_module.SIGINT, signal_module.SIGTERM)
    return proc.returncode, "".join(out_lines), "".join(err_lines), latency


@pytest.fixture(scope="module")
def slow_blend(tmp_path_factory):
    """The lit plane at 64 x 48: with 3 M photons the photon pass takes seconds, with 256
    samples the camera pass too."""
    path = tmp_path_factory.mktemp("cli_slow") / "slow.blend"
    scenes.plane_and_point_light(width=64, height=48)
    scenes.photon_map()
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


@pytest.mark.parametrize("signame, stage, keep", [
    ("SIGINT", "photon pass: Traced", False),
    ("SIGTERM", "photon pass: Traced", False),
    ("SIGINT", "camera pass:", False),
    ("SIGTERM", "camera pass:", True),
])
def test_a_signal_cancels_writes_nothing_and_exits_non_zero(slow_blend, tmp_path, signame,
                                                            stage, keep):
    """SIGINT / SIGTERM at each stage: the render stops between batches (no crash), no
    frame under the output's name (a partial one only with --keep-partial, named so),
    "cancelled" said, exit status 128 + the signal (130 / 143)."""
    import signal as signal_module

    signum = getattr(signal_module, signame)
    photons = "3000000" if stage.startswith("photon") else "20000"
    extra = ["--keep-partial"] if keep else []
    code, out, err, latency = cli_until(
        stage, signum, "render", slow_blend, "-o", tmp_path / "c_####", "-f", 1,
        "--set", f"global_photons={photons}", "--set", "samples=256", *extra)
    assert code == 128 + signum, (code, out[-2000:], err[-2000:])
    assert stage in out
    assert f"cancelled by {signame} during frame 1" in err
    assert "Traceback" not in err and "Fatal Python error" not in err
    assert "wrote" not in out
    # Well within a second on an idle machine (measured 0.02-0.2 s); loose for a shared one.
    assert latency is not None and latency < 5.0, latency
    names = sorted(p.name for p in tmp_path.iterdir())
    if keep:
        assert names == ["c_0001.partial.exr"]
        assert f"the partial frame is in {tmp_path / 'c_0001.partial.exr'}" in err
        combined = scenes.read_multilayer_exr(tmp_path / "c_0001.partial.exr")["Combined"]
        assert combined.shape == (48, 64, 4) and np.isfinite(combined).all()
    else:
        assert names == [], names
        assert "no output written" in err


def test_unwritable_output_fails_before_rendering(blend_file, tmp_path):
    """An output folder that cannot be written is an error naming it before any render
    (/proc refuses new files even to root; a regular file cannot be a folder)."""
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    for target, reason in ((blocker / "sub" / "o_####", "Not a directory"),
                           ("/proc/o_####", "")):
        done = cli("render", blend_file, "-o", target, "-f", 1, timeout=120)
        assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]
        folder = str(blocker / "sub") if reason else "/proc"
        assert f"cannot write the output to {folder}: {reason}" in done.stderr, done.stderr
        assert "Traceback" not in done.stderr
        assert "Photon Map:" not in done.stdout  # no render started


def test_dask_local_2_renders_the_same_frame_and_needs_the_progressive_integrator(blend_file,
                                                                                 tmp_path):
    """--dask local:2 (a LocalCluster the CLI starts and stops) writes the same EXR pixels
    as the render on this process; --dask without the progressive integrator is refused."""
    pytest.importorskip("dask.distributed")
    args = ("--set", "integrator=progressive", "--set", "progressive_passes=6",
            "--set", "photons_per_pass=1500", "--set", "threads=1")
    one = cli("render", blend_file, "-o", tmp_path / "one_####", "-f", 1, *args)
    assert one.returncode == 0, one.stdout[-3000:] + one.stderr[-3000:]
    many = cli("render", blend_file, "-o", tmp_path / "dask_####", "-f", 1, *args,
               "--dask", "local:2")
    assert many.returncode == 0, many.stdout[-3000:] + many.stderr[-3000:]
    a = scenes.read_multilayer_exr(tmp_path / "one_0001.exr")["Combined"]
    b = scenes.read_multilayer_exr(tmp_path / "dask_0001.exr")["Combined"]
    np.testing.assert_array_equal(a, b)
    bad = cli("render", blend_file, "-o", tmp_path / "x_####", "--dask", "local:2", timeout=120)
    assert bad.returncode == 1 and "needs the progressive integrator" in bad.stderr
    assert "Traceback" not in bad.stderr
    gone = cli("render", blend_file, "-o", tmp_path / "y_####", *args,
               "--dask", "tcp://127.0.0.1:9", timeout=120)
    assert gone.returncode == 1 and "tcp://127.0.0.1:9" in gone.stderr, gone.stderr[-2000:]


def test_sigint_cancels_a_dask_render(blend_file, tmp_path):
    """Ctrl-C during a --dask local:2 render: the cluster's tasks are dropped, no frame is
    written, exit status 130, and the local cluster is shut down (the process ends)."""
    pytest.importorskip("dask.distributed")
    import signal as signal_module

    code, out, err, latency = cli_until(
        "Pass ", signal_module.SIGINT, "render", blend_file, "-o", tmp_path / "d_####", "-f", 1,
        "--set", "integrator=progressive", "--set", "progressive_passes=256",
        "--set", "photons_per_pass=20000", "--set", "threads=1", "--dask", "local:2",
        timeout=300)
    assert code == 130, (code, out[-2000:], err[-2000:])
    assert "cancelled by SIGINT during frame 1" in err
    assert "Traceback" not in err and "Fatal Python error" not in err
    assert "wrote" not in out and sorted(p.name for p in tmp_path.iterdir()) == []
    assert latency is not None and latency < 5.0, latency
