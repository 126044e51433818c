"""The closure table: how a material's BSDFs cross the boundary (see ``contract.Materials``).

A material is a weighted sum of closures, like Cycles' SVM output: Mix Shader and Add Shader
are flattened by the exporter into weights, so material m is

    f_m = sum over c in [closure_first[m], closure_first[m] + closure_count[m])
          of closure_weight[c] * f_kind[c](closure_params[c])

Each closure row has a kind (``CLOSURE_*``, int32) and a fixed-width parameter row of
``PARAM_COUNT`` float32 values, read by the named indices below (colours take three
consecutive slots). A kind reads only the slots its comment names; the others are ignored
(the exporter leaves them at ``default_params()``). Values are Blender's node inputs as the
user set them, already clamped to the ranges Blender's UI allows; the core owns what they
mean (core/materials/). Emission and opacity are per material (``Materials.emission``,
``Materials.alpha``), not closures.

The explicit integer values cross the boundary and are stored in nothing persistent, but
tests and the exporter name them: add new kinds and slots at the end.
"""

from __future__ import annotations

import numpy as np

# --- closure kinds (Materials.closure_kind) --------------------------------------------------
CLOSURE_DIFFUSE = 0      # Diffuse BSDF: COLOR, ROUGHNESS (Oren-Nayar sigma as Cycles)
CLOSURE_GLOSSY = 1       # Glossy BSDF: COLOR, ROUGHNESS, ANISOTROPIC, ANISOTROPIC_ROTATION,
                         # DISTRIBUTION; no Fresnel (tint = COLOR), like Cycles
CLOSURE_GLASS = 2        # Glass BSDF: COLOR, ROUGHNESS, IOR, DISTRIBUTION
CLOSURE_REFRACTION = 3   # Refraction BSDF: COLOR, ROUGHNESS, IOR, DISTRIBUTION
CLOSURE_TRANSLUCENT = 4  # Translucent BSDF: COLOR (Lambert on the far side)
CLOSURE_SHEEN = 5        # Sheen BSDF (Microfiber): COLOR, ROUGHNESS
CLOSURE_METALLIC = 6     # Metallic BSDF (Blender 4.3+): COLOR (F0), SPECULAR_TINT (F82 edge
                         # tint), ROUGHNESS, ANISOTROPIC, ANISOTROPIC_ROTATION, DISTRIBUTION,
                         # FRESNEL_TYPE, METAL_N, METAL_K
CLOSURE_PRINCIPLED = 7   # Principled BSDF v2 (Blender 4.0+): every slot but FRESNEL_TYPE,
                         # METAL_N, METAL_K
CLOSURE_KIND_NAMES = {
    CLOSURE_DIFFUSE: "DIFFUSE", CLOSURE_GLOSSY: "GLOSSY", CLOSURE_GLASS: "GLASS",
    CLOSURE_REFRACTION: "REFRACTION", CLOSURE_TRANSLUCENT: "TRANSLUCENT",
    CLOSURE_SHEEN: "SHEEN", CLOSURE_METALLIC: "METALLIC", CLOSURE_PRINCIPLED: "PRINCIPLED",
}

# --- microfacet distributions (the DISTRIBUTION slot) ----------------------------------------
DISTRIBUTION_GGX = 0            # single-scatter GGX
DISTRIBUTION_MULTI_GGX = 1      # multiscatter GGX (energy compensated; Cycles' default)
DISTRIBUTION_BECKMANN = 2       # Beckmann (Glossy / Glass / Refraction nodes)
DISTRIBUTION_ASHIKHMIN_SHIRLEY = 3

# --- Fresnel of the Metallic BSDF (the FRESNEL_TYPE slot) ------------------------------------
FRESNEL_F82 = 0                 # "F82 Tint": COLOR at normal incidence, SPECULAR_TINT at 82 deg
FRESNEL_CONDUCTOR = 1           # "Physical Conductor": complex IOR METAL_N + i METAL_K per channel

# --- parameter slots (Materials.closure_params[:, slot]) --------------------------------------
COLOR = 0                  # 3 slots: Base Color / Color, linear RGB
ROUGHNESS = 3              # Roughness in [0, 1] (alpha = roughness^2)
METALLIC = 4               # Metallic in [0, 1]
IOR = 5                    # IOR (> 0; 1 = no refraction)
SPECULAR_LEVEL = 6         # Specular IOR Level in [0, inf), 0.5 = the IOR as given
SPECULAR_TINT = 7          # 3 slots: Specular Tint (Principled) / Edge Tint (Metallic F82)
TRANSMISSION = 10          # Transmission Weight in [0, 1]
COAT_WEIGHT = 11
COAT_ROUGHNESS = 12
COAT_IOR = 13
COAT_TINT = 14             # 3 slots
SHEEN_WEIGHT = 17
SHEEN_ROUGHNESS = 18
SHEEN_TINT = 19            # 3 slots
ANISOTROPIC = 22           # Anisotropic in [0, 1]
ANISOTROPIC_ROTATION = 23  # Anisotropic Rotation in [0, 1] (fraction of a turn)
DIFFUSE_ROUGHNESS = 24     # Diffuse Roughness in [0, 1] (Blender 4.3+)
SUBSURFACE_WEIGHT = 25     # rendered as diffuse (the exporter warns)
THIN_WALL = 26             # 0 or 1 (Blender 5.2's Thin Wall)
DISTRIBUTION = 27          # DISTRIBUTION_* as a float
FRESNEL_TYPE = 28          # FRESNEL_* as a float
METAL_N = 29               # 3 slots
METAL_K = 32               # 3 slots
TANGENT = 35               # 3 slots: a linked Tangent input (world space, any length); 0 =
                           # unlinked: Cycles' default, the radial tangent about the
                           # object's Z axis (core.prepared.HitShader.tangents)
COAT_NORMAL = 38           # 3 slots: a linked Coat Normal (Principled; world space, made
                           # unit and valid by core.prepared.HitShader.shade); 0 = unlinked:
                           # the coat shades with the shading normal (where a Bump / Normal
                           # Map bends it, shade fills in the un-bent one, as Cycles' sd->N)
PARAM_COUNT = 41


def default_params() -> np.ndarray:
    """(PARAM_COUNT,) float32: Blender's defaults of a new Principled BSDF (base 0.8 grey,
    roughness 0.5, IOR 1.5 (4.2+ default 1.5; 1.45 before), specular level 0.5, white tints,
    coat IOR 1.5, sheen roughness 0.5, multiscatter GGX, F82)."""
    p = np.zeros(PARAM_COUNT, np.float32)
    p[COLOR:COLOR + 3] = 0.8
    p[ROUGHNESS] = 0.5
    p[IOR] = 1.5
    p[SPECULAR_LEVEL] = 0.5
    p[SPECULAR_TINT:SPECULAR_TINT + 3] = 1.0
    p[COAT_ROUGHNESS] = 0.03
    p[COAT_IOR] = 1.5
    p[COAT_TINT:COAT_TINT + 3] = 1.0
    p[SHEEN_ROUGHNESS] = 0.5
    p[SHEEN_TINT:SHEEN_TINT + 3] = 1.0
    p[DISTRIBUTION] = DISTRIBUTION_MULTI_GGX
    p[FRESNEL_TYPE] = FRESNEL_F82
    p[METAL_N:METAL_N + 3] = (2.757, 2.513, 2.231)
    p[METAL_K:METAL_K + 3] = (3.867, 3.404, 3.009)
    return p


_SLOTS = {
    "color": (COLOR, 3), "roughness": (ROUGHNESS, 1), "metallic": (METALLIC, 1),
    "ior": (IOR, 1), "specular_level": (SPECULAR_LEVEL, 1),
    "specular_tint": (SPECULAR_TINT, 3), "transmission": (TRANSMISSION, 1),
    "coat_weight": (COAT_WEIGHT, 1), "coat_roughness": (COAT_ROUGHNESS, 1),
    "coat_ior": (COAT_IOR, 1), "coat_tint": (COAT_TINT, 3),
    "sheen_weight": (SHEEN_WEIGHT, 1), "sheen_roughness": (SHEEN_ROUGHNESS, 1),
    "sheen_tint": (SHEEN_TINT, 3), "anisotropic": (ANISOTROPIC, 1),
    "anisotropic_rotation": (ANISOTROPIC_ROTATION, 1),
    "diffuse_roughness": (DIFFUSE_ROUGHNESS, 1), "subsurface_weight": (SUBSURFACE_WEIGHT, 1),
    "thin_wall": (THIN_WALL, 1), "distribution": (DISTRIBUTION, 1),
    "fresnel_type": (FRESNEL_TYPE, 1), "metal_n": (METAL_N, 3), "metal_k": (METAL_K, 3),
    "tangent": (TANGENT, 3), "coat_normal": (COAT_NORMAL, 3),
}
PARAM_NAMES = tuple(_SLOTS)
"""The keyword names ``params()`` accepts, one per slot group."""


def params(**values) -> np.ndarray:
    """(PARAM_COUNT,) float32 row: ``default_params()`` with the named slots replaced, e.g.
    ``params(color=(0.9, 0.6, 0.2), roughness=0.3, metallic=1.0)``. Unknown names raise
    ``KeyError`` naming them."""
    p = default_params()
    for name, value in values.items():
        if name not in _SLOTS:
            raise KeyError(f"unknown closure parameter {name!r}; known: {', '.join(PARAM_NAMES)}")
        start, width = _SLOTS[name]
        p[start:start + width] = value
    return p
