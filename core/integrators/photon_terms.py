"""The photon pass of a render: which photon terms the scene and settings need, the
tracing (core/photons/tracing.py, over the prepared scene, with the camera pre-pass of
photon importance), the automatic radii, the radiance cache for final gathering, and why a
term is skipped.

Called once per render by core/integrators/photon_mapping.py before the camera pass;
returns the ``gather.PhotonTerms`` the camera pass adds and the stats the render reports:
``photon_maps`` (the tracer's own stats), ``caustic_photons_stored`` /
``global_photons_stored``, ``caustic_radius`` / ``global_radius`` (metres),
``gather_rays_per_sample``, ``diffuse_area`` (m^2) and ``skipped`` (term -> reason).
"""

from __future__ import annotations

import numpy as np

from ..passes import ProgressFn, StopFn
from ..photons import estimate, tracing
from ..prepared import PreparedScene
from ..scene import geometry
from ..settings import RenderSettings
from . import camera_paths, gather


def trace_maps(prepared: PreparedScene, settings: RenderSettings,
               on_progress: ProgressFn | None = None, should_stop: StopFn | None = None, *,
               include_direct: bool = True, skip: dict | None = None) -> tracing.PhotonMaps:
    """``tracing.trace_photons`` with the camera pre-pass of photon importance
    (``camera_paths.importance_prepass``): the photon maps a render of ``prepared`` uses."""
    def prepass():
        return camera_paths.importance_prepass(prepared, settings.seed,
                                               settings.max_specular_depth)
    return tracing.trace_photons(prepared, settings, on_progress, should_stop,
                                 include_direct=include_direct, skip=skip, prepass=prepass)


def run(prepared: PreparedScene, settings: RenderSettings, maps,
        on_progress: ProgressFn | None, should_stop: StopFn | None,
        share: float) -> tuple[gather.PhotonTerms, dict, bool]:
    """Trace (or take) the photon maps and resolve what the camera pass adds.

    maps: a tracing.PhotonMaps (or a stand-in with the same fields) to use instead of
    tracing; on_progress gets fractions in [0, share]; should_stop() -> True cancels.
    Returns (terms, stats, cancelled). A term is skipped, with its reason in
    stats["skipped"], when the settings switch it off, when the scene cannot produce it,
    or when the tracer built no map for it.
    """
    st = settings
    used = prepared.used_materials
    # Glossy-on-diffuse materials (a Principled wall's specular layer) count: the light
    # their glossy lobe reflects from the lights onto diffuse surfaces is the caustic map's.
    specular = bool(np.any(used & prepared.specular_material))
    diffuse_area = prepared.diffuse_area
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
    if diffuse_area == 0.0 and not (prepared.medium is not None and prepared.medium.scatters):
        for term in ("caustics", "indirect"):
            skipped.setdefault(term, "no diffuse surface to receive photons")
    wanted = [t for t in ("caustics", "indirect") if t not in skipped]
    stats = {"traced": False, "photon_maps": {}}
    cancelled = False
    if maps is None and wanted:
        # Far from the origin the ray offsets swallow the gaps caustics leave through
        # (half the caustic is lost at 1e5 m for a 2 m room): refuse, naming float32.
        geometry.check_float32_precision(prepared.scene)

        def photon_progress(fraction, message):
            if on_progress is not None:
                on_progress(share * fraction, message)

        # The tracer builds only the maps of the terms rendered: no caustic photons when,
        # say, the only glossy lobe sits on a diffuse base (the global map carries it).
        skip = {key: skipped[term] for term, key in (("caustics", "caustic"),
                                                     ("indirect", "global")) if term in skipped}
        maps = trace_maps(prepared, st, photon_progress, should_stop,
                          include_direct=st.indirect_mode == "final_gather", skip=skip)
        stats["traced"] = True
        cancelled = bool(maps.stats.get("cancelled"))
        if on_progress is not None and not cancelled:
            built = [f"{name} map {len(m)} photons" for name, m in
                     (("caustic", maps.caustic_map), ("global", maps.global_map)) if m is not None]
            on_progress(share, "Photons traced: " + (", ".join(built) or "no map built"))
        cancelled = cancelled or (should_stop is not None and should_stop())
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
    r_c = st.caustic_radius or estimate.auto_radius(diffuse_area, st.caustic_k, n_c)
    r_g = st.global_radius or estimate.auto_radius(diffuse_area, st.global_k, n_g)
    terms = gather.PhotonTerms(
        caustic_map=caustic_map, global_map=global_map, caustic_k=st.caustic_k,
        global_k=st.global_k, caustic_radius=r_c, global_radius=r_g, filter=st.filter,
        mode=st.indirect_mode, gather_rays=max(1, st.final_gather_rays // st.samples))
    # Diffuse-like lobes that are not Lambert: the terms evaluate the BSDF there (gather.py)
    lobes = prepared.lobes
    if np.any(lobes["non_lambert"] & used):
        terms.bsdf_materials = lobes["non_lambert"]
        terms.back_share = np.where(lobes["diffuse_transmits"], gather.BACK_SHARE, 0.0)
    terms.medium = prepared.medium
    if maps is not None and terms.medium is not None:
        indirect = "indirect" in wanted
        terms.volume_map = getattr(maps, "volume_map", None) if indirect else None
        terms.volume_gather_map = getattr(maps, "volume_gather_map", None) if indirect else None
        terms.volume_caustic_map = (getattr(maps, "volume_caustic_map", None)
                                    if "caustics" in wanted else None)
    if global_map is not None and st.indirect_mode == "final_gather" and not cancelled:
        if on_progress is not None:
            points = 2 * gather.cache_point_count(n_g, diffuse_area, r_g)
            on_progress(share, f"Precomputing the radiance cache ({points:,} points)")
        cancelled = should_stop is not None and should_stop()
        if not cancelled:
            cache = gather.build_radiance_cache(terms, prepared, settings, should_stop=should_stop)
            cancelled = should_stop is not None and should_stop()
            terms.cache = None if cancelled else cache
    stats.update({"caustic_photons_stored": n_c, "global_photons_stored": n_g,
                  "caustic_radius": r_c if n_c else 0.0, "global_radius": r_g if n_g else 0.0,
                  "gather_rays_per_sample": terms.gather_rays if n_g and
                  st.indirect_mode == "final_gather" else 0,
                  "diffuse_area": diffuse_area, "skipped": skipped})
    return terms, stats, cancelled
