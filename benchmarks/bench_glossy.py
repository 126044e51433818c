"""Glossy transport (issue 13): the cost of the lobes per hit, and whether final gathering
is worth its cost at diffuse hits reached through a glossy bounce.

    .venv/bin/python benchmarks/bench_glossy.py [--size 64] [--samples 8]

1. Lobes per hit: ``closure.sample_bsdf`` and ``closure.eval_bsdf`` in one numba loop over 2 M
   hits, ns per call, for Lambert, GGX (visible normals), Lambert + GGX and smooth glass,
   against Lambert alone.
2. After a glossy bounce: a closed room (red / green walls, white floor and ceiling) with
   a rough metal sphere (roughness 0.3) and a glossy floor (Lambert 0.5 + GGX 0.25 at
   roughness 0.2), an area light. Rendered with ``photon_mapping.GLOBAL_AFTER_GLOSSY``
   on (the global map's estimate at diffuse hits after a glossy bounce) and off (shadow
   rays + caustic map + final gathering there), against a reference (off, 4x the samples,
   another seed): render time and RMS error of the specular pass (where the two differ)
   and of combined.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np
from numba import njit

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from core.integrators import photon_mapping  # noqa: E402
from core.materials import closure  # noqa: E402
from core.scene import shapes  # noqa: E402
from core.scene.contract import LIGHT_AREA, Lights, Materials, Scene  # noqa: E402
from core.settings import RenderSettings  # noqa: E402


@njit(cache=False)
def _lobe_loop(tab, m, u, which):
    acc = 0.0
    for i in range(u.shape[0]):
        z = 0.2 + 0.8 * u[i, 0]
        s = np.sqrt(1 - z * z)
        if which == 0:
            r = closure.sample_bsdf(tab, m, 1.0, 1.0, 1.0, s, 0.0, z, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0,
                                 1.0, 0.0, 0.0, True, u[i, 1], u[i, 2], u[i, 3])
            acc += r[3]
        else:
            r = closure.eval_bsdf(tab, m, 1.0, 1.0, 1.0, s, 0.0, z, -s * u[i, 1], s * u[i, 2], z,
                                  0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, True)
            acc += r[0]
    return acc


def lobe_costs(n: int = 2_000_000) -> None:
    rows = {"lambert": {"diffuse": [0.8] * 3},
            "ggx r=0.3": {"specular": [0.9] * 3, "roughness": 0.3},
            "lambert+ggx": {"diffuse": [0.5] * 3, "specular": [0.25] * 3, "roughness": 0.2},
            "smooth glass": {"transmission": [1] * 3, "ior": 1.5}}
    tab = closure.table(Materials.from_list(list(rows.values())))
    u = np.random.default_rng(0).random((n, 4))
    _lobe_loop(tab, 0, u[:10], 0)
    _lobe_loop(tab, 0, u[:10], 1)
    print(f"lobes per hit ({n} hits, one thread):")
    base = None
    for m, name in enumerate(rows):
        out = []
        for which in (0, 1):
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter()
                _lobe_loop(tab, m, u, which)
                best = min(best, time.perf_counter() - t0)
            out.append(best / n * 1e9)
        base = base or out
        print(f"  {name:14s} sample {out[0]:6.1f} ns  eval {out[1]:6.1f} ns  "
              f"(x{out[0] / base[0]:.2f} / x{out[1] / base[1]:.2f} Lambert)")


def glossy_room(size: int) -> Scene:
    room = shapes.box([-1, -1, 0], [1, 1, 2], inward=True)
    c = room.corners
    left = np.all(np.isclose(c[:, :, 0], -1), axis=1)
    right = np.all(np.isclose(c[:, :, 0], 1), axis=1)
    floor = np.all(np.isclose(c[:, :, 2], 0), axis=1)
    rest = ~(left | right | floor)
    parts = [(shapes.Part(c[rest], room.normals[rest]), 0),
             (shapes.Part(c[left], room.normals[left]), 1),
             (shapes.Part(c[right], room.normals[right]), 2),
             (shapes.Part(c[floor], room.normals[floor]), 3),
             (shapes.uv_sphere([0.0, 0.2, 0.5], 0.5, 24, 48), 4)]
    mats = Materials.from_list([
        {"diffuse": [0.75] * 3}, {"diffuse": [0.75, 0.1, 0.1]}, {"diffuse": [0.1, 0.75, 0.1]},
        {"diffuse": [0.5] * 3, "specular": [0.25] * 3, "roughness": 0.2},
        {"specular": [0.9, 0.7, 0.5], "roughness": 0.3}])
    lights = Lights.from_list([{"kind": LIGHT_AREA, "position": [0, 0, 1.98], "power": 40.0,
                                "size": [0.5, 0.5]}])
    cam = shapes.pinhole([0, -0.95, 1.0], [0, 0.3, 0.6], size, size, np.radians(75))
    return Scene(shapes.assemble(parts), mats, lights, cam)


def after_glossy(size: int, samples: int) -> None:
    scene = glossy_room(size)
    st = RenderSettings(samples=samples, adaptive_threshold=0.0, global_photons=100_000,
                        caustic_photons=100_000, final_gather_rays=32, max_specular_depth=4,
                        seed=1)
    photon_mapping.GLOBAL_AFTER_GLOSSY = False
    ref = photon_mapping.render(scene, st.with_values(samples=4 * samples, seed=7))
    rows = []
    for on in (True, False):
        photon_mapping.GLOBAL_AFTER_GLOSSY = on
        out = photon_mapping.render(scene, st)
        rows.append((on, out))
    print(f"after a glossy bounce ({size}x{size}, {samples} spp, reference {4 * samples} spp):")
    for on, out in rows:
        e_spec = np.sqrt(np.mean((out.passes["specular"] - ref.passes["specular"]) ** 2))
        e_comb = np.sqrt(np.mean((out.passes["combined"] - ref.passes["combined"]) ** 2))
        s = out.stats
        print(f"  global map after glossy {'on ' if on else 'off'}: render {s['time_render']:6.2f} s, "
              f"gather rays {s['rays_gather']:>9d}, rays/s {s['rays_per_second'] / 1e6:5.2f} M, "
              f"RMS error specular {e_spec:.4f}, combined {e_comb:.4f} "
              f"(specular mean {out.passes['specular'].mean():.4f} vs ref "
              f"{ref.passes['specular'].mean():.4f})")
    photon_mapping.GLOBAL_AFTER_GLOSSY = True


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--samples", type=int, default=8)
    ap.add_argument("--skip-lobes", action="store_true")
    a = ap.parse_args()
    if not a.skip_lobes:
        lobe_costs()
    after_glossy(a.size, a.samples)


if __name__ == "__main__":
    main()
