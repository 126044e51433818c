"""One frame's progressive passes on a Dask cluster (core/integrators/distributed.py): the
image equals the single-process one bit for bit, a killed worker changes nothing, clear
errors. The tests start their own LocalCluster (two worker processes) and stop it."""

import os
import signal
import time

import numpy as np
import pytest

pytest.importorskip("dask.distributed")

from core import memory  # noqa: E402
from core.integrators import distributed, sppm  # noqa: E402
from core.settings import RenderSettings, SettingsError  # noqa: E402

from tests.core.scenes import caustic_scene  # noqa: E402


SETTINGS = RenderSettings().with_values(integrator="progressive", threads=1)


@pytest.fixture(scope="module")
def cluster():
    c = distributed.connect("local:2")
    try:
        c.client.wait_for_workers(2, timeout=120)
        yield c
    finally:
        c.close()
    # Nothing left running: the LocalCluster's worker processes are gone.
    assert c.cluster.status.name == "closed"


def test_local_2_equals_the_single_process_render_bit_for_bit(cluster):
    scene = caustic_scene(1.0, 24, 24)
    settings = SETTINGS.with_values(photons_per_pass=6_000, progressive_passes=23,
                                    progressive_block=4)
    single = sppm.render(scene, settings)
    seen = []
    out = distributed.render(scene, settings, cluster.client,
                             on_tile=lambda k, p: seen.append(k))
    assert not out.cancelled and out.stats["passes"] == 23 and out.stats["tasks"] == 6
    np.testing.assert_array_equal(out.passes["combined"], single.passes["combined"])
    assert out.stats["photons_stored"] == single.stats["photons_stored"]
    assert out.stats["radius_max"] == single.stats["radius_max"]
    assert seen == sorted(seen) and seen[-1] == 23
    assert out.stats["bytes_per_block"] == 24 * 24 * 3 * 8


def test_a_worker_killed_mid_render_leaves_the_image_unchanged(cluster):
    scene = caustic_scene(1.0, 24, 24)
    settings = SETTINGS.with_values(photons_per_pass=20_000, progressive_passes=24,
                                    progressive_block=2)
    single = sppm.render(scene, settings).passes["combined"]
    pids = list(cluster.client.run(os.getpid).values())
    killed = []

    def kill_one(k, _passes):
        if not killed:
            # A task is running on every worker now (two in flight per worker).
            os.kill(pids[0], signal.SIGKILL)
            killed.append(k)

    out = distributed.render(scene, settings, cluster.client, on_tile=kill_one)
    assert killed and killed[0] < 24
    assert out.stats["passes"] == 24 and not out.cancelled
    np.testing.assert_array_equal(out.passes["combined"], single)
    cluster.client.wait_for_workers(2, timeout=120)  # the nanny restarted it


def test_cancel_keeps_what_was_merged(cluster):
    scene = caustic_scene(1.0, 16, 16)
    settings = SETTINGS.with_values(photons_per_pass=4_000, progressive_passes=40,
                                    progressive_block=4)
    merged = []
    # Stop at the first merge that holds passes (a block may arrive before block 0).
    out = distributed.render(scene, settings, cluster.client,
                             on_tile=lambda k, p: merged.append(k),
                             should_stop=lambda: bool(merged) and merged[-1] > 0)
    assert out.stats["passes"] % 4 == 0 and out.stats["passes"] >= 4, merged
    # Cancelled, unless block 0 came last (a worker restarted by the test above is slow to
    # start): then nothing held passes before the end.
    assert out.cancelled or not any(merged[:-1]), merged
    done = sppm.render(scene, settings.with_values(progressive_passes=out.stats["passes"]))
    np.testing.assert_array_equal(out.passes["combined"], done.passes["combined"])


def test_cancel_does_not_wait_for_a_running_block(cluster):
    """Esc while the only block runs (64 passes of 200k photons: seconds of work): asked
    between short waits, the render returns cancelled with nothing merged and the block
    dropped, instead of waiting for it."""
    scene = caustic_scene(1.0, 16, 16)
    settings = SETTINGS.with_values(photons_per_pass=200_000, progressive_passes=64,
                                    progressive_block=64)
    asked = []

    def should_stop():  # "no" at the first question, "yes" from the second (0.25 s later)
        asked.append(time.perf_counter())
        return len(asked) >= 2

    out = distributed.render(scene, settings, cluster.client, should_stop=should_stop)
    assert out.cancelled and out.stats["passes"] == 0 and out.stats["tasks"] == 0, out.stats
    assert asked[1] - asked[0] >= 0.9 * distributed.STOP_POLL_SECONDS
    image = out.passes["combined"]
    assert np.isfinite(image).all() and not image.any()


def test_a_scene_too_large_for_the_workers_is_refused_before_any_task(cluster, monkeypatch):
    monkeypatch.setattr(memory, "BYTES_PER_PASS_PHOTON", 1 << 40)
    with pytest.raises(distributed.DistributedError, match="MiB per worker"):
        distributed.render(caustic_scene(1.0, 8, 8), SETTINGS, cluster.client)


def test_the_progressive_integrator_is_required(cluster):
    with pytest.raises(SettingsError, match="progressive integrator"):
        distributed.render(caustic_scene(1.0, 8, 8),
                           SETTINGS.with_values(integrator="photon_map"), cluster.client)


def test_an_unreachable_scheduler_is_named_within_10_s():
    t0 = time.perf_counter()
    with pytest.raises(distributed.DistributedError, match="tcp://127.0.0.1:9"):
        distributed.connect("tcp://127.0.0.1:9")
    assert time.perf_counter() - t0 < 10.0
    with pytest.raises(distributed.DistributedError, match="nowhere"):
        distributed.connect("nowhere")
    with pytest.raises(distributed.DistributedError, match="local:0"):
        distributed.connect("local:0")


def test_core_import_does_not_import_dask():
    import subprocess
    import sys
    code = "import core, core.integrators.sppm, sys; print('dask' in sys.modules)"
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(
        os.path.abspath(__file__)))))
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                         text=True, check=True)
    assert out.stdout.strip() == "False"
