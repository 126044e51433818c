"""Scenes built by hand for core tests and benchmarks (plain arrays, no Blender)."""

import numpy as np

from core.scene import shapes
from core.scene.contract import LIGHT_POINT, LIGHT_SPOT, Lights, Materials, Scene
from core.scene.media import Media


def caustic_scene(scale=1.0, width=32, height=32) -> Scene:
    """A glass sphere (radius 0.5 s, IOR 1.5) 0.1 s above a 2 s x 2 s diffuse floor (albedo
    0.8) under a 200 s^2 W point light at (0.3, 0, 2.5) s, a width x height pinhole camera:
    the scene of tests/core/integrators/test_sppm.py, test_distributed.py, the cached
    reference (make_caustic_reference.py, benchmarks/sppm_convergence.py). Lengths in
    metres times ``scale``; the power scales with s^2 so the image does not change."""
    s = scale
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [2 * s, 0, 0], [0, 2 * s, 0]), 0),
                            (shapes.uv_sphere([0, 0, 0.6 * s], 0.5 * s, 16, 32), 1)])
    mats = Materials.from_list([{"diffuse": [0.8] * 3}, {"transmission": [1, 1, 1], "ior": 1.5}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0.3 * s, 0, 2.5 * s],
                                "power": 200.0 * s * s}])
    cam = shapes.pinhole([0, -3.0 * s, 2.5 * s], [0, 0, 0.3 * s], width, height, 0.9)
    return Scene(mesh, mats, lights, cam).validate()


PRISM_LIGHT = [-3.07, 0.0, 0.407]
"""Where prism_scene's spot light sits: 3 m before the prism's left face, aiming up at 20
degrees so the light meets it near minimum deviation (incidence ~50 degrees)."""


def prism_scene(abbe: float | None = 64.17, width=64, height=48, spot_size=0.35,
                power=2000.0, color=(1.0, 1.0, 1.0)) -> Scene:
    """A 60-degree BK7 prism (n_d 1.5168, Dispersion V_d ``abbe``; None: the setting
    absent) 1 m above a 12 x 4 m white floor (albedo 0.8), lit by a narrow white spot light
    (``spot_size`` rad, about the face's width, ``power`` W) through its left face: the light leaves the right face
    heading down at ~19 degrees and spreads into the rainbow caustic on the floor near
    x = 4.4 m. The camera looks down at that strip. The scene of
    tests/core/photons/test_dispersion_tracing.py and tools/prism_picture.py."""
    mesh = shapes.assemble([(shapes.quad([3.0, 0, 0], [6.0, 0, 0], [0, 2.0, 0]), 0),
                            (shapes.prism([0, 0, 1.0], 1.0, 1.2), 1)])
    glass = {"transmission": [1, 1, 1], "ior": 1.5168}
    if abbe is not None:
        glass["dispersion"] = abbe
    mats = Materials.from_list([{"diffuse": [0.8] * 3}, glass])
    face = [-0.25, 0.0, 1.433]  # the left face's centre
    lights = Lights.from_list([{"kind": LIGHT_SPOT, "to_world": shapes.look_at(PRISM_LIGHT, face),
                                "power": power, "spot_size": spot_size, "spot_blend": 0.0,
                                "color": list(color)}])
    cam = shapes.pinhole([4.4, -2.2, 2.0], [4.3, 0, 0], width, height, 0.9)
    return Scene(mesh, mats, lights, cam).validate()


def prism_view_scene(abbe: float | None = 20.0, width=64, height=48, fov=0.4,
                     half=0.15) -> Scene:
    """The camera's view through prism_scene's prism at a white emitter: a square of
    emission (1, 1, 1) W/(m^2 sr), ``half`` m half-size, at PRISM_LIGHT facing the left
    face, nothing else (black world). The camera sits where prism_scene's light lands on
    the floor, looking at the right face, so it sees the emitter along the light's path
    reversed (near minimum deviation: the image keeps its size at every wavelength).
    Dispersion V_d ``abbe`` (None: the setting absent). The scene of
    tests/core/integrators/test_dispersion_camera.py."""
    face = np.array([-0.25, 0.0, 1.433])
    light = np.array(PRISM_LIGHT)
    n = (face - light) / np.linalg.norm(face - light)
    u = np.cross(n, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    mesh = shapes.assemble([(shapes.quad(light, u * half, [0.0, half, 0.0]), 0),
                            (shapes.prism([0, 0, 1.0], 1.0, 1.2), 1)])
    glass = {"transmission": [1, 1, 1], "ior": 1.5168}
    if abbe is not None:
        glass["dispersion"] = abbe
    mats = Materials.from_list([{"diffuse": [0, 0, 0], "emission": [1, 1, 1]}, glass])
    cam = shapes.pinhole([4.4, 0.0, 0.0], [0.25, 0.0, 1.433], width, height, fov)
    return Scene(mesh, mats, Lights.from_list([]), cam).validate()


def fog_scene(width=24, height=24, sigma_s=0.25, sigma_a=0.05, g=0.3) -> Scene:
    """A 4 m x 4 m diffuse floor (albedo 0.8) and a back wall (albedo 0.6) in World fog
    (sigma_s, sigma_a 1/m grey, Henyey-Greenstein g), lit by a 300 W point light at 1.5 m,
    seen by a width x height pinhole camera from 3 m away: the light's glow in the fog,
    its single and multiple scattering, and the floor seen through the fog. The scene of
    the progressive mode's media tests (tests/core/integrators/test_sppm_media.py) and
    benchmarks/sppm_fog_convergence.py."""
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0]), 0),
                            (shapes.quad([0, 2, 1.5], [2, 0, 0], [0, 0, 1.5]), 1)])
    mats = Materials.from_list([{"diffuse": [0.8] * 3}, {"diffuse": [0.6] * 3}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0.4, 0.3, 1.5],
                                "power": 300.0}])
    media = Media.from_list([{"sigma_s": [sigma_s] * 3, "sigma_a": [sigma_a] * 3,
                              "anisotropy": g, "name": "Fog"}])
    cam = shapes.pinhole([0, -3.0, 1.2], [0, 0.5, 0.8], width, height, 0.9)
    return Scene(mesh, mats, lights, cam, media=media).validate()
