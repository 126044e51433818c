"""Denoising: the Denoising Albedo and Denoising Normal passes as Cycles defines them
(checked against Cycles' own passes in this bpy process, on a textured scene with a
mirror), and the Denoise setting (the compositor's Denoise node, OpenImageDenoise as
shipped with Blender) lowering a Preview render's error against a Converged one.
"""

import pathlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402
from tests.blender.test_textures import block_image, textured_material  # noqa: E402
from tests.metrics import rel_mse  # noqa: E402

pytestmark = pytest.mark.blender

SIZE = (48, 36)


def feature_scene():
    """A textured floor, a grey diffuse sphere and a mirror sphere under a sun."""
    scenes.reset()
    scenes.set_resolution(*SIZE)
    image, _ = block_image("Blocks")
    # Diffuse BSDF: Principled's dielectric specular layer is not modelled yet (its
    # albedo, about 0.04, is in Cycles' Denoising Albedo).
    scenes.add_plane(size=6.0, material=textured_material("Floor", image, shader='ShaderNodeBsdfDiffuse',
                                                          socket="Color"))
    scenes.add_sphere(radius=0.5, location=(-0.6, 0.3, 0.5), segments=32,
                      material=scenes.diffuse_material("Grey", (0.5, 0.4, 0.3)))
    mirror = bpy.data.materials.new("Mirror")
    nodes = scenes.ensure_node_tree(mirror).nodes
    nodes.clear()
    glossy = nodes.new('ShaderNodeBsdfGlossy')
    glossy.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
    glossy.inputs["Roughness"].default_value = 0.0
    out = nodes.new('ShaderNodeOutputMaterial')
    mirror.node_tree.links.new(glossy.outputs[0], out.inputs["Surface"])
    scenes.add_sphere(radius=0.5, location=(0.7, 0.5, 0.5), segments=32, material=mirror)
    scenes.add_light('SUN', power=3.0, rotation=(0.5, 0.2, 0.0))
    scenes.add_camera(location=(0.0, -4.0, 2.0), look_at=(0.0, 0.3, 0.4))
    return bpy.context.scene


def test_denoising_passes_match_cycles():
    scene = feature_scene()
    ref.configure_cycles(scene, 64, seed=1)
    scene.view_layers[0].cycles.denoising_store_passes = True
    cycles = scenes.render_passes(scene)
    scene = feature_scene()
    scenes.use_photon_map(scene, samples=64, denoising_data=True, caustics=False,
                          indirect_mode='off', seed=1)
    ours = scenes.render_passes(scene)
    for name in ("Denoising Albedo", "Denoising Normal"):
        a, b = ours[name][..., :3].astype(np.float64), cycles[name][..., :3].astype(np.float64)
        assert np.isfinite(a).all()
        # Pixels whose 3 x 3 neighbourhood is uniform in Cycles' pass: away from
        # silhouettes and texel edges, where the two renders' sub-pixel sampling differs.
        pad = np.pad(b, ((1, 1), (1, 1), (0, 0)), mode="edge")
        spread = np.max([np.abs(pad[1 + dy:1 + dy + b.shape[0], 1 + dx:1 + dx + b.shape[1]] - b)
                         for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0).max(axis=-1)
        flat = spread < 1e-3
        err = np.abs(a - b).max(axis=-1)[flat]
        same = float(np.mean(err < 1e-3))
        print(f"\n{name}: {flat.mean():.0%} of the pixels uniform; there {same:.1%} equal to "
              f"1e-3 (median |difference| {np.median(err):.1e})")
        assert flat.mean() > 0.5
        # Known, and not the passes' doing: about 6 % of the floor's pixels see another
        # texel block than Cycles does (Combined differs there by the same colours).
        assert same > 0.9, name


def composite(scene, path: pathlib.Path) -> np.ndarray:
    """Render with the compositor and read the composite (single-layer EXR), (H, W, 3)."""
    import OpenEXR

    from photon_map.photon_engine.cli import set_format

    set_format(scene.render.image_settings, "OPEN_EXR")
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        channels = exr.parts[0].channels
        return np.stack([np.asarray(channels[c].pixels) for c in "RGB"], axis=-1).astype(np.float64)


def test_denoise_lowers_the_error_of_a_preview_render(tmp_path):
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.photon_engine.cli import apply_quality

    scene = ref.demo_scene(resolution=(64, 48))
    scenes.use_photon_map(scene)
    apply_quality(scene.photon_map, "converged")
    reference = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)

    scene = ref.demo_scene(resolution=(64, 48))
    scenes.use_photon_map(scene, seed=5)
    apply_quality(scene.photon_map, "preview")
    noisy = composite(scene, tmp_path / "noisy.exr")
    scene.photon_map.denoise = True
    assert scene.photon_map.denoising_data
    denoised = composite(scene, tmp_path / "denoised.exr")
    before, after = rel_mse(noisy, reference), rel_mse(denoised, reference)
    print(f"\nPreview vs Converged relMSE: {before:.4f} noisy, {after:.4f} denoised")
    assert np.isfinite(denoised).all() and not np.array_equal(denoised, noisy)
    assert after < 0.8 * before
    scene.photon_map.denoise = False  # removes the compositor it made
    assert getattr(scene, "compositing_node_group", None) is None or \
        not scene.compositing_node_group
    np.testing.assert_allclose(composite(scene, tmp_path / "again.exr"), noisy, atol=1e-6)


def test_progressive_makes_the_denoising_passes_of_the_photon_mapping_integrator():
    """The Progressive integrator's Denoising Albedo / Normal are the photon-mapping
    integrator's: the same rule at the same hits (denoise_features.py), averaged over its
    passes' camera rays instead of the camera samples. Where the feature is the same over
    the whole pixel (3 x 3 neighbourhood uniform) both are the mean of one value, hence
    equal to float rounding; at silhouettes and texel edges the two sub-pixel sample sets
    differ, which is sampling noise (the image means agree within 2 %)."""
    scene = feature_scene()
    scenes.use_photon_map(scene, samples=16, denoising_data=True, caustics=False,
                          indirect_mode='off', seed=1)
    final = scenes.render_passes(scene)
    scene = feature_scene()
    scenes.use_photon_map(scene, integrator='progressive', progressive_passes=16,
                          photons_per_pass=500, denoising_data=True, seed=1)
    sppm = scenes.render_passes(scene)
    for name in ("Denoising Albedo", "Denoising Normal"):
        a, b = sppm[name][..., :3].astype(np.float64), final[name][..., :3].astype(np.float64)
        assert np.isfinite(a).all() and np.abs(a).max() > 0.1
        pad = np.pad(b, ((1, 1), (1, 1), (0, 0)), mode="edge")
        spread = np.max([np.abs(pad[1 + dy:1 + dy + b.shape[0], 1 + dx:1 + dx + b.shape[1]] - b)
                         for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0).max(axis=-1)
        flat = spread < 1e-6
        err = np.abs(a - b).max(axis=-1)
        print(f"\n{name}: {flat.mean():.0%} of the pixels uniform, there max |difference| "
              f"{err[flat].max():.1e}; means {a.mean(axis=(0, 1)).round(4)} vs "
              f"{b.mean(axis=(0, 1)).round(4)}")
        assert flat.mean() > 0.4
        # At most one of a pixel's 16 paths may record nothing: a reflection off the
        # smooth-shaded mirror sphere whose direction falls below its geometric surface is
        # rejected by the closure sampler in both integrators (closure.sample_delta /
        # sample_bsdf), and the two sample different sub-pixel positions.
        assert np.mean(err[flat] < 1e-5) > 0.99, name
        assert err[flat].max() < 1.0 / 16 + 1e-5, name
        np.testing.assert_allclose(a.mean(axis=(0, 1)), b.mean(axis=(0, 1)), rtol=0.02, atol=2e-3)


@pytest.mark.api
def test_the_denoise_setting_builds_and_removes_its_compositor(tmp_path):
    """The Denoise setting on every supported Blender (compat.denoise_compositor: 5.x a
    compositing node group, 4.x the scene's own node tree with a Composite node): the
    Render Layers' Image, Denoising Albedo and Denoising Normal feed a Denoise node whose
    result is the saved image (finite, not the render, its mean kept, no rougher between
    neighbouring pixels: this smooth scene has little noise to take; that Denoise lowers
    the error of a noisy render is test_denoise_lowers_the_error_of_a_preview_render), and
    switching it off gives the render back unchanged."""
    scene = scenes.plane_and_point_light(width=32, height=24)
    scenes.use_photon_map(scene, samples=1, global_photons=2000, caustic_photons=0,
                          final_gather_rays=2, seed=3)
    from photon_map.photon_engine import compat
    noisy = composite(scene, tmp_path / "noisy.exr")
    scene.photon_map.denoise = True
    assert scene.photon_map.denoising_data
    tree = scene.compositing_node_group if hasattr(scene, "compositing_node_group") \
        else scene.node_tree
    denoise = tree.nodes[compat.DENOISE_TREE]
    assert {s.name for s in denoise.inputs if s.is_linked} == {"Image", "Albedo", "Normal"}
    denoised = composite(scene, tmp_path / "denoised.exr")
    assert np.isfinite(denoised).all() and denoised.min() >= 0

    def roughness(image):
        return float(np.abs(np.diff(image, axis=1)).mean())

    print(f"\nneighbour spread: {roughness(noisy):.4f} noisy, {roughness(denoised):.4f} denoised")
    assert not np.array_equal(denoised, noisy) and roughness(denoised) <= roughness(noisy)
    np.testing.assert_allclose(denoised.mean(), noisy.mean(), rtol=0.1)
    scene.photon_map.denoise = False
    np.testing.assert_allclose(composite(scene, tmp_path / "again.exr"), noisy, atol=1e-6)
