"""Rays per second: the renderer against raw Embree on the same scene, in the same run.

    .venv/bin/python benchmarks/bench_rays.py [--triangles 260000] [--size 256] [--samples 16]
                                              [--direct-only]

The scene: diffuse spheres (tessellated to about --triangles triangles) in a closed box,
lit by an area light and a point light, no specular bounces: so every ray counted is a
camera ray, a shadow ray or a final-gather ray (--direct-only: indirect light and caustics
off, camera and shadow rays only; the photon pass is timed apart, not counted). The baseline
is what DESIGN.md calls the ceiling: embreex's ``EmbreeScene.run`` on 2 M incoherent rays (random origins in the box, random directions),
split in halves over two threads. The goal for the ratio renderer / raw is >= 0.5 (the
rest is shading). A second figure replays exactly the renderer's own batches through raw
embreex: the share of the render's time that is Embree. Every measurement is repeated
(--rounds) and the best kept, since the machine is shared.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from core import prepared as prepared_scene  # noqa: E402
from core.integrators import photon_mapping as integrator  # noqa: E402
from core.scene import shapes  # noqa: E402
from core.scene.contract import LIGHT_AREA, LIGHT_POINT, Lights, Materials, Scene  # noqa: E402
from core.settings import RenderSettings  # noqa: E402


def build_scene(triangles: int, size: int) -> Scene:
    # 4 spheres of rings x 2 rings segments x 2 triangles each.
    rings = max(4, int(np.sqrt(triangles / 4 / 4)))
    parts = [(shapes.box([-2, -2, 0], [2, 2, 3], inward=True), 0)]
    for i, (x, y) in enumerate([(-0.9, -0.6), (0.9, -0.6), (-0.9, 0.8), (0.9, 0.8)]):
        parts.append((shapes.uv_sphere([x, y, 0.7], 0.65, rings, 2 * rings), 1 + i % 2))
    mesh = shapes.assemble(parts)
    mats = Materials.from_list([{"diffuse": [0.7, 0.7, 0.7]}, {"diffuse": [0.8, 0.3, 0.2]},
                                {"diffuse": [0.2, 0.4, 0.8]}])
    lights = Lights.from_list([
        {"kind": LIGHT_AREA, "position": [0, 0, 2.95], "power": 300.0, "size": [1.0, 1.0]},
        {"kind": LIGHT_POINT, "position": [1.2, -1.5, 2.2], "power": 100.0, "radius": 0.1},
    ])
    cam = shapes.pinhole([0, -1.95, 1.4], [0, 0.5, 0.6], size, size, np.radians(70))
    return Scene(mesh, mats, lights, cam)


def raw_embree(scene: Scene, n_rays: int, seed: int = 0,
               box=((-1.9, -1.9, 0.1), (1.9, 1.9, 2.9))) -> dict[str, float]:
    """Raw embreex rates (rays/s) on ``n_rays`` incoherent rays (uniform origins in ``box``,
    metres, uniform directions): ``intersect_1thread``, ``intersect_2threads`` (halves),
    and the same for ``occluded``. bench_photons.py uses it with its own box."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    emb = rtcore_scene.EmbreeScene()
    TriangleMesh(emb, np.ascontiguousarray(scene.mesh.triangle_vertices(), np.float32))
    rng = np.random.default_rng(seed)
    o = rng.uniform(box[0], box[1], (n_rays, 3)).astype(np.float32)
    d = rng.normal(size=(n_rays, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    far = np.full(n_rays, 1e30, np.float32)
    emb.run(o[:1000], d[:1000], dists=far[:1000])  # warm up
    out = {}
    for query in ("INTERSECT", "OCCLUDED"):
        output = 1 if query == "INTERSECT" else None
        t0 = time.perf_counter()
        emb.run(o, d, dists=far.copy(), query=query, output=output)
        out[f"{query.lower()}_1thread"] = n_rays / (time.perf_counter() - t0)
        half = n_rays // 2
        with ThreadPoolExecutor(2) as pool:
            t0 = time.perf_counter()
            futs = [pool.submit(emb.run, o[a:b], d[a:b], dists=far[a:b].copy(), query=query, output=output)
                    for a, b in ((0, half), (half, n_rays))]
            for f in futs:
                f.result()
            out[f"{query.lower()}_2threads"] = n_rays / (time.perf_counter() - t0)
    return out


class RecordingAccelerator:
    """Wraps the render's Accelerator and keeps a copy of every batch it traces while
    ``recording`` (off during the photon pass: the rate is the camera pass's)."""

    def __init__(self, inner):
        self.inner = inner
        self.batches = []
        self.recording = True

    def intersect(self, origins, directions, tfar=None):
        if self.recording:
            self.batches.append(("INTERSECT", np.array(origins, np.float32), np.array(directions, np.float32),
                                 None if tfar is None else np.array(np.broadcast_to(tfar, (len(origins),)), np.float32)))
        return self.inner.intersect(origins, directions, tfar)

    def occluded(self, origins, directions, tfar):
        if self.recording:
            self.batches.append(("OCCLUDED", np.array(origins, np.float32), np.array(directions, np.float32),
                                 np.array(np.broadcast_to(tfar, (len(origins),)), np.float32)))
        return self.inner.occluded(origins, directions, tfar)

    def close(self):
        self.inner.close()


def replay_raw(scene: Scene, batches) -> float:
    """Seconds raw embreex takes for exactly the renderer's batches (2 threads, halves)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    emb = rtcore_scene.EmbreeScene()
    TriangleMesh(emb, np.ascontiguousarray(scene.mesh.triangle_vertices(), np.float32))
    big = np.float32(3e38)
    total = 0.0
    with ThreadPoolExecutor(2) as pool:
        for query, o, d, tf in batches:
            n = o.shape[0]
            tf = np.full(n, big, np.float32) if tf is None else np.minimum(tf, big)
            half = n // 2
            output = 1 if query == "INTERSECT" else None
            t0 = time.perf_counter()
            futs = [pool.submit(emb.run, o[a:b], d[a:b], dists=tf[a:b].copy(), query=query, output=output)
                    for a, b in ((0, half), (half, n)) if b > a]
            for f in futs:
                f.result()
            total += time.perf_counter() - t0
    return total


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=260_000)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--rays", type=int, default=2_000_000)
    ap.add_argument("--rounds", type=int, default=3,
                    help="repeat every measurement and keep the best (the machine is shared)")
    ap.add_argument("--direct-only", action="store_true",
                    help="indirect light and caustics off: camera and shadow rays only")
    ap.add_argument("--profile", action="store_true", help="profile one render with pyinstrument")
    args = ap.parse_args()

    scene = build_scene(args.triangles, args.size)
    print(f"scene: {scene.mesh.triangle_count} triangles, {args.size}x{args.size} px, "
          f"{args.samples} spp, {scene.lights.count} lights, best of {args.rounds} rounds")
    # Every pixel all samples, 64 gather rays per pixel: the workload of the published
    # figures (the presets' defaults sample adaptively since 2026-12-05).
    settings = RenderSettings(samples=args.samples, adaptive_threshold=0.0,
                              final_gather_rays=64, max_specular_depth=0, threads=2,
                              **({"indirect_mode": "off", "caustics": False}
                                 if args.direct_only else {}))
    integrator.render(build_scene(1000, 8), RenderSettings(samples=1))  # compile / load kernels

    raw, render_time, replay_time, stats = {}, np.inf, np.inf, None
    real_accelerator = prepared_scene.Accelerator
    for _ in range(args.rounds):
        for k, v in raw_embree(scene, args.rays).items():
            raw[k] = max(raw.get(k, 0.0), v)
        recorder = {}

        def recording_accelerator(*a, **kw):
            recorder["acc"] = RecordingAccelerator(real_accelerator(*a, **kw))
            return recorder["acc"]

        out = integrator.render(scene, settings)
        if out.stats["time_render"] < render_time:
            render_time, stats = out.stats["time_render"], out.stats
        # The same render, keeping its camera pass's batches: the prepared scene's
        # accelerator records, except during the photon pass (its rays are not counted).
        real_photon_run = integrator.photon_terms.run

        def photon_run_unrecorded(*a, **kw):
            recorder["acc"].recording = False
            try:
                return real_photon_run(*a, **kw)
            finally:
                recorder["acc"].recording = True

        prepared_scene.Accelerator = recording_accelerator
        integrator.photon_terms.run = photon_run_unrecorded
        try:
            integrator.render(scene, settings)
        finally:
            prepared_scene.Accelerator = real_accelerator
            integrator.photon_terms.run = real_photon_run
        batches = recorder.pop("acc").batches
        replayed_rays, replayed_calls = sum(b[1].shape[0] for b in batches), len(batches)
        replay_time = min(replay_time, replay_raw(scene, batches))

    for k, v in raw.items():
        print(f"raw embreex {k:20s} {v / 1e6:6.2f} M rays/s")
    st = stats
    # The BVH build and scene checks (time_prepare) happen once per render and are not
    # part of the raw rate either: the rate is over the tracing phase.
    rate = st["rays_total"] / render_time
    print(f"renderer: {st['rays_total'] / 1e6:.2f} M rays ({st['rays_camera'] / 1e6:.2f} camera, "
          f"{st['rays_shadow'] / 1e6:.2f} shadow) traced in {render_time:.2f} s = "
          f"{rate / 1e6:.2f} M rays/s (whole render {st['time_total']:.2f} s with "
          f"{st['time_prepare']:.2f} s BVH build and checks)")
    print(f"  time: intersect {st['time_intersect']:.2f} s, shadow rays {st['time_shadow']:.2f} s, "
          f"shading and bookkeeping {st['time_shading']:.2f} s")
    raw_rate = raw["intersect_2threads"]
    print(f"ratio renderer / raw incoherent intersect rate, 2 threads (goal >= 0.5): {rate / raw_rate:.2f}")
    print(f"raw embreex on the renderer's own camera-pass batches ({replayed_rays / 1e6:.2f} M rays, "
          f"{replayed_calls} calls, mean {replayed_rays / max(replayed_calls, 1):.0f} rays): {replay_time:.2f} s = "
          f"{st['rays_total'] / replay_time / 1e6:.2f} M rays/s; ratio renderer / that: "
          f"{replay_time / render_time:.2f}")

    if args.profile:
        from pyinstrument import Profiler
        prof = Profiler()
        prof.start()
        integrator.render(scene, settings)
        prof.stop()
        print(prof.output_text(unicode=False, color=False))


if __name__ == "__main__":
    main()
