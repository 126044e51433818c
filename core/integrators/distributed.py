"""One frame's progressive passes on a Dask cluster (``dask.distributed``), merged exactly.

The progressive mode is pass-independent (core/integrators/sppm.py: Knaus & Zwicker's
global radius schedule; pass k depends only on the scene, the settings and k), so the
blocks of ``progressive_block`` passes that make up a render can run on any worker in any
order: each task renders one block with ``sppm.PassRenderer.render_block`` and returns its
``PassSums``; the client adds them to an ``sppm.ImageSum``, which merges in block order,
so the image is the same bit for bit as ``sppm.render`` of the same settings and seed on
one machine (the same per-pass numbers, summed in the same order in float64).

- The scene is sent once per frame: ``Client.scatter(..., broadcast=True)``, as plain
  arrays (dataclasses flattened to dicts: a worker needs the core and its dependencies
  (numpy, numba, embreex), never Blender, and not the client's package name). Each worker
  prepares it once (Embree, tables) and keeps it for the frame's tasks.
- A worker lost in the middle of a task costs that task: Dask runs it again elsewhere
  (the scene is on every worker); its result, and so the image, is unchanged.
- A scene too large for the workers' memory is refused with the estimate before any task.
- should_stop() -> True cancels the tasks not merged and keeps what was merged; a time
  budget stops submitting blocks that would end past it and waits for those running.

Dask is imported here only (and in the CLI), never when ``core`` is imported: it is an
optional dependency (requirements.txt; the Blender extension does not ship it).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import pickle
import time
import uuid

import numpy as np

from ..passes import ProgressFn, RenderOutput, StopFn, TileFn
from .. import memory
from ..prepared import prepare
from ..scene import contract
from ..scene.contract import Scene
from ..media import density
from ..settings import RenderSettings, SettingsError
from ..shading import program as shader_program
from . import dask_task, sppm

CONNECT_TIMEOUT = 6.0
"""Seconds to reach a scheduler before the address is reported unreachable."""
STOP_POLL_SECONDS = 0.25
"""How often a cluster render asks should_stop() while it waits for blocks (s)."""


TASK_EXPRESSION = "__import__('cloudpickle').loads(blob)(*args)"
"""What a worker evaluates for a block (``render``)."""


class DistributedError(RuntimeError):
    """A cluster problem the user can act on (unreachable scheduler, no workers, a scene
    too large for them); the message names the address or the figures."""


# --- connecting -----------------------------------------------------------------------------

class Cluster:
    """A connected ``dask.distributed.Client`` (and the LocalCluster it owns, for
    ``local:N``); a context manager that closes what it started."""

    def __init__(self, client, cluster=None, address=""):
        self.client, self.cluster, self.address = client, cluster, address

    def close(self):
        try:
            if self.cluster is not None:
                # Closing our LocalCluster races each worker's heartbeat against the
                # scheduler's shutdown; a worker that loses logs "Failed to communicate with
                # scheduler during heartbeat" with a traceback, noise on a Ctrl-C in a
                # terminal. The workers are ours and about to go: quiet their log first.
                with contextlib.suppress(Exception):
                    self.client.run(lambda: logging.getLogger("distributed.worker")
                                    .setLevel(logging.CRITICAL), on_error="ignore")
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def connect(address: str, timeout: float = CONNECT_TIMEOUT) -> Cluster:
    """``tcp://host:8786`` (any Dask scheduler address) or ``local:N`` (a LocalCluster of N
    single-threaded worker processes on this machine). Raises DistributedError naming the
    address when it is malformed or unreachable within ``timeout`` seconds."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as error:
        raise DistributedError(f"--dask {address}: dask.distributed is not installed "
                               f"(pip install 'dask[distributed]'): {error}") from None
    address = str(address).strip()
    if address.startswith("local:"):
        try:
            n = int(address[len("local:"):])
        except ValueError:
            n = 0
        if not 1 <= n <= 1024:
            raise DistributedError(f"bad Dask address {address!r}: local:N needs N in [1, 1024]")
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        return Cluster(Client(cluster), cluster, address)
    if "://" not in address or not address.split("://", 1)[1]:
        raise DistributedError(f"bad Dask address {address!r}: expected tcp://host:port "
                               f"(a scheduler) or local:N")
    try:
        client = Client(address, timeout=timeout)
    except (OSError, TimeoutError) as error:
        raise DistributedError(f"cannot reach the Dask scheduler at {address} within "
                               f"{timeout:g} s ({type(error).__name__}: {error})") from None
    return Cluster(client, None, address)


# --- what a task carries --------------------------------------------------------------------

def scene_payload(obj):
    """The scene as plain objects: dataclasses become {"__class__": name, fields...}."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {"__class__": type(obj).__name__}
        for f in dataclasses.fields(obj):
            out[f.name] = scene_payload(getattr(obj, f.name))
        return out
    if isinstance(obj, (list, tuple)):
        return type(obj)(scene_payload(v) for v in obj)
    return obj


PAYLOAD_MODULES = (contract, shader_program)
"""Where ``scene_from_payload`` finds a payload's classes: the scene contract's, and the
shader programs that materials and media hold (``Materials.programs``,
``Media.programs``)."""


def scene_from_payload(payload):
    """The inverse of ``scene_payload`` with this core's classes (PAYLOAD_MODULES)."""
    if isinstance(payload, dict) and "__class__" in payload:
        name = payload["__class__"]
        cls = next((getattr(m, name) for m in PAYLOAD_MODULES if hasattr(m, name)), None)
        if cls is None:
            raise TypeError(f"a Dask scene payload holds a {name}, which no module of "
                            f"PAYLOAD_MODULES defines")
        return cls(**{k: scene_from_payload(v) for k, v in payload.items() if k != "__class__"})
    if isinstance(payload, (list, tuple)):
        return type(payload)(scene_from_payload(v) for v in payload)
    return payload


_WORKER: dict = {}
"""On a worker: token -> (PreparedScene, PassRenderer) of the frame being rendered."""


def render_block_on_worker(scene_payload_, settings_values, token, start, stop):
    """A task's body, on a worker: prepare the frame's scene once, render [start, stop)."""
    entry = _WORKER.get(token)
    if entry is None:
        for prepared, _ in _WORKER.values():  # the previous frame's
            prepared.close()
        _WORKER.clear()
        settings = RenderSettings(**settings_values).validated()
        prepared = prepare(scene_from_payload(scene_payload_), settings.threads, settings.seed)
        entry = _WORKER[token] = (prepared, sppm.PassRenderer(prepared, settings))
    t0 = time.perf_counter()
    fields = entry[0].medium.fields if entry[0].medium is not None else None
    if fields is not None:  # this block's clipping alone (the fields count every pass)
        fields.take_clipping()
    sums = entry[1].render_block(start, stop)
    stats = dict(sums.stats)
    if fields is not None:
        stats["medium_clipping"] = fields.take_clipping()
    stats["time_tasks"] = time.perf_counter() - t0
    stats["initial_radius"] = entry[1].r1
    return sums.start, sums.stop, sums.radiance, stats


def _core_names() -> list[str]:
    own = __name__.rsplit(".integrators.", 1)[0]  # e.g. core, photon_map.core, bl_ext...core
    return list(dict.fromkeys([own, "core", "photon_map.core"]))


def _core_root() -> str:
    """The directory holding this core package (a worker on this machine can import it)."""
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.dirname(os.path.dirname(here))


def memory_estimate(scene: Scene, settings: RenderSettings) -> int:
    """Bytes a worker needs for the frame: what the progressive render needs on one
    machine (``memory.estimate``: the prepared scene, one pass's photons, the per-pixel
    sums), which is what a worker runs."""
    return memory.estimate(scene, settings).total


def _check_memory(client, scene, settings, address) -> int:
    workers = client.scheduler_info().get("workers", {})
    if not workers:
        raise DistributedError(f"the Dask scheduler at {address} has no workers")
    need = memory_estimate(scene, settings)
    limits = [int(w.get("memory_limit") or 0) for w in workers.values()]
    limits = [m for m in limits if m > 0]
    if limits and need > min(limits):
        raise DistributedError(
            f"the scene needs about {need / 2**20:,.0f} MiB per worker (prepared scene, "
            f"{settings.photons_per_pass:,} photons per pass, the image sums); the smallest "
            f"worker at {address} has {min(limits) / 2**20:,.0f} MiB: nothing was sent")
    return need


# --- the render -----------------------------------------------------------------------------

def render(scene: Scene, settings: RenderSettings, client, on_progress: ProgressFn | None = None,
           on_tile: TileFn | None = None, should_stop: StopFn | None = None,
           address: str = "") -> RenderOutput:
    """``sppm.render`` on the workers of ``client`` (a ``dask.distributed.Client``): the same
    RenderOutput, the same image bit for bit (module doc). on_tile(k, {"combined": image})
    after each merge (k passes merged: a prefix [0, k)), on_progress(fraction, message),
    should_stop() -> True cancels what is not merged (``cancelled``).

    stats add: workers, scene_bytes (the scattered payload), bytes_per_block (a task's
    result), time_scatter, time_merge (client time adding blocks), time_tasks (worker time
    in passes, summed), tasks; medium_warnings as ``sppm.render``'s (the workers' density
    clipping summed over the blocks received)."""
    from dask.distributed import wait

    settings = (settings or RenderSettings()).validated()
    if settings.integrator != "progressive":
        raise SettingsError(f'a Dask render needs the progressive integrator '
                            f'(integrator="progressive"), got "{settings.integrator}"')
    scene.validate()
    address = address or str(getattr(client, "scheduler", None) and client.scheduler.address)
    t_start = time.perf_counter()
    need = _check_memory(client, scene, settings, address)
    passes, block = settings.progressive_passes, settings.progressive_block
    budget = float(settings.time_budget) or None
    w, h = int(scene.camera.width), int(scene.camera.height)
    # The workers' own cores: single-threaded workers (local:N) get one thread each.
    worker_settings = dataclasses.asdict(settings)
    payload = scene_payload(scene)
    scene_bytes = len(pickle.dumps(payload, protocol=5))
    [scene_future] = client.scatter([payload], broadcast=True, hash=False)
    time_scatter = time.perf_counter() - t_start
    token = uuid.uuid4().hex
    blocks = sppm.pass_blocks(passes, block)
    n_workers = max(1, len(client.scheduler_info().get("workers", {})))
    in_flight = 2 * n_workers
    names, root = _core_names(), _core_root()
    # The task is the builtin eval of a fixed expression: plain pickle sends a function by
    # its module's name, which a worker may not have (Blender's bl_ext..., the CLI's
    # photon_map); eval is everywhere, and dask_task.run_block travels by value.
    import cloudpickle
    cloudpickle.register_pickle_by_value(dask_task)
    task_blob = cloudpickle.dumps(dask_task.run_block)
    cloudpickle.unregister_pickle_by_value(dask_task)

    def submit(i):
        a, b = blocks[i]
        return client.submit(eval, TASK_EXPRESSION,
                             {"blob": task_blob, "args": [names, root, scene_future,
                                                          worker_settings, token, a, b]},
                             key=f"photon-map-{token[:8]}-{a}", pure=False, retries=2)

    image = sppm.ImageSum(w, h)
    futures = {}
    submitted = 0
    while submitted < min(in_flight, len(blocks)):
        f = submit(submitted)
        futures[f.key] = f
        submitted += 1
    cancelled, stopped_by = False, "passes"
    time_merge, time_tasks, bytes_per_block, tasks = 0.0, 0.0, 0, 0
    r1 = float("nan")
    clipping = {}  # the media's density clipping, summed over the blocks received
    try:
        while futures:
            # Esc / a signal is asked between short waits, not only when a block arrives:
            # a block (progressive_block passes) can take minutes.
            if should_stop is not None and should_stop():
                cancelled = image.passes < passes
                stopped_by = "cancelled" if cancelled else "passes"
                break
            try:
                done, _ = wait(list(futures.values()), timeout=STOP_POLL_SECONDS,
                               return_when="FIRST_COMPLETED")
            except TimeoutError:  # nothing finished yet (asyncio's is this one since 3.11)
                continue
            for f in sorted(done, key=lambda f: f.key):
                a, b, radiance, stats = f.result()
                del futures[f.key]
                tasks += 1
                bytes_per_block = max(bytes_per_block, radiance.nbytes)
                time_tasks += stats.pop("time_tasks", 0.0)
                r1 = stats.pop("initial_radius", r1)
                density.merge_clipping(clipping, stats.pop("medium_clipping", {}))
                t0 = time.perf_counter()
                merged = image.add(sppm.PassSums(a, b, radiance, stats))
                time_merge += time.perf_counter() - t0
                if on_tile is not None:
                    on_tile(merged, {"combined": image.radiance()})
                if on_progress is not None:
                    on_progress(merged / passes, f"Pass {merged}/{passes} ({n_workers} workers)")
                if submitted < len(blocks):
                    elapsed = time.perf_counter() - t_start
                    rate = merged / max(elapsed, 1e-9)  # passes per second, whole cluster
                    ahead = blocks[submitted][1]        # passes submitted once this one is
                    if budget is not None and merged and ahead / rate > budget:
                        stopped_by = "time_budget"
                        submitted = len(blocks)         # no more; wait for those running
                    else:
                        nf = submit(submitted)
                        futures[nf.key] = nf
                        submitted += 1
    finally:
        for f in futures.values():
            f.cancel()
        scene_future.release()
    stats = sppm.finish_stats(dict(image.stats), image.passes,
                              _last_radius(r1, settings, image.passes), stopped_by,
                              budget, t_start)
    stats.update({"alpha": float(settings.progressive_alpha), "initial_radius": r1,
                  "photons_per_pass": int(settings.photons_per_pass),
                  "progressive_block": int(block), "distributed": address,
                  "workers": n_workers, "scene_bytes": scene_bytes,
                  "memory_estimate": need, "bytes_per_block": bytes_per_block,
                  "time_scatter": time_scatter, "time_merge": time_merge,
                  "time_tasks": time_tasks, "tasks": tasks,
                  "medium_warnings": density.clipping_warnings(clipping)})
    return RenderOutput(passes={"combined": image.radiance()}, stats=stats, cancelled=cancelled)


def _last_radius(r1, settings, passes) -> float:
    """The last merged pass's radius r_{n-1} (r_1 as the workers computed it)."""
    if not passes or not np.isfinite(r1):
        return float("nan")
    return float(sppm.radius_schedule(r1, settings.progressive_alpha, passes)[-1])
