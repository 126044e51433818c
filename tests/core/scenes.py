"""Scenes built by hand for core tests and benchmarks (plain arrays, no Blender)."""

from core.scene import shapes
from core.scene.contract import LIGHT_POINT, Lights, Materials, Scene


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
