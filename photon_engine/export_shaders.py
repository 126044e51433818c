"""The BSDF nodes -> closures (core/scene/closures.py), with Cycles' node semantics.

One function per node, ``(reader, node) -> Closure``, registered in ``HANDLERS`` by
``bl_idname``. Each writes one closure row holding the node's inputs in the slots its
kind reads (clamped where Cycles' SVM clamps them, export_nodes.NodeReader) and the
legacy lobes the core's passes read until they read the closure table:

| node | closure | legacy lobes |
|---|---|---|
| Principled BSDF | PRINCIPLED, every slot | diffuse base (1-m)(1-t), specular base m, glass base (1-m) t |
| Diffuse BSDF | DIFFUSE (colour, roughness) | diffuse |
| Glossy BSDF | GLOSSY (colour, roughness, anisotropy, rotation, distribution) | specular |
| Metallic BSDF (4.3+) | METALLIC (F0, edge tint, n, k, Fresnel type, ...) | specular = F0 |
| Glass BSDF | GLASS (colour, roughness, IOR, distribution) | glass |
| Refraction BSDF | REFRACTION (colour, roughness, IOR, distribution) | glass |
| Translucent BSDF | TRANSLUCENT (colour) | diffuse |
| Sheen BSDF | SHEEN (colour, roughness) | none |
| Subsurface Scattering | DIFFUSE (colour), reported | diffuse |

An Image Texture into a node's colour input (Base Color / Color) is the closure's
``texture`` with COLOR white (the legacy lobes: only the diffuse lobe is textured, the
others take the image's mean colour). Linked Normal / Coat Normal / Tangent inputs, thin
film, subsurface and values Cycles would clamp are reported (export_nodes).
"""

from __future__ import annotations

import numpy as np

from ..core.scene import closures as cl
from . import compat
from .export_nodes import Closure, closure_row, diffuse_closure, follow_reroutes, \
    legacy_glossy

INF = float("inf")

MICROFACETS = {"GGX": cl.DISTRIBUTION_GGX, "MULTI_GGX": cl.DISTRIBUTION_MULTI_GGX,
               "BECKMANN": cl.DISTRIBUTION_BECKMANN,
               "ASHIKHMIN_SHIRLEY": cl.DISTRIBUTION_ASHIKHMIN_SHIRLEY,
               "SHARP": cl.DISTRIBUTION_GGX}
"""Blender's ``distribution`` enum items -> the DISTRIBUTION slot. Blender 3.x's "SHARP"
is GGX at roughness 0 (``_roughness``)."""

FRESNEL = {"F82": cl.FRESNEL_F82, "PHYSICAL_CONDUCTOR": cl.FRESNEL_CONDUCTOR}
"""Metallic BSDF's ``fresnel_type`` items -> the FRESNEL_TYPE slot."""


def _distribution(reader, node, allowed, fallback):
    table = {k: MICROFACETS[k] for k in (*allowed, "SHARP")}
    return float(reader.enum(node, "distribution", table, table[fallback]))


def _roughness(reader, node) -> float:
    """The Roughness input; 0 under Blender 3.x's "SHARP" distribution (which hides it)."""
    if getattr(node, "distribution", None) == "SHARP":
        return 0.0
    return reader.ranged(node, "Roughness")


def principled(reader, node) -> Closure:
    """Principled BSDF v2 (4.0+): every input in its slot; emission and alpha per material."""
    base, tex, tint = reader.textured_color(node, "Base Color")
    metallic = reader.ranged(node, "Metallic")
    roughness = reader.ranged(node, "Roughness")
    transmission = reader.ranged(node, "Transmission Weight", default=0.0)
    ior = reader.ior(node, "IOR", default=1.5)
    subsurface = reader.ranged(node, "Subsurface Weight", default=0.0)
    if subsurface > 0.0:
        reader.note_node(node, f"subsurface scattering (weight {subsurface:g}) is rendered "
                               f"as its diffuse approximation")
    reader.thin_film(node)
    reader.ignored_links(node, "Normal", "Coat Normal", "Tangent")
    values = dict(
        color=base, metallic=metallic, roughness=roughness, ior=ior,
        specular_level=reader.ranged(node, "Specular IOR Level", 0.0, INF, default=0.5),
        specular_tint=reader.tint(node, "Specular Tint", base),
        transmission=transmission,
        coat_weight=reader.ranged(node, "Coat Weight", default=0.0),
        coat_roughness=reader.ranged(node, "Coat Roughness", default=0.03),
        coat_ior=reader.ranged(node, "Coat IOR", 1.0, INF, default=1.5),
        coat_tint=reader.ranged_color(node, "Coat Tint", default=(1, 1, 1)),
        sheen_weight=reader.ranged(node, "Sheen Weight", default=0.0),
        sheen_roughness=reader.ranged(node, "Sheen Roughness", default=0.5),
        sheen_tint=np.minimum(reader.tint(node, "Sheen Tint", base), 1.0),
        anisotropic=reader.ranged(node, "Anisotropic", default=0.0),
        anisotropic_rotation=reader.ranged(node, "Anisotropic Rotation", -INF, INF, default=0.0),
        diffuse_roughness=reader.ranged(node, "Diffuse Roughness", default=0.0),
        subsurface_weight=subsurface,
        thin_wall=1.0 if compat.thin_wall(node) else 0.0,
        distribution=_distribution(reader, node, ("GGX", "MULTI_GGX"), "MULTI_GGX"),
    )
    c = legacy_glossy(Closure(bsdfs=[closure_row(cl.CLOSURE_PRINCIPLED, texture=tex, **values)]),
                      spec=tint * metallic, trans=tint * (1 - metallic) * transmission,
                      roughness=roughness, ior=ior)
    c.diffuse = base * (1 - metallic) * (1 - transmission)
    c.diffuse_texture = tex
    emission = reader.ranged_color(node, "Emission Color", INF, default=(0, 0, 0))
    c.emission = emission * reader.ranged(node, "Emission Strength", 0.0, INF, default=1.0)
    c.emitters = [{"node": node, "color": "Emission Color", "strength": "Emission Strength",
                   "weight": 1.0}]
    atex, linked_alpha = reader.image_input(node, ("Alpha",), "Alpha")
    sock = compat.input_socket(node, "Alpha")
    programmed = (not linked_alpha and reader.linked is not None and sock is not None
                  and sock.is_linked and _constant_link(sock) is False)
    alpha = 1.0 if linked_alpha or programmed else reader.ranged(node, "Alpha", default=1.0)
    if programmed:  # a node graph into Alpha: the program's opacity (export_materials)
        reader.linked.append((node, sock))
        c.cutouts = [{"node": node, "socket": "Alpha", "kind": "alpha", "weight": 1.0}]
        cut = {"node": node, "socket": sock, "take": True}  # the surface's share: alpha
        c.bsdfs = [dict(b, cuts=[cut]) for b in c.bsdfs]
        c.emitters = [dict(e, cuts=[cut]) for e in c.emitters]
    if alpha < 1.0:
        c = c.scaled(alpha)
        c.transparency = 1.0 - alpha
    c.alpha_texture = atex
    return c


def _constant_link(sock):
    """None: unlinked (or an invalid link); True: fed by a constant RGB / Value node (the
    reader reads it); False: fed by any other node (a program computes it)."""
    linked = follow_reroutes(sock)
    if linked is None:
        return None
    return linked.node.bl_idname in ("ShaderNodeRGB", "ShaderNodeValue")


def diffuse(reader, node) -> Closure:
    """Diffuse BSDF: Lambert at roughness 0, Oren-Nayar above (Cycles' sigma = roughness)."""
    color, tex, _ = reader.textured_color(node, "Color")
    reader.ignored_links(node, "Normal")
    c = diffuse_closure(color, tex)
    c.bsdfs[0]["params"][cl.ROUGHNESS] = reader.ranged(node, "Roughness", default=0.0)
    return c


def glossy(reader, node) -> Closure:
    """Glossy BSDF (ShaderNodeBsdfAnisotropic in 4.x/5.x): colour as a constant Fresnel
    tint, Anisotropy in [-1, 1] (Cycles clamps to +-0.99: negative stretches along the
    bitangent), Rotation a fraction of a turn."""
    color, tex, tint = reader.textured_color(node, "Color")
    roughness = _roughness(reader, node)
    reader.ignored_links(node, "Normal", "Tangent")
    if getattr(node, "distribution", "GGX") == "ASHIKHMIN_SHIRLEY":
        reader.note_node(node, 'glossy distribution "ASHIKHMIN_SHIRLEY" is rendered as GGX')
    values = dict(color=color, roughness=roughness,
                  anisotropic=reader.ranged(node, "Anisotropy", -1.0, 1.0, default=0.0),
                  anisotropic_rotation=reader.ranged(node, "Rotation", -INF, INF, default=0.0),
                  distribution=_distribution(reader, node, tuple(MICROFACETS), "MULTI_GGX"))
    return legacy_glossy(Closure(bsdfs=[closure_row(cl.CLOSURE_GLOSSY, texture=tex, **values)]),
                         spec=tint, roughness=roughness)


def metallic(reader, node) -> Closure:
    """Metallic BSDF (4.3+): F82 tint (Base Color at normal incidence, Edge Tint at 82
    degrees) or the physical conductor's complex IOR (IOR + i Extinction per channel).
    Blender hides the inputs of the other Fresnel type (Cycles ignores them): they keep
    the contract's defaults."""
    fresnel = reader.enum(node, "fresnel_type", FRESNEL, cl.FRESNEL_F82)
    defaults = cl.default_params()
    if fresnel == cl.FRESNEL_F82:
        color, tex, tint = reader.textured_color(node, "Base Color")
        edge = reader.ranged_color(node, "Edge Tint", default=(1, 1, 1))
        n, k = defaults[cl.METAL_N:cl.METAL_N + 3], defaults[cl.METAL_K:cl.METAL_K + 3]
    else:
        color, tex = defaults[cl.COLOR:cl.COLOR + 3], -1
        edge = defaults[cl.SPECULAR_TINT:cl.SPECULAR_TINT + 3]
        n = reader.ranged_color(node, "IOR", INF, default=defaults[cl.METAL_N:cl.METAL_N + 3])
        k = reader.ranged_color(node, "Extinction", INF,
                                default=defaults[cl.METAL_K:cl.METAL_K + 3])
        # Legacy tint: the conductor's reflectance at normal incidence.
        tint = ((n - 1) ** 2 + k ** 2) / np.maximum((n + 1) ** 2 + k ** 2, 1e-12)
    roughness = reader.ranged(node, "Roughness")
    reader.thin_film(node)
    reader.ignored_links(node, "Normal", "Tangent")
    # Anisotropy in [0, 1] as Principled's (the Glossy BSDF's goes negative).
    values = dict(color=color, roughness=roughness, specular_tint=edge,
                  anisotropic=reader.ranged(node, "Anisotropy", default=0.0),
                  anisotropic_rotation=reader.ranged(node, "Rotation", -INF, INF, default=0.0),
                  distribution=_distribution(reader, node, ("BECKMANN", "GGX", "MULTI_GGX"),
                                             "MULTI_GGX"),
                  fresnel_type=float(fresnel), metal_n=n, metal_k=k)
    return legacy_glossy(Closure(bsdfs=[closure_row(cl.CLOSURE_METALLIC, texture=tex, **values)]),
                         spec=tint, roughness=roughness)


def _dielectric(reader, node, kind, allowed, fallback) -> Closure:
    color, tex, tint = reader.textured_color(node, "Color")
    roughness = _roughness(reader, node)
    ior = reader.ior(node, "IOR")
    reader.thin_film(node)
    reader.ignored_links(node, "Normal")
    values = dict(color=color, roughness=roughness, ior=ior,
                  distribution=_distribution(reader, node, allowed, fallback))
    return legacy_glossy(Closure(bsdfs=[closure_row(kind, texture=tex, **values)]),
                         trans=tint, roughness=roughness, ior=ior)


def glass(reader, node) -> Closure:
    """Glass BSDF: Fresnel-weighted reflection and refraction, both tinted by the colour."""
    return _dielectric(reader, node, cl.CLOSURE_GLASS, ("BECKMANN", "GGX", "MULTI_GGX"),
                       "MULTI_GGX")


def refraction(reader, node) -> Closure:
    """Refraction BSDF: the refracted part only (legacy: a glass lobe)."""
    return _dielectric(reader, node, cl.CLOSURE_REFRACTION, ("BECKMANN", "GGX"), "BECKMANN")


def translucent(reader, node) -> Closure:
    """Translucent BSDF: Lambert transmission to the far side (legacy: diffuse)."""
    color, tex, _ = reader.textured_color(node, "Color")
    reader.ignored_links(node, "Normal")
    return Closure(diffuse=color, diffuse_texture=tex,
                   bsdfs=[closure_row(cl.CLOSURE_TRANSLUCENT, texture=tex, color=color)])


def sheen(reader, node) -> Closure:
    """Sheen BSDF: the Microfiber model (Cycles' default); Ashikhmin is reported and
    rendered as Microfiber. No legacy lobe."""
    color, tex, _ = reader.textured_color(node, "Color")
    if getattr(node, "distribution", "MICROFIBER") != "MICROFIBER":
        reader.note_node(node, f'sheen distribution "{node.distribution}" is rendered as '
                               f'MICROFIBER')
    reader.ignored_links(node, "Normal")
    return Closure(bsdfs=[closure_row(cl.CLOSURE_SHEEN, texture=tex, color=color,
                               roughness=reader.ranged(node, "Roughness"))])


def subsurface(reader, node) -> Closure:
    """Subsurface Scattering: its diffuse approximation (colour as albedo), reported."""
    color, tex, _ = reader.textured_color(node, "Color")
    reader.note_node(node, "subsurface scattering is rendered as its diffuse approximation")
    reader.ignored_links(node, "Normal")
    return diffuse_closure(color, tex)


HANDLERS = {
    "ShaderNodeBsdfPrincipled": principled,
    "ShaderNodeBsdfDiffuse": diffuse,
    "ShaderNodeBsdfGlossy": glossy,
    "ShaderNodeBsdfAnisotropic": glossy,  # 4.x/5.x: the Glossy BSDF's real idname
    "ShaderNodeBsdfMetallic": metallic,
    "ShaderNodeBsdfGlass": glass,
    "ShaderNodeBsdfRefraction": refraction,
    "ShaderNodeBsdfTranslucent": translucent,
    "ShaderNodeBsdfSheen": sheen,
    "ShaderNodeSubsurfaceScattering": subsurface,
}
"""bl_idname -> the function turning that node into a Closure."""
