"""The photon pass of a render: which photon terms the scene and settings need, the
tracing (core/tracing.py, with the render's Accelerator), the automatic radii, the
radiance cache for final gathering, and why a term is skipped.

Called once per render by core/integrator.py before the camera pass; fills
``ctx.terms`` (a gather.PhotonTerms) and returns the stats the render reports:
``photon_maps`` (the tracer's own stats), ``caustic_photons_stored`` /
``global_photons_stored``, ``caustic_radius`` / ``global_radius`` (metres),
``gather_rays_per_sample``, ``diffuse_area`` (m^2) and ``skipped`` (term -> reason).
"""

from __future__ import annotations

import numpy as np

from . import gather, geometry


def run(ctx, maps, progress, share: float) -> tuple[dict, bool]:
    """Trace (or take) the photon maps and resolve what the camera pass adds.

    ctx: the integrator's render context (scene, settings, accel, triangles, materials);
    maps: a tracing.PhotonMaps (or a stand-in with the same fields) to use instead of
    tracing; progress: the render's callback, given fractions in [0, share].
    Sets ctx.terms; returns (stats, cancelled). A term is skipped, with its reason in
    stats["skipped"], when the settings switch it off, when the scene cannot produce it,
    or when the tracer built no map for it.
    """
    st = ctx.settings
    used = np.zeros(ctx.materials["diffuse"].shape[0], bool)
    used[np.unique(ctx.tri_material)] = True
    specular = bool(np.any(used & (ctx.has_delta | (np.any(ctx.materials["specular"] > 0, axis=1)
                                                    & ~ctx.has_diffuse))))
    diffuse_area = gather.diffuse_area(ctx.tri_vertices, ctx.tri_material, ctx.materials["diffuse"])
    skipped = {}
    if not st.caustics:
        skipped["caustics"] = "caustics switched off"
    elif st.caustic_photons == 0:
        skipped["caustics"] = "0 caustic photons"
    elif not specular:
        skipped["caustics"] = "no mirror, glass or glossy surface in the scene"
    if st.indirect_mode == "off":
        skipped["indirect"] = "indirect light switched off"
    elif st.global_photons == 0:
        skipped["indirect"] = "0 global photons"
    if diffuse_area == 0.0:
        for term in ("caustics", "indirect"):
            skipped.setdefault(term, "no diffuse surface to receive photons")
    wanted = [t for t in ("caustics", "indirect") if t not in skipped]
    stats = {"traced": False, "photon_maps": {}}
    cancelled = False
    if maps is None and wanted:
        from . import tracing

        # Far from the origin the ray offsets swallow the gaps caustics leave through
        # (half the caustic is lost at 1e5 m for a 2 m room): refuse, naming float32.
        geometry.check_float32_precision(ctx.scene)

        state = {"cancelled": False}

        def photon_progress(fraction, message):
            if progress is None:
                return False
            state["cancelled"] = bool(progress(share * fraction, message))
            return state["cancelled"]

        # The tracer builds only the maps of the terms rendered: no caustic photons when,
        # say, the only glossy lobe sits on a diffuse base (the global map carries it).
        skip = {key: skipped[term] for term, key in (("caustics", "caustic"),
                                                     ("indirect", "global")) if term in skipped}
        maps = tracing.trace_photons(ctx.scene, st, ctx.accel, photon_progress,
                                     include_direct=st.indirect_mode == "final_gather",
                                     skip=skip)
        stats["traced"] = True
        cancelled = state["cancelled"]
        if progress is not None and not cancelled:
            built = [f"{name} map {len(m)} photons" for name, m in
                     (("caustic", maps.caustic_map), ("global", maps.global_map)) if m is not None]
            cancelled = bool(progress(share, "Photons traced: " + (", ".join(built)
                                                                          or "no map built")))
    caustic_map = global_map = None
    if maps is not None:
        stats["photon_maps"] = dict(maps.stats)
        caustic_map = maps.caustic_map if "caustics" in wanted else None
        global_map = maps.global_map if "indirect" in wanted else None
        decisions = list(maps.stats.get("decisions", [])) if isinstance(maps.stats, dict) else []
        for term, found, key in (("caustics", caustic_map, "caustic"),
                                 ("indirect", global_map, "global")):
            if term in wanted and (found is None or len(found) == 0):
                why = [d for d in decisions if d.startswith(f"{key} map")]
                skipped[term] = why[-1] if why else f"no {key} photons stored"
    caustic_map = caustic_map if caustic_map is not None and len(caustic_map) else None
    global_map = global_map if global_map is not None and len(global_map) else None
    n_c = len(caustic_map) if caustic_map is not None else 0
    n_g = len(global_map) if global_map is not None else 0
    r_c = st.caustic_radius or gather.auto_radius(diffuse_area, st.caustic_k, n_c)
    r_g = st.global_radius or gather.auto_radius(diffuse_area, st.global_k, n_g)
    ctx.terms = gather.PhotonTerms(
        caustic_map=caustic_map, global_map=global_map, caustic_k=st.caustic_k,
        global_k=st.global_k, caustic_radius=r_c, global_radius=r_g, filter=st.filter,
        mode=st.indirect_mode, gather_rays=max(1, st.final_gather_rays // st.samples))
    if global_map is not None and st.indirect_mode == "final_gather" and not cancelled:
        if progress is not None:
            points = 2 * gather.cache_point_count(n_g, diffuse_area, r_g)
            cancelled = bool(progress(share, f"Precomputing the radiance cache ({points:,} points)"))
        if not cancelled:
            asked = {"stop": False}

            def stop():
                # Between chunks of cache points: a cancel within a chunk's time.
                asked["stop"] = bool(progress is not None and progress(
                    share, "Precomputing the radiance cache"))
                return asked["stop"]

            cache = gather.build_radiance_cache(ctx.terms, ctx, should_stop=stop)
            cancelled = asked["stop"]
            ctx.terms.use_cache(None if cancelled else cache)
    stats.update({"caustic_photons_stored": n_c, "global_photons_stored": n_g,
                  "caustic_radius": r_c if n_c else 0.0, "global_radius": r_g if n_g else 0.0,
                  "gather_rays_per_sample": ctx.terms.gather_rays if n_g and
                  st.indirect_mode == "final_gather" else 0,
                  "diffuse_area": diffuse_area, "skipped": skipped})
    return stats, cancelled
