"""Speed for accuracy: each quality preset, SPPM pass counts and Cycles at equal wall time,
measured against converged references on four scenes built with bpy.

    .venv/bin/python benchmarks/tradeoff.py --write-docs --json out/tradeoff.json  # full run
    .venv/bin/python benchmarks/tradeoff.py --scenes demo --quick # a short development run
    .venv/bin/python benchmarks/tradeoff.py --make-references [--scenes ...] [--resolution WxH]

--write-docs rewrites the generated block of docs/tradeoff.md and docs/images/tradeoff_<scene>.png;
--strip draws docs/images/tradeoff_presets.png (each preset's image beside the reference).
--pictures writes only the scenes' pictures (docs/images/tradeoff_<scene>.png, and for the fog
scenes tradeoff_<scene>_images.png: each preset above Cycles at about its wall time), not
docs/tradeoff.md (a run of some scenes must not drop the others' rows there):

    .venv/bin/python benchmarks/tradeoff.py --scenes fog_spot_1m,fog_caustic_1m --quick --pictures
    .venv/bin/python benchmarks/tradeoff.py --scenes fog_caustic,fog_spot --quick --pictures

Scenes (SCENES): ``demo`` (the Cornell box of examples/cornell_box.py: mirror and glass
spheres, a small area light), ``caustic`` (a glass sphere on a floor under a small area
light, tests/blender/cycles_caustic_reference.py's scene), ``interior`` (a closed room lit
only by an area light facing the ceiling: almost every visible pixel is indirect light),
``mirror`` (a room corner with a mirror wall, a diffuse sphere and box, a ceiling light),
``artist`` (a room of default Principled BSDF walls, a glossy floor, rough copper, gold and
frosted-glass spheres: issue 13's scene), ``fog_spot`` (a floor in World fog lit by a spot
light of radius 0.1 m) and ``fog_caustic`` (the same with a glass sphere under the spot: the
volumetric caustic), tests/blender/cycles_media_reference.py's scenes as they are (issue
16), and ``fog_spot_1m``, ``fog_caustic_1m``: the same with the spot light's radius 1 m,
where Cycles converges on the caustic (at 0.1 m it does not: an index-matched sphere darkens
its image by 13 %, that module's docstring); ``fog_box_caustic_1m``: the glass sphere in a
fog box under the 1 m light raised so that its sphere holds no fog (where Cycles' light hits
lose nothing, docs/volumes.md "Cycles' loss inside a wide light").

Resolutions: RESOLUTIONS (64 x 48, the caustic 96 x 72), or --resolution / --quick (48 x 36).
References (cached in benchmarks/references/<scene>_<W>x<H>.npz with the command that
regenerates them and a fingerprint of the code that built them; a stale or missing one is
re-rendered, or refused with the command under ``--no-make``):
- Cycles, full global illumination with BOUNCES bounces of every kind (Photon Map's
  ``photon_max_bounces`` and ``max_specular_depth``), caustics on, no clamping, no
  denoising, a 1-pixel box filter, 2 seeds x REF_SAMPLES samples averaged;
- for the fog scenes but ``fog_caustic``: cycles_media_reference.py's cached Cycles render
  (its seeds x samples, BOUNCES bounces, volume bounces included), at that module's
  resolution only;
- for ``caustic`` and ``fog_caustic`` (SPPM_REFERENCES): SPPM (sppm_reference) with 2 seeds
  x passes of photons, cross-checked against Cycles (for ``caustic`` a render of the same
  scene, for ``fog_caustic`` cycles_media_reference's cached one, which is dark there: the
  relMSE between the two is stored and printed); fog_caustic's procedure is also run on
  SPPM_CHECKS' scenes (fog_caustic_1m, fog_spot) and compared with their converged Cycles
  references (relMSE, channel means, worst 8 x 8 block; stored and printed).
``noise`` (noise_floor): the reference's own error estimated from its two halves (the
floor under which no method can be measured).

Methods, interleaved in one process (preset, Cycles, preset, ... then SPPM) so the shared
machine's load affects them alike: each preset of core/presets.py (wall time = the
exporter on the evaluated depsgraph + the photon pass + the camera pass, numba already
compiled), SPPM (core/integrators/sppm.py; wall time at 1, 4, 16, ... passes includes the export),
Cycles at CYCLES_SAMPLES samples (wall time = ``bpy.ops.render.render``: sync, BVH,
render; same settings as the reference, seed 0).

relMSE = mean((a - b)^2 / (b^2 + 0.01)) over pixels and channels; mean ratio =
mean(a) / mean(reference).
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import inspect
import json
import math
import pathlib
import os
import platform
import sys
import textwrap
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402

from tests.blender import cycles_caustic_reference as caustic_ref  # noqa: E402
from tests.blender import cycles_media_reference as media_ref  # noqa: E402
from tests.blender import cycles_reference as cref  # noqa: E402
from tests.blender import scenes  # noqa: E402
from tests.metrics import rel_mse  # noqa: E402

REF_DIR = ROOT / "benchmarks" / "references"
DOCS = ROOT / "docs"
RESOLUTIONS = {"demo": (64, 48), "caustic": (96, 72), "interior": (64, 48), "mirror": (64, 48),
               "artist": (64, 48), "fog_spot_1m": media_ref.RESOLUTION,
               "fog_caustic_1m": media_ref.RESOLUTION, "fog_spot": media_ref.RESOLUTION,
               "fog_caustic": media_ref.RESOLUTION,
               "fog_box_caustic_1m": media_ref.RESOLUTION}
"""Pixels per scene: small, so a full run fits ~30 min on 2 shared cores (the caustic is
larger: its reference is SPPM, whose cost does not grow with the pixel count)."""
QUICK_RESOLUTION = (48, 36)
BOUNCES = 8
"""Bounces of every kind for Cycles = Photon Map's photon_max_bounces and max_specular_depth."""
REF_SAMPLES = 4096
"""Cycles reference samples per seed (two seeds averaged)."""
CAUSTIC_REF_PASSES = 1024
CAUSTIC_REF_PHOTONS = 100_000
"""SPPM reference of the caustic scene: passes x photons per pass, per seed (two seeds)."""
FOG_REF_PASSES = 64
FOG_REF_PHOTONS = 50_000
"""SPPM reference of fog_caustic (0.1 m light, where Cycles does not converge): passes x
photons per pass, per seed (two seeds). About 2.6 s a pass on 2 shared cores (photon
tracing through the fog is most of it), so the reference and its two checks take ~20 min."""
SPPM_REFERENCES = {"caustic": (CAUSTIC_REF_PASSES, CAUSTIC_REF_PHOTONS),
                   "fog_caustic": (FOG_REF_PASSES, FOG_REF_PHOTONS)}
"""Scenes whose reference is SPPM (sppm_reference): (passes, photons per pass) per seed."""
SPPM_CHECKS = {"fog_caustic": ("fog_caustic_1m", "fog_spot")}
"""The SPPM reference procedure of a scene repeated on scenes where Cycles converges, against
their Cycles references (stored with the reference as check_<scene>_*): fog_caustic_1m
(the same glass sphere, a 1 m light) and fog_spot (the 0.1 m light, no glass)."""
SPPM_PHOTONS = 50_000
"""Photons per SPPM pass in the measurements."""
SPPM_MARKS = (1, 4, 16, 64, 256)
CYCLES_SAMPLES = (1, 4, 16, 64, 256, 1024, 4096)
QUICK_SPPM_MARKS = (1, 4, 16, 64)
QUICK_CYCLES_SAMPLES = (1, 4, 16, 64, 256)
MEDIA_CYCLES_SAMPLES = (16, 64, 256, 1024, 4096, 16384)
"""Cycles' sample counts on the fog scenes, --quick or not: 48 x 36 pixels take Cycles about
2 ms a sample, so Photon Map's wall times are reached by measurement, not extrapolation."""
REGENERATE = ".venv/bin/python benchmarks/tradeoff.py --make-references --scenes {scene} " \
             "--resolution {w}x{h}"


def mean_ratio(a, b) -> float:
    return float(np.mean(a) / np.mean(b))


def noise_floor(a, b) -> float:
    """The relMSE of the mean of two independent renders a, b against the truth, estimated
    as mean((a - b)^2 / (m^2 + 0.01)) / 4 with m = (a + b) / 2 (var(a - b) = 2 sigma^2,
    the mean's variance is sigma^2 / 2; dividing by m, not by one of the noisy halves,
    keeps one half's outliers from dominating)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    m = (a + b) / 2
    return float(np.mean((a - b) ** 2 / (m * m + 0.01)) / 4)


# Scenes -------------------------------------------------------------------------------

def _glossy_mirror(name="Mirror", color=(0.9, 0.9, 0.9)):
    mat = bpy.data.materials.new(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    bsdf = nodes.new('ShaderNodeBsdfGlossy')
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    links.new(bsdf.outputs[0], nodes.new('ShaderNodeOutputMaterial').inputs["Surface"])
    return mat


def demo_scene(resolution):
    """The demo: examples/cornell_box.py's Cornell box (mirror and glass spheres)."""
    return cref.demo_scene(resolution=resolution)


def caustic_scene(resolution):
    """A glass sphere (r 0.3 m, IOR 1.5) above a white floor, a 0.3 m area light to the
    side, seen from above (the caustic beside the sphere)."""
    return caustic_ref.glass_sphere_scene(resolution=resolution)


def _room(size=(4.0, 4.0, 2.5), colors=None):
    """A closed box room, x in [-sx/2, sx/2], y likewise, z in [0, sz], walls facing in."""
    sx, sy, sz = size
    colors = colors or {}
    grey = (0.6, 0.6, 0.6)
    walls = {  # name: (location, rotation)
        "Floor": ((0, 0, 0), (0, 0, 0)),
        "Ceiling": ((0, 0, sz), (math.pi, 0, 0)),
        "WallN": ((0, sy / 2, sz / 2), (math.pi / 2, 0, 0)),
        "WallS": ((0, -sy / 2, sz / 2), (-math.pi / 2, 0, 0)),
        "WallE": ((sx / 2, 0, sz / 2), (0, -math.pi / 2, 0)),
        "WallW": ((-sx / 2, 0, sz / 2), (0, math.pi / 2, 0)),
    }
    for name, (loc, rot) in walls.items():
        obj = scenes.add_plane(size=1.0, location=loc, rotation=rot, name=name,
                               material=scenes.diffuse_material(name, colors.get(name, grey)))
        # The plane's local x, y after the rotation: x, y (floor, ceiling), x, z (N, S
        # walls), z, y (E, W walls).
        obj.scale = {"Floor": (sx, sy), "Ceiling": (sx, sy), "WallN": (sx, sz),
                     "WallS": (sx, sz), "WallE": (sz, sy), "WallW": (sz, sy)}[name] + (1.0,)


def interior_scene(resolution):
    """A closed 4 x 4 x 2.5 m room (grey walls, a blue-ish wall, a warm floor), a table-like
    box, lit only by a 0.6 m area light 1.7 m up facing the ceiling: apart from the ceiling
    patch above the light, everything the camera sees is indirect light."""
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    _room(colors={"Floor": (0.55, 0.45, 0.35), "WallE": (0.3, 0.4, 0.6)})
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.6, 0.8, 0.4))
    box = bpy.context.active_object
    box.scale = (0.8, 0.6, 0.8)
    box.rotation_euler = (0.0, 0.0, 0.4)
    box.data.materials.append(scenes.diffuse_material("Box", (0.7, 0.7, 0.7)))
    scenes.add_light('AREA', location=(-0.8, 0.6, 1.7), power=200.0, size=0.6,
                     rotation=(math.pi, 0.0, 0.0), name="Uplight")
    scenes.add_camera(location=(-1.6, -1.8, 1.5), look_at=(0.6, 0.8, 0.8), lens=20.0)
    return scene


def mirror_scene(resolution):
    """A room corner (white floor, back and left walls) with a full mirror on the right
    wall, a red diffuse sphere and a grey box, a 0.5 m area light facing down."""
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    white = scenes.diffuse_material("White", (0.7, 0.7, 0.7))
    scenes.add_plane(size=4.0, material=white, name="Floor")
    scenes.add_plane(size=4.0, location=(0.0, 2.0, 2.0), rotation=(math.pi / 2, 0.0, 0.0),
                     material=white, name="Back")
    scenes.add_plane(size=4.0, location=(-2.0, 0.0, 2.0), rotation=(0.0, math.pi / 2, 0.0),
                     material=scenes.diffuse_material("Blue", (0.2, 0.3, 0.6)), name="Left")
    scenes.add_plane(size=4.0, location=(1.6, 0.4, 1.2), rotation=(0.0, -math.pi / 2, 0.25),
                     material=_glossy_mirror(), name="MirrorWall")
    scenes.add_sphere(radius=0.5, location=(-0.3, 0.6, 0.5), segments=48,
                      material=scenes.diffuse_material("Red", (0.7, 0.15, 0.1)), name="Ball")
    bpy.ops.mesh.primitive_cube_add(size=0.7, location=(0.7, -0.2, 0.35))
    box = bpy.context.active_object
    box.rotation_euler = (0.0, 0.0, 0.5)
    box.data.materials.append(scenes.diffuse_material("Box", (0.6, 0.6, 0.5)))
    scenes.add_light('AREA', location=(-0.4, 0.0, 2.8), power=150.0, size=0.5, name="Key")
    scenes.add_camera(location=(-1.2, -3.4, 1.6), look_at=(0.4, 0.6, 0.6), lens=28.0)
    return scene


def artist_scene(resolution):
    """A room the way an artist builds one (issue 13): walls and ceiling in Blender's default
    Principled BSDF (base 0.8 grey, roughness 0.5, IOR 1.5), a glossy dark floor (roughness
    0.1), a rough copper sphere (roughness 0.35), a gold sphere (roughness 0.15), a frosted
    glass sphere (transmission 1, roughness 0.2), a 0.8 m area light under the ceiling."""
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    sx, sy, sz = 4.0, 4.0, 2.6
    walls = {  # name: (location, rotation, scale)
        "Floor": ((0, 0, 0), (0, 0, 0), (sx, sy)),
        "Ceiling": ((0, 0, sz), (math.pi, 0, 0), (sx, sy)),
        "WallN": ((0, sy / 2, sz / 2), (math.pi / 2, 0, 0), (sx, sz)),
        "WallS": ((0, -sy / 2, sz / 2), (-math.pi / 2, 0, 0), (sx, sz)),
        "WallE": ((sx / 2, 0, sz / 2), (0, -math.pi / 2, 0), (sz, sy)),
        "WallW": ((-sx / 2, 0, sz / 2), (0, math.pi / 2, 0), (sz, sy)),
    }
    wall = scenes.principled_material("Wall")
    floor = scenes.principled_material("GlossyFloor", Base_Color=(0.25, 0.22, 0.2),
                                       Roughness=0.1)
    for name, (loc, rot, scale) in walls.items():
        obj = scenes.add_plane(size=1.0, location=loc, rotation=rot, name=name,
                               material=floor if name == "Floor" else wall)
        obj.scale = scale + (1.0,)
    spheres = (
        ("Copper", (-0.9, 0.5, 0.45), dict(Base_Color=(0.955, 0.638, 0.538), Metallic=1.0,
                                            Roughness=0.35)),
        ("Gold", (0.0, 0.9, 0.45), dict(Base_Color=(1.0, 0.766, 0.336), Metallic=1.0,
                                         Roughness=0.15)),
        ("Frosted", (0.9, 0.3, 0.45), dict(Transmission_Weight=1.0, Roughness=0.2,
                                            IOR=1.5, Base_Color=(1.0, 1.0, 1.0))),
    )
    for name, loc, inputs in spheres:
        scenes.add_sphere(radius=0.45, location=loc, segments=48, name=name,
                          material=scenes.principled_material(name, **inputs))
    scenes.add_light('AREA', location=(0.0, 0.0, sz - 0.05), power=400.0, size=0.8,
                     name="Ceiling Light")
    scenes.add_camera(location=(0.0, -1.9, 1.3), look_at=(0.0, 0.6, 0.5), lens=24.0)
    return scene


def fog_spot_scene(resolution):
    """A grey floor in World fog (albedo 0.7, sigma_t 0.25 / m) under a spot light of radius
    1 m (cycles_media_reference's fog_spot_1m)."""
    return media_ref.wide_light(lambda: media_ref.fog_spot_scene(resolution))()


def fog_caustic_scene(resolution):
    """fog_spot_1m with a glass sphere under the spot: the volumetric caustic
    (cycles_media_reference's fog_caustic_1m)."""
    return media_ref.wide_light(lambda: media_ref.fog_spot_scene(resolution, sphere=True))()


def fog_spot_small_scene(resolution):
    """cycles_media_reference's fog_spot as is: the fog and floor under the 0.1 m spot."""
    return media_ref.fog_spot_scene(resolution)


def fog_caustic_small_scene(resolution):
    """cycles_media_reference's fog_caustic as is: the glass sphere under the 0.1 m spot,
    the volumetric caustic Cycles does not converge on (its reference is SPPM)."""
    return media_ref.fog_spot_scene(resolution, sphere=True)


def fog_box_caustic_scene(resolution):
    """cycles_media_reference's fog_box_caustic_1m: the glass sphere in a fog box under the
    1 m spot light, whose own sphere holds no fog (Cycles' reference sound there)."""
    return media_ref.fog_box_scene(resolution)


SCENES = {"demo": demo_scene, "caustic": caustic_scene, "interior": interior_scene,
          "mirror": mirror_scene, "artist": artist_scene, "fog_spot_1m": fog_spot_scene,
          "fog_caustic_1m": fog_caustic_scene, "fog_spot": fog_spot_small_scene,
          "fog_caustic": fog_caustic_small_scene, "fog_box_caustic_1m": fog_box_caustic_scene}
MEDIA_SCENES = ("fog_spot_1m", "fog_caustic_1m", "fog_spot", "fog_caustic",
                "fog_box_caustic_1m")
"""Scenes whose Cycles renders use cycles_media_reference.configure_cycles_media (volume
bounces too), at that module's resolution only; their reference is that module's cached
Cycles render of the same name, except for SPPM_REFERENCES' (fog_caustic)."""


# Renderers ----------------------------------------------------------------------------

def configure_cycles_full(scene, samples, seed=0):
    """Cycles with full global illumination: BOUNCES bounces of every kind, caustics on,
    otherwise cycles_reference.configure_cycles (CPU, box filter, no denoising, no clamping)."""
    cref.configure_cycles(scene, samples, seed, max_depth=BOUNCES)
    c = scene.cycles
    c.max_bounces = BOUNCES
    c.diffuse_bounces = BOUNCES
    c.glossy_bounces = BOUNCES
    c.transmission_bounces = BOUNCES
    c.caustics_reflective = True
    c.caustics_refractive = True
    return scene


def cycles_render(scene, samples, seed=0, configure=configure_cycles_full):
    """(image (H, W, 3) float64, wall s of bpy.ops.render.render)."""
    configure(scene, samples, seed)
    t0 = time.perf_counter()
    bpy.ops.render.render()
    wall = time.perf_counter() - t0
    return scenes.saved_render_result(scene)["Combined"][..., :3].astype(np.float64), wall


class PhotonMap:
    """The extension's core, imported through the package name Blender uses."""

    def __init__(self):
        from importlib import import_module

        package = scenes.photon_map()
        name = package.__name__
        self.export = import_module(f"{name}.photon_engine.export")
        self.integrator = import_module(f"{name}.core.integrators.photon_mapping")
        self.sppm = import_module(f"{name}.core.integrators.sppm")
        self.presets = import_module(f"{name}.core.presets")
        self.settings = import_module(f"{name}.core.settings")

    def export_scene(self):
        return self.export.export_scene(bpy.context.evaluated_depsgraph_get()).scene

    def preset(self, quality, seed=0):
        """(image (H, W, 3) float64, wall s incl. export, stats)."""
        t0 = time.perf_counter()
        core_scene = self.export_scene()
        settings = self.presets.preset_settings(quality).with_values(seed=seed)
        out = self.integrator.render(core_scene, settings)
        wall = time.perf_counter() - t0
        return out.passes["combined"].astype(np.float64), wall, out.stats

    def progressive(self, marks, photons, seed=0):
        """{passes: (image, wall s incl. export)} at each mark."""
        t0 = time.perf_counter()
        core_scene = self.export_scene()
        settings = self.settings.RenderSettings().with_values(seed=seed, photons_per_pass=photons)
        found = {}
        gen = self.sppm.progressive_passes(core_scene, settings, max(marks))
        try:
            for state in gen:
                if state.passes in marks:
                    found[state.passes] = (state.radiance().astype(np.float64).reshape(
                        state.height, state.width, 3), time.perf_counter() - t0)
        finally:
            gen.close()
        return found

    def warm_up(self):
        """Compile/load the numba kernels on a tiny scene so no timing includes them."""
        caustic_scene((8, 6))  # glass: the caustic map's kernels too
        self.preset("draft")
        self.progressive((1,), 1000)
        fog_caustic_scene((8, 6))  # World fog: the media kernels, both integrators
        self.preset("draft")
        self.progressive((1,), 1000)


# References ---------------------------------------------------------------------------

def fingerprint(name, resolution) -> str:
    """Hash of the code that builds scene ``name`` and renders its reference."""
    parts = [inspect.getsource(SCENES[name]), inspect.getsource(configure_cycles_full),
             inspect.getsource(cref.configure_cycles),
             repr((resolution, BOUNCES, REF_SAMPLES))]
    if name == "demo":
        parts += cref.cornell_box_sources()
    if name == "caustic":  # (its parts as when its reference was made: not SPPM_REFERENCES)
        parts += [inspect.getsource(caustic_ref.glass_sphere_scene),
                  repr((CAUSTIC_REF_PASSES, CAUSTIC_REF_PHOTONS))]
    elif name in SPPM_REFERENCES:
        parts += [media_ref.fingerprint(name), repr(SPPM_REFERENCES[name])]
    for check in SPPM_CHECKS.get(name, ()):
        parts += [inspect.getsource(SCENES[check]), media_ref.fingerprint(check)]
    if name in ("interior", "mirror"):
        parts += [inspect.getsource(_room), inspect.getsource(_glossy_mirror)]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:16]


def reference_path(name, resolution) -> pathlib.Path:
    return REF_DIR / f"{name}_{resolution[0]}x{resolution[1]}.npz"


def regenerate_command(name, resolution) -> str:
    return REGENERATE.format(scene=name, w=resolution[0], h=resolution[1])


def load_reference(name, resolution) -> dict | None:
    """The cached reference dict (image, image_a, image_b, noise, ...), or None when it is
    missing or was made by other code (stale)."""
    path = reference_path(name, resolution)
    if not path.exists():
        return None
    data = dict(np.load(path))
    if str(data["fingerprint"]) != fingerprint(name, resolution):
        return None
    data["noise"] = noise_floor(data["image_a"], data["image_b"])
    if "cycles_a" in data:
        data["cycles_noise"] = noise_floor(data["cycles_a"], data["cycles_b"])
    return data


def sppm_reference(pm: PhotonMap, passes, photons) -> list:
    """The two halves [a, b] ((H, W, 3) float64) of an SPPM reference of the current scene:
    seeds 101 and 102, ``passes`` passes of ``photons`` photons each (the reference is
    their mean, the noise floor their difference)."""
    return [pm.progressive((passes,), photons, seed=seed)[passes][0] for seed in (101, 102)]


def check_text(ref) -> str:
    """The SPPM reference's checks (SPPM_CHECKS) stored in ``ref``, as text ('' if none)."""
    names = [k[len("check_"):-len("_relmse")] for k in ref
             if k.startswith("check_") and k.endswith("_relmse")]
    return "".join(
        f"; check, the same SPPM on {n} vs its Cycles reference: relMSE "
        f"{float(ref[f'check_{n}_relmse']):.3g} (SPPM noise {float(ref[f'check_{n}_noise']):.2g}, "
        f"Cycles noise {float(ref[f'check_{n}_cycles_noise']):.2g}), channel means "
        f"{', '.join(f'{100 * v:+.2f}' for v in ref[f'check_{n}_channel'])} %, worst 8x8 "
        f"block {100 * float(ref[f'check_{n}_worst_block']):+.1f} %" for n in names)


def make_reference(name, resolution, pm: PhotonMap) -> dict:
    t0 = time.perf_counter()
    stamp = fingerprint(name, resolution)  # before the long render (the source may change)
    scene = SCENES[name](resolution)
    extra = {}
    if name in SPPM_REFERENCES:
        passes, photons = SPPM_REFERENCES[name]
        a, b = sppm_reference(pm, passes, photons)
        image = (a + b) / 2
        if name in MEDIA_SCENES:  # Cycles' cached render (it may not converge there)
            media = media_reference(name, resolution)
            cyc = [media["image_a"].astype(np.float64), media["image_b"].astype(np.float64)]
            cycles_method = str(media["method"])
        else:
            cyc = [cycles_render(scene, REF_SAMPLES, seed)[0] for seed in (1, 2)]
            cycles_method = f"Cycles 2 x {REF_SAMPLES} samples"
        cycles_image = (cyc[0] + cyc[1]) / 2
        extra_halves = dict(cycles_a=cyc[0].astype(np.float32), cycles_b=cyc[1].astype(np.float32))
        extra = dict(method=np.str_(f"SPPM 2 x {passes} passes x {photons:,} photons"),
                     cycles=cycles_image.astype(np.float32),
                     cycles_method=np.str_(cycles_method),
                     cycles_vs_sppm=np.float64(rel_mse(cycles_image, image)),
                     cycles_noise=np.float64(noise_floor(*cyc)),
                     cycles_mean_ratio=np.float64(mean_ratio(cycles_image, image)),
                     **extra_halves)
    else:
        a, _ = cycles_render(scene, REF_SAMPLES, 1)
        b, _ = cycles_render(scene, REF_SAMPLES, 2)
        image = (a + b) / 2
        extra = dict(method=np.str_(f"Cycles 2 x {REF_SAMPLES} samples, {BOUNCES} bounces"))
    data = dict(image=image.astype(np.float32), image_a=a.astype(np.float32),
                image_b=b.astype(np.float32),
                fingerprint=np.str_(stamp),
                command=np.str_(regenerate_command(name, resolution)),
                blender=np.str_(bpy.app.version_string),
                seconds=np.float64(time.perf_counter() - t0), **extra)
    REF_DIR.mkdir(parents=True, exist_ok=True)
    # Saved before the checks too, so a measurement can use it while they run.
    np.savez_compressed(reference_path(name, resolution), **data)
    for check in SPPM_CHECKS.get(name, ()):
        t1 = time.perf_counter()
        SCENES[check](resolution)
        ca, cb = sppm_reference(pm, *SPPM_REFERENCES[name])
        mine = (ca + cb) / 2
        truth = media_reference(check, resolution)
        figures = cref.compare(mine, truth["image"])
        data.update({f"check_{check}_image": mine.astype(np.float32),
                     f"check_{check}_relmse": np.float64(rel_mse(mine, truth["image"])),
                     f"check_{check}_noise": np.float64(noise_floor(ca, cb)),
                     f"check_{check}_cycles_noise": np.float64(truth["noise"]),
                     f"check_{check}_channel": np.asarray(figures["channel"], np.float64),
                     f"check_{check}_worst_block": np.float64(
                         figures["blocks"].flat[np.nanargmax(np.abs(figures["blocks"]))]),
                     f"check_{check}_seconds": np.float64(time.perf_counter() - t1)})
        np.savez_compressed(reference_path(name, resolution), **data)
    data = load_reference(name, resolution)
    msg = f"reference {name} {resolution[0]}x{resolution[1]}: {data['method']}, " \
          f"{data['seconds']:.0f} s, noise {data['noise']:.2g}"
    if "cycles_vs_sppm" in data:
        msg += f", {data.get('cycles_method', 'Cycles')} vs this reference relMSE " \
               f"{float(data['cycles_vs_sppm']):.4f} (Cycles noise " \
               f"{float(data['cycles_noise']):.4f}), mean ratio " \
               f"{float(data['cycles_mean_ratio']):.3f}"
    print(msg + check_text(data), flush=True)
    return data


def media_reference(name, resolution, make=True, force=False) -> dict:
    """cycles_media_reference.py's cached Cycles render of fog scene ``name``, with the keys
    the other references have (image_a and image_b are its odd and even seeds)."""
    command = f".venv/bin/python tests/blender/cycles_media_reference.py {name}"
    try:
        data = None if force else media_ref.load_reference(name)
    except AssertionError:  # missing, or made by other scene code
        data = None
    if data is None:
        if not make:
            raise SystemExit(f"missing or stale reference {media_ref.reference_path(name)}; "
                             f"regenerate it with: {command}")
        media_ref.main([name])
        data = media_ref.load_reference(name)
    if "image_a" not in data:
        raise SystemExit(f"{media_ref.reference_path(name)} has no halves; regenerate it with: "
                         f"{command}")
    data["noise"] = noise_floor(data["image_a"], data["image_b"])
    samples, seeds = media_ref.CACHE.runs(name)
    data["method"] = np.str_(f"Cycles {seeds} seeds x {samples:,} samples, "
                             f"{media_ref.BOUNCES} bounces")
    data["command"] = np.str_(command)
    return data


def reference(name, resolution, pm, make=True, force=False) -> dict:
    if name in MEDIA_SCENES and tuple(resolution) != tuple(media_ref.RESOLUTION):
        raise SystemExit(f"{name} has a reference at {media_ref.RESOLUTION[0]}x"
                         f"{media_ref.RESOLUTION[1]} only, not {resolution[0]}x{resolution[1]}")
    if name in MEDIA_SCENES and name not in SPPM_REFERENCES:
        return media_reference(name, resolution, make, force)
    data = None if force else load_reference(name, resolution)
    if data is None:
        if not make:
            raise SystemExit(f"missing or stale reference {reference_path(name, resolution)}; "
                             f"regenerate it with: {regenerate_command(name, resolution)}")
        data = make_reference(name, resolution, pm)
    return data


# Measurements -------------------------------------------------------------------------

def measure_scene(name, resolution, pm, qualities, sppm_marks, cycles_samples, ref) -> list:
    """Rows {scene, method, label, wall, relmse, ratio, ...}, interleaving presets and Cycles."""
    scene = SCENES[name](resolution)
    image = ref["image"].astype(np.float64)
    rows = []
    configure = media_ref.configure_cycles_media if name in MEDIA_SCENES else configure_cycles_full
    if name in MEDIA_SCENES:
        cycles_samples = MEDIA_CYCLES_SAMPLES

    def add(method, label, img, wall, **extra):
        row = dict(scene=name, method=method, label=label, wall=wall,
                   relmse=rel_mse(img, image), ratio=mean_ratio(img, image), image=img, **extra)
        rows.append(row)
        print(f"| {name} | {label} | {wall:.2f} | {row['relmse']:.4g} | {row['ratio']:.3f} |",
              flush=True)

    cycles_render(scene, 1, configure=configure)  # Cycles' kernels and scene sync warm, like numba's
    jobs = []
    for i in range(max(len(qualities), len(cycles_samples))):
        if i < len(qualities):
            jobs.append(("preset", qualities[i]))
        if i < len(cycles_samples):
            jobs.append(("cycles", cycles_samples[i]))
    for kind, value in jobs:
        if kind == "preset":
            img, wall, stats = pm.preset(value)
            add("preset", value.title(), img, wall,
                photons=int(stats.get("global_photons_stored", 0) +
                            stats.get("caustic_photons_stored", 0)))
        else:
            img, wall = cycles_render(scene, value, configure=configure)
            add("cycles", f"Cycles {value} spp", img, wall, samples=value)
    found = pm.progressive(sppm_marks, SPPM_PHOTONS) if sppm_marks else {}
    for passes, (img, wall) in sorted(found.items()):
        add("sppm", f"SPPM {passes} passes", img, wall, passes=passes)
    return rows


def cycles_at(rows, scene, wall) -> tuple[float, bool]:
    """Cycles' relMSE at ``wall`` seconds: log-log interpolated between the measured sample
    counts, or beyond the last one extrapolated as 1 / time (unbiased Monte Carlo: the
    variance falls as 1 / samples); (relMSE, extrapolated). nan below the first count."""
    pts = sorted((r["wall"], r["relmse"]) for r in rows
                 if r["scene"] == scene and r["method"] == "cycles")
    if not pts or wall < pts[0][0]:
        return float("nan"), False
    if wall > pts[-1][0]:
        return pts[-1][1] * pts[-1][0] / wall, True
    t = np.log([p[0] for p in pts])
    e = np.log([p[1] for p in pts])
    return float(np.exp(np.interp(math.log(wall), t, e))), False


def table(rows) -> str:
    lines = ["| scene | method | wall s | relMSE | mean ratio | Cycles relMSE at equal time |",
             "|---|---|---:|---:|---:|---:|"]
    for r in rows:
        eq = ""
        if r["method"] != "cycles":
            err, extrapolated = cycles_at(rows, r["scene"], r["wall"])
            eq = f"{err:.4g}" + (" (extrapolated)" if extrapolated else "")
        lines.append(f"| {r['scene']} | {r['label']} | {r['wall']:.2f} | {r['relmse']:.4g} | "
                     f"{r['ratio']:.3f} | {eq} |")
    return "\n".join(lines)


def figure(rows, name, ref, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 4.2), dpi=100)
    mine = [r for r in rows if r["scene"] == name]
    styles = {"cycles": ("o-", "tab:blue", "Cycles (path tracing)"),
              "sppm": ("s-", "tab:orange", f"Photon Map SPPM ({SPPM_PHOTONS // 1000}k photons/pass)"),
              "preset": ("D", "tab:red", "Photon Map presets (final gather)")}
    for method, (style, color, label) in styles.items():
        pts = [r for r in mine if r["method"] == method]
        if not pts:
            continue
        ax.plot([r["wall"] for r in pts], [r["relmse"] for r in pts], style, color=color,
                label=label, ms=6)
        for r in pts:
            text = {"cycles": str(r.get("samples")), "sppm": str(r.get("passes")),
                    "preset": r["label"]}[method]
            ax.annotate(text, (r["wall"], r["relmse"]), textcoords="offset points",
                        xytext=(4, 4), fontsize=7, color=color)
    ax.axhline(float(ref["noise"]), ls="--", color="grey", lw=0.8,
               label="reference noise (from its two halves)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(f"wall time, s ({os.cpu_count()} cores)")
    ax.set_ylabel("relMSE vs reference")
    ax.set_title(f"{name}: error vs time ({ref['image'].shape[1]}x{ref['image'].shape[0]})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def equal_time_strip(rows, name, ref, path):
    """Each preset's image above Cycles' render nearest to it in wall time, and the
    reference; the same exposure for all (the reference's 99th percentile -> white, gamma
    2.2), nearest-neighbour pixels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    presets = [r for r in rows if r["scene"] == name and r["method"] == "preset"]
    cycles = [r for r in rows if r["scene"] == name and r["method"] == "cycles"]
    if not presets or not cycles:
        return
    pairs = [(p, min(cycles, key=lambda c: abs(math.log(c["wall"] / p["wall"]))))
             for p in presets]
    white = float(np.percentile(ref["image"], 99))
    fig, axs = plt.subplots(2, len(pairs) + 1, squeeze=False,
                            figsize=(2.6 * (len(pairs) + 1), 4.6))
    for col, (p, c) in enumerate(pairs):
        for ax, r, who in ((axs[0, col], p, "Photon Map "), (axs[1, col], c, "")):
            ax.imshow(np.clip(r["image"] / white, 0, 1) ** (1 / 2.2), interpolation="nearest")
            ax.set_title(f"{who}{r['label']}\n{r['wall']:.1f} s, relMSE {r['relmse']:.3g}",
                         fontsize=7)
            ax.axis("off")
    axs[0, -1].imshow(np.clip(ref["image"] / white, 0, 1) ** (1 / 2.2), interpolation="nearest")
    axs[0, -1].set_title("reference\n" + textwrap.fill(str(ref["method"]), 40), fontsize=6)
    for ax in axs[:, -1]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def preset_strip(names, res, pm, path):
    """One row per scene: every preset's image and the reference, the same exposure
    (the reference's 99th percentile -> white, gamma 2.2), nearest-neighbour pixels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    qualities = pm.presets.QUALITIES
    fig, axs = plt.subplots(len(names), len(qualities) + 1, squeeze=False,
                            figsize=(2.6 * (len(qualities) + 1), 2.2 * len(names)))
    for row, name in zip(axs, names):
        ref = reference(name, res[name], pm, make=False)
        SCENES[name](res[name])
        images = [(q.title(), pm.preset(q)[0]) for q in qualities]
        images.append(("reference", ref["image"]))
        white = float(np.percentile(ref["image"], 99))
        for ax, (title, image) in zip(row, images):
            ax.imshow(np.clip(image / white, 0, 1) ** (1 / 2.2), interpolation="nearest")
            ax.set_title(f"{name}: {title}", fontsize=8)
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


BEGIN, END = "<!-- tradeoff:begin (benchmarks/tradeoff.py --write-docs) -->", \
    "<!-- tradeoff:end -->"


def write_docs(rows, refs, command, seconds):
    """The generated block of docs/tradeoff.md (between BEGIN and END; the rest is prose)."""
    load = os.getloadavg()
    cpu = platform.machine()
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                   if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    lines = [BEGIN, "",
             f"Command: `{command}`  ",
             f"Date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; "
             f"machine: {cpu}, {os.cpu_count()} cores "
             f"(load average at the end, other jobs included: "
             f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f}), Blender {bpy.app.version_string}; "
             f"the run took {seconds / 60:.0f} min.",
             "", "References:", ""]
    for name, ref in refs.items():
        h, w = ref["image"].shape[:2]
        line = f"- {name} ({w}x{h}): {ref['method']}, noise {float(ref['noise']):.2g} " \
               f"(`{ref['command']}`)"
        if "cycles_vs_sppm" in ref:
            line += f"; cross-check, Cycles vs this reference: " \
                    f"relMSE {float(ref['cycles_vs_sppm']):.4f} (Cycles' own noise " \
                    f"{float(ref['cycles_noise']):.4f}), mean ratio " \
                    f"{float(ref['cycles_mean_ratio']):.3f}"
        lines.append(line + check_text(ref))
    lines += ["", table(rows), ""]
    for name in refs:
        lines.append(f"![{name}](images/tradeoff_{name}.png)")
    lines += ["", END]
    block = "\n".join(lines)
    path = DOCS / "tradeoff.md"
    text = path.read_text() if path.exists() else "# Speed for accuracy\n\n" + BEGIN + END + "\n"
    head, rest = text.split(BEGIN, 1)
    tail = rest.split(END, 1)[1]
    path.write_text(head + block + tail)


def _resolution(text):
    w, h = (int(v) for v in text.lower().split("x"))
    return (w, h)


def main(argv=None) -> list | None:
    """Run the command line ``argv``; the measured rows (dicts with their images), if any."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated subset")
    ap.add_argument("--resolution", type=_resolution, default=None)
    ap.add_argument("--quick", action="store_true",
                    help=f"{QUICK_RESOLUTION[0]}x{QUICK_RESOLUTION[1]}, no Converged preset, "
                         "fewer SPPM passes and Cycles samples")
    ap.add_argument("--qualities", default=None, help="comma-separated presets to measure")
    ap.add_argument("--make-references", action="store_true",
                    help="re-render the references of the scenes, then stop")
    ap.add_argument("--no-make", action="store_true", help="fail on a missing/stale reference")
    ap.add_argument("--write-docs", action="store_true",
                    help="write docs/tradeoff.md's table and docs/images/tradeoff_*.png")
    ap.add_argument("--pictures", action="store_true",
                    help="write only docs/images/tradeoff_<scene>*.png, not docs/tradeoff.md")
    ap.add_argument("--json", default=None, help="also save the rows as JSON here")
    ap.add_argument("--strip", action="store_true",
                    help="only draw docs/images/tradeoff_presets.png (each preset's image "
                         "and the reference, per scene), then stop")
    args = ap.parse_args(argv)
    names = [n for n in args.scenes.split(",") if n]
    for n in names:
        if n not in SCENES:
            ap.error(f"unknown scene {n!r}; one of {', '.join(SCENES)}")
    fixed = args.resolution or (QUICK_RESOLUTION if args.quick else None)
    res = {n: fixed or RESOLUTIONS[n] for n in names}
    started = time.perf_counter()
    pm = PhotonMap()
    pm.warm_up()
    if args.strip:
        preset_strip(names, res, pm, DOCS / "images" / "tradeoff_presets.png")
        return
    if args.make_references:
        for n in names:
            reference(n, res[n], pm, force=True)
        return
    qualities = tuple(args.qualities.split(",")) if args.qualities else (
        pm.presets.QUALITIES[:-1] if args.quick else pm.presets.QUALITIES)
    marks = QUICK_SPPM_MARKS if args.quick else SPPM_MARKS
    samples = QUICK_CYCLES_SAMPLES if args.quick else CYCLES_SAMPLES
    refs, rows = {}, []
    print("| scene | method | wall s | relMSE | mean ratio |\n|---|---|---:|---:|---:|", flush=True)
    for n in names:  # all first: fingerprints read this file's source, which may change later
        refs[n] = reference(n, res[n], pm, make=not args.no_make)
    for n in names:
        rows += measure_scene(n, res[n], pm, qualities, marks, samples, refs[n])
    print()
    print(table(rows))
    for n, ref in refs.items():
        print(f"{n}: reference {ref['method']}, noise {float(ref['noise']):.2g}"
              + (f", Cycles vs this reference relMSE {float(ref['cycles_vs_sppm']):.4f} "
                 f"(its noise {float(ref['cycles_noise']):.4f}), mean ratio "
                 f"{float(ref['cycles_mean_ratio']):.3f}"
                 if "cycles_vs_sppm" in ref else "") + check_text(ref))
    if args.json:
        pathlib.Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(args.json).write_text(json.dumps(
            [{k: v for k, v in r.items() if k != "image"} for r in rows], indent=1))
    if args.write_docs or args.pictures:
        (DOCS / "images").mkdir(parents=True, exist_ok=True)
        for n, ref in refs.items():
            figure(rows, n, ref, DOCS / "images" / f"tradeoff_{n}.png")
            if n in MEDIA_SCENES:
                equal_time_strip(rows, n, ref, DOCS / "images" / f"tradeoff_{n}_images.png")
    if args.write_docs:
        command = ".venv/bin/python benchmarks/tradeoff.py " + " ".join(
            argv if argv is not None else sys.argv[1:])
        write_docs(rows, refs, command.strip(), time.perf_counter() - started)
    return rows


if __name__ == "__main__":
    main()
