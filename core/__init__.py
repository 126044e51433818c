"""Photon Map's renderer: numpy arrays in, numpy images out. Never imports bpy.

``core.render(scene, settings, on_progress=None, on_tile=None, should_stop=None)`` renders
a ``core.scene.contract.Scene`` and returns a ``core.passes.RenderOutput``. The packages,
from the bottom up (each imports only those below it; docs/architecture.md):

- top-level modules: ``sampling`` (counter-based random numbers, the table of random
  streams), ``color``, ``settings`` and ``presets``, ``passes`` (pass names,
  RenderOutput, the callback types), ``_numba_cache``;
- ``scene``: the data contract (Scene and its arrays, validation), camera rays, the Embree
  accelerator, ray-offset geometry, bounding spheres, test shapes;
- ``materials``: BSDF lobes and texture lookup; ``lights``: light sets, light sampling and
  intersection kernels;
- ``prepared``: the PreparedScene, every per-render table built once;
- ``photons``: the seed's first pass: emission, scattering, storage rules, tracing,
  importance, encoding, the kd-tree (balance, locate), the photon map, density
  estimation, the hash grid;
- ``integrators``: how an image is formed: camera paths, direct light, final gathering
  and the radiance cache, the photon terms, the photon-mapping integrator, SPPM, the
  debug overlay;
- ``io``: EXR files; ``api``: the entry points ``render``, ``render_to_exr`` and
  ``progressive`` (the viewport's resumable passes).
"""

# Before any kernel module is imported: numba's on-disk cache must be kept apart per
# package name (core / photon_map.core / bl_ext...photon_map.core), see _numba_cache.
from . import _numba_cache  # noqa: F401
from .api import progressive, render, render_to_exr  # noqa: E402,F401
