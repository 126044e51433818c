"""A diffuse floor inside a dielectric, seen through it: the photons' estimates there are
physical radiance, n^2 times what a camera path carries through a refraction (it does not
scale radiance by eta^2, Cycles' convention), so both integrators divide them by n^2
(core/integrators/photon_mapping.py, sppm.py; a pool floor under water read +66 % against
Cycles before)."""

import math

import numpy as np
import pytest

from core.integrators import photon_mapping, sppm
from core.scene import shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, LIGHT_SUN, Camera, Lights, Materials, Scene
from core.settings import RenderSettings

pytestmark = pytest.mark.core

IOR, ALBEDO = 1.5, 0.5


def _fresnel(cos_i, n):
    """Unpolarised Fresnel reflectance from the side of index 1 into index n."""
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_i ** 2)) / n
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin_t ** 2))
    rs = (cos_i - n * cos_t) / (cos_i + n * cos_t)
    rp = (n * cos_i - cos_t) / (n * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


def expected_radiance(n=IOR, albedo=ALBEDO, irradiance=1.0):
    """What an orthographic camera straight above sees of a Lambert floor inside a wide
    slab of index n lit by a sun at normal incidence: the light through the top
    (T0 = 1 - R(0)) lights the floor, which sends it up diffusely; the top sends back the
    internal diffuse reflectance r_i = 1 - (1 - r_e) / n^2 (r_e the external one, a
    cosine-weighted Fresnel average): E = T0 E0 / (1 - albedo r_i) on the floor, and the
    camera sees T0 albedo E / (pi n^2) (radiance leaving a dielectric falls by n^2)."""
    c = (np.arange(200_000) + 0.5) / 200_000  # cos theta, midpoint rule of 2 c dc
    r_e = float(np.sum(_fresnel(c, n) * 2 * c) / c.size)
    r_i = 1.0 - (1.0 - r_e) / (n * n)
    t0 = 1.0 - float(_fresnel(np.array([1.0]), n)[0])
    e_floor = t0 * irradiance / (1.0 - albedo * r_i)
    return t0 * albedo * e_floor / (math.pi * n * n)


def slab_scene(res=4) -> Scene:
    """A 40 x 40 m Lambert floor at z = 0 inside a glass slab from z = -0.05 to 0.3 m, a sun
    of 1 W/m^2 straight down, an orthographic camera of 0.5 m looking down at the middle."""
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [20, 0, 0], [0, 20, 0]), 0),
                            (shapes.box([-20, -20, -0.05], [20, 20, 0.3]), 1)])
    mats = Materials.from_list([{"diffuse": [ALBEDO] * 3},
                                {"transmission": [1, 1, 1], "ior": IOR}])
    lights = Lights.from_list([{"kind": LIGHT_SUN, "power": 1.0}])
    cam = Camera(to_world=shapes.look_at([0, 0, 5], [0, 0, 0], (0, 1, 0)), width=res,
                 height=res, film_size=np.array([0.5, 0.5]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, mats, lights, cam).validate()


SETTINGS = RenderSettings(samples=4, seed=3, global_photons=200_000, caustic_photons=200_000,
                          photon_max_bounces=12, max_specular_depth=8, threads=2)


def test_a_floor_inside_glass_reads_its_radiance_through_the_glass():
    want = expected_radiance()
    out = photon_mapping.render(slab_scene(), SETTINGS)
    got = out.passes["combined"].mean()
    print(f"\nfloor inside glass: {got:.5f} against {want:.5f} ({100 * (got / want - 1):+.2f} %)")
    assert got == pytest.approx(want, rel=0.03)


def test_the_progressive_integrator_reads_it_too():
    want = expected_radiance()
    out = sppm.render(slab_scene(), SETTINGS.with_values(progressive_passes=16,
                                                         photons_per_pass=100_000))
    got = out.passes["combined"].mean()
    print(f"\nfloor inside glass (SPPM): {got:.5f} against {want:.5f} "
          f"({100 * (got / want - 1):+.2f} %)")
    assert got == pytest.approx(want, rel=0.04)
