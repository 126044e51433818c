"""Photon Map's renderer: numpy arrays in, numpy images out. Never imports bpy.

Modules, each one idea: scene (the data contract), settings, accel (Embree), camera,
lights, bsdf, integrator (the camera pass), photon_map (storage, balance, k-NN),
estimate (density estimation), exr (OpenEXR output).
"""

# Before any kernel module is imported: numba's on-disk cache must be kept apart per
# package name (core / photon_map.core / bl_ext...photon_map.core), see _numba_cache.
from . import _numba_cache  # noqa: F401
