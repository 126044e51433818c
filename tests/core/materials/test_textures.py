"""Image textures and cut-outs (core/materials/textures.py): the bilinear lookup and the sRGB decode
against hand-computed values, the scene contract's checks, textured albedo in every term
(a uniform texture renders as the constant albedo it holds, a texture changes colour
bleeding like the geometry it paints), and Principled alpha as a straight pass-through."""

import numpy as np
import pytest

from core.photons import store
from core.integrators import photon_mapping as integrator
from core.photons import scatter
from core.scene import shapes
from core.integrators import sppm
from core.materials import textures
from core.scene.contract import (CAMERA_ORTHOGRAPHIC, LIGHT_POINT, LIGHT_SUN, Camera, Lights, Materials,
                        Scene, SceneError, Textures)
from core.settings import RenderSettings


def planar_uvs(mesh, origin, u_axis, v_axis):
    """The mesh with UVs (p - origin) . axis / |axis|^2 per corner (a planar projection)."""
    p = mesh.vertices[mesh.triangles].astype(np.float64) - np.asarray(origin, np.float64)
    ua, va = np.asarray(u_axis, np.float64), np.asarray(v_axis, np.float64)
    uv = np.stack([p @ ua / (ua @ ua), p @ va / (va @ va)], axis=-1).astype(np.float32)
    return type(mesh)(**{**mesh.__dict__, "uvs": np.ascontiguousarray(uv)})


def ortho_down(center, size, res):
    """Orthographic camera 5 m above ``center`` looking down (-Z), image +X right, +Y up."""
    eye = np.asarray(center, np.float64) + [0, 0, 5]
    return Camera(to_world=shapes.look_at(eye, center, (0, 1, 0)), width=res, height=res,
                  film_size=np.array([size, size]), kind=CAMERA_ORTHOGRAPHIC)


# --- the lookup ------------------------------------------------------------------------------

def _grid_texture():
    # 3 x 2 texels, one channel value 10 j + i (row j = 0 at the bottom), alpha = i / 2.
    img = np.zeros((2, 3, 4), np.float32)
    for j in range(2):
        for i in range(3):
            img[j, i] = [10 * j + i, 0, 0, i / 2]
    return Textures.from_images([img])


@pytest.mark.parametrize("uv, value", [
    ((0.5 / 3, 0.25), 0.0),            # centre of texel (0, 0)
    ((1.5 / 3, 0.75), 11.0),           # centre of texel (1, 1)
    ((2.5 / 3, 0.25), 2.0),            # centre of texel (2, 0)
    ((1.0 / 3, 0.25), 0.5),            # half-way between texels 0 and 1
    ((0.5 / 3, 0.5), 5.0),             # half-way between rows 0 and 1
    ((1.0 / 3, 0.5), 5.5),             # the middle of four texels
    ((0.0, 0.25), 1.0),                # left edge: half texel 0, half texel 2 (repeat)
    ((0.5 / 3, 0.0), 5.0),             # bottom edge: half row 0, half row 1 (repeat)
    ((0.5 / 3 + 1.0, 0.25 - 1.0), 0.0),  # one period away: the same texel
    ((0.5 / 3 - 3.0, 0.75 + 2.0), 10.0),
    ((0.5 / 3 + 0.25 / 3, 0.25), 0.25),  # a quarter of the way from texel 0 to 1
])
def test_bilinear_lookup_matches_hand_computed_values(uv, value):
    out = textures.lookup(_grid_texture(), 0, np.array([uv]))
    assert out[0, 0] == pytest.approx(value, abs=1e-5)


def test_lookup_reads_alpha_and_the_right_texture_of_several():
    a = np.full((1, 1, 3), 0.2, np.float32)
    b = np.zeros((2, 2, 4), np.float32)
    b[..., 3] = 0.5
    b[1, 1, :3] = 1.0
    tx = Textures.from_images([a, b])
    out = textures.lookup(tx, [0, 1, 1], np.array([[0.3, 0.9], [0.75, 0.75], [0.25, 0.25]]))
    np.testing.assert_allclose(out[0], [0.2, 0.2, 0.2, 1.0], atol=1e-6)   # no alpha -> 1
    np.testing.assert_allclose(out[1], [1.0, 1.0, 1.0, 0.5], atol=1e-6)
    np.testing.assert_allclose(out[2], [0.0, 0.0, 0.0, 0.5], atol=1e-6)


def test_srgb_decode_is_the_iec_formula():
    c = np.array([0.0, 0.02, 0.04045, 0.0405, 0.2, 0.5, 0.735, 1.0])
    want = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(textures.srgb_to_linear(c), want, rtol=1e-6, atol=1e-9)
    assert textures.srgb_to_linear(0.5) == pytest.approx(0.21404114, rel=1e-6)


# --- the scene contract --------------------------------------------------------------------

def _floor_scene(mats, tx=None, res=4):
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), 0)])
    lights = Lights.from_list([{"kind": LIGHT_SUN, "power": 1.0}])
    return Scene(mesh, mats, lights, ortho_down([0, 0, 0], 2.0, res),
                 textures=tx if tx is not None else Textures.empty())


def test_bad_textures_and_alpha_raise_errors_naming_the_field():
    tx = Textures.from_images([np.ones((2, 2, 3), np.float32)])
    with pytest.raises(SceneError, match="materials.diffuse_texture of 'Leaf'"):
        _floor_scene(Materials.from_list([{"name": "Leaf", "diffuse": [1] * 3,
                                           "diffuse_texture": 1}]), tx).validate()
    with pytest.raises(SceneError, match="materials.alpha of 'Leaf'"):
        _floor_scene(Materials.from_list([{"name": "Leaf", "alpha": 1.5}])).validate()
    with pytest.raises(SceneError, match="materials.alpha_texture"):
        _floor_scene(Materials.from_list([{"alpha_texture": 0}])).validate()
    bad = Textures(tx.pixels, np.array([2], np.int64), tx.width, tx.height, ("img",))
    with pytest.raises(SceneError, match="textures.offset of 'img'"):
        _floor_scene(Materials.from_list([{"diffuse": [1] * 3}]), bad).validate()
    nan = Textures(np.full((4, 4), np.nan, np.float32), tx.offset, tx.width, tx.height)
    with pytest.raises(SceneError, match="textures.pixels"):
        _floor_scene(Materials.from_list([{"diffuse": [1] * 3}]), nan).validate()
    _floor_scene(Materials.from_list([{"diffuse": [1] * 3, "diffuse_texture": 0}]), tx).validate()


def test_textured_plane_under_a_sun_shows_each_texel_times_e_over_pi():
    """4 x 4 colour blocks of 4 x 4 texels each over the floor seen from above: inside a
    block (away from its border texels) the bilinear lookup is the block's colour, and
    the pixels there are colour x E cos / pi (direct light only)."""
    rng = np.random.default_rng(1)
    img = rng.uniform(0.05, 1.0, (4, 4, 3)).astype(np.float32)
    big = np.repeat(np.repeat(img, 4, axis=0), 4, axis=1)  # 16 x 16 texels
    mats = Materials.from_list([{"diffuse": [1.0] * 3, "diffuse_texture": 0}])
    scene = _floor_scene(mats, Textures.from_images([big]), res=16)
    scene = Scene(planar_uvs(scene.mesh, [-1, -1, 0], [2, 0, 0], [0, 2, 0]), scene.materials,
                  scene.lights, scene.camera, textures=scene.textures)
    out = integrator.render(scene, RenderSettings(samples=4, caustics=False,
                                                  indirect_mode="off"))
    d = out.passes["direct"]
    # Image row 0 is the top (+Y), texture row 0 the bottom (v = 0 at y = -1); a block is
    # 4 x 4 pixels and its middle 2 x 2 pixels lie where the lookup is constant.
    for j in range(4):
        for i in range(4):
            r, c = 4 * (3 - j) + 1, 4 * i + 1
            block = d[r:r + 2, c:c + 2].reshape(-1, 3)
            np.testing.assert_allclose(block, np.broadcast_to(img[j, i] / np.pi, block.shape),
                                       rtol=1e-4)


# --- textured albedo in every term --------------------------------------------------------

def _cornell_textured():
    """The integrator tests' Cornell box, its white and red walls painted by uniform
    textures of their own colours (lobe weight 1)."""
    from tests.core.integrators.test_photon_mapping import cornell

    base = cornell(res=12)
    m = base.materials
    white = np.full((2, 2, 3), m.diffuse[0], np.float32)
    red = np.full((3, 5, 3), m.diffuse[1], np.float32)
    diffuse = m.diffuse.copy()
    diffuse[0] = diffuse[1] = 1.0
    tex = np.full(m.count, -1, np.int32)
    tex[0], tex[1] = 0, 1
    mats = Materials(**{**m.__dict__, "diffuse": diffuse, "diffuse_texture": tex})
    rng = np.random.default_rng(2)
    mesh = base.mesh
    uvs = rng.uniform(-3, 3, mesh.uvs.shape).astype(np.float32)  # any UVs: uniform texture
    mesh = type(mesh)(**{**mesh.__dict__, "uvs": uvs})
    return base, Scene(mesh, mats, base.lights, base.camera, base.world,
                       Textures.from_images([white, red]))


SMALL = RenderSettings(samples=4, seed=3, global_photons=40_000, caustic_photons=20_000,
                       final_gather_rays=16)


@pytest.mark.parametrize("mode", ["final_gather", "preview"])
def test_uniform_texture_renders_like_the_constant_albedo(mode):
    base, textured = _cornell_textured()
    st = SMALL.with_values(indirect_mode=mode)
    a = integrator.render(base, st)
    b = integrator.render(textured, st)
    assert a.stats["caustic_photons_stored"] > 0 and a.stats["global_photons_stored"] > 0
    for name, img in a.passes.items():
        # Bilinear weights of a uniform texture round to the texel within an ulp or so;
        # a photon's roulette can flip on that, so allow float-rounding-sized noise.
        np.testing.assert_allclose(b.passes[name].mean(axis=(0, 1)), img.mean(axis=(0, 1)),
                                   rtol=2e-3, atol=1e-7, err_msg=name)
        assert np.mean(np.abs(b.passes[name] - img)) <= 2e-3 * max(img.mean(), 1e-9) + 1e-7, name


def test_uniform_texture_renders_like_the_constant_albedo_in_sppm():
    base, textured = _cornell_textured()
    settings = RenderSettings(seed=3, progressive_passes=3, photons_per_pass=20_000)
    a = sppm.render(base, settings)
    b = sppm.render(textured, settings)
    np.testing.assert_allclose(b.passes["combined"].mean(axis=(0, 1)),
                               a.passes["combined"].mean(axis=(0, 1)), rtol=2e-3)
    assert np.mean(np.abs(b.passes["combined"] - a.passes["combined"])) <= \
        2e-3 * a.passes["combined"].mean()


def _bleed_scene(floor: str):
    """A white wall at x = 1 (facing -X) on a 2 x 2 m floor, a point light above. floor:
    "white", "texture" (an 8 x 1 texture: 4 white texels for x < 0, 4 red ones for x > 0,
    UVs spanning texel centre to texel centre so nothing wraps) or "split" (the same
    painted with two constant materials split at x = 0)."""
    white, red = [0.8, 0.8, 0.8], [0.8, 0.1, 0.1]
    wall = shapes.quad([1, 0, 1], [0, -1, 0], [0, 0, 1])  # normal (-1, 0, 0)
    if floor == "split":
        parts = [(shapes.quad([-0.5, 0, 0], [0.5, 0, 0], [0, 1, 0]), 1),
                 (shapes.quad([0.5, 0, 0], [0.5, 0, 0], [0, 1, 0]), 2), (wall, 0)]
    else:
        parts = [(shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), 1), (wall, 0)]
    rows = [{"diffuse": white}, {"diffuse": white}, {"diffuse": red}]
    tx = Textures.empty()
    mesh = shapes.assemble(parts)
    if floor == "texture":
        img = np.array([[white] * 4 + [red] * 4], np.float32)
        tx = Textures.from_images([img])
        rows[1] = {"diffuse": [1.0] * 3, "diffuse_texture": 0}
        # x = -1 -> u = 1/16 (centre of texel 0), x = 1 -> u = 15/16 (centre of texel 7)
        mesh = planar_uvs(mesh, [-1 - 2 / 14, 0, 0], [2 * 8 / 7, 0, 0], [0, 1, 0])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0.0, 0.0, 1.8],
                                "power": 300.0}])
    cam = Camera(to_world=shapes.look_at([-2, 0, 1], [1, 0, 1], (0, 0, 1)), width=8, height=8,
                 film_size=np.array([1.6, 1.6]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, Materials.from_list(rows), lights, cam, textures=tx)


def test_a_red_textured_floor_bleeds_red_on_the_wall_like_red_geometry():
    st = RenderSettings(samples=4, seed=5, global_photons=100_000, caustics=False,
                        final_gather_rays=64)
    ind = {k: integrator.render(_bleed_scene(k), st).passes["indirect"].mean(axis=(0, 1))
           for k in ("white", "texture", "split")}
    assert ind["white"][0] / ind["white"][1] == pytest.approx(1.0, abs=0.03)
    assert ind["texture"][0] / ind["texture"][1] > 1.15
    np.testing.assert_allclose(ind["texture"], ind["split"], rtol=0.04)


# --- cut-outs (Principled alpha) ----------------------------------------------------------

def _cutout_scene(alpha=0.25, res=16):
    """A floor (z = 0, albedo 0.8) and above it at z = 0.5 a green plane of opacity
    ``alpha`` covering x in [-0.5, 0.5] (both facing up), a unit sun straight down."""
    floor = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    plane = shapes.quad([0, 0, 0.5], [0.5, 0, 0], [0, 1, 0])
    mats = Materials.from_list([{"diffuse": [0.8, 0.8, 0.8]},
                                {"diffuse": [0.9, 0.3, 0.1], "alpha": alpha}])
    lights = Lights.from_list([{"kind": LIGHT_SUN, "power": 1.0}])
    return Scene(shapes.assemble([(floor, 0), (plane, 1)]), mats, lights,
                 ortho_down([0, 0, 0], 2.0, res))


def test_floor_seen_through_a_cutout_is_the_alpha_blend():
    """Over the plane: 0.25 x plane (E / pi x albedo) + 0.75 x floor lit through the plane
    (0.75 E / pi x 0.8); beside it the bare floor. Everything in the Direct pass."""
    scene = _cutout_scene()
    out = integrator.render(scene, RenderSettings(samples=64, caustics=False,
                                                  indirect_mode="off"))
    d = out.passes["direct"]
    e = 1.0 / np.pi
    over = d[:, 5:11].mean(axis=(0, 1))   # x in [-0.5, 0.5] -> columns 4..11
    beside = np.concatenate([d[:, :3], d[:, 13:]], axis=1).mean(axis=(0, 1))
    want = 0.25 * np.array([0.9, 0.3, 0.1]) * e + 0.75 * 0.75 * 0.8 * e
    np.testing.assert_allclose(over, want, rtol=0.02)
    np.testing.assert_allclose(beside, 0.8 * e, rtol=1e-4)
    assert np.all(out.passes["specular"] == 0)


def test_opaque_alpha_changes_nothing():
    a = integrator.render(_cutout_scene(alpha=1.0), SMALL.with_values(caustics=False))
    mats = _cutout_scene().materials
    opaque = Materials(**{**mats.__dict__, "alpha": None})
    s = _cutout_scene()
    b = integrator.render(Scene(s.mesh, opaque, s.lights, s.camera), SMALL.with_values(caustics=False))
    for name, img in a.passes.items():
        np.testing.assert_array_equal(b.passes[name], img, err_msg=name)


def test_photons_pass_a_cutout_straight_without_becoming_caustic():
    """The scatter kernel at an opacity-0.25 plane: 75 % of the photons go on unchanged
    (direction, flux, bounce counts), in the caustic mode too, where none is stored."""
    n = 100_000
    tri_v = np.array([[[-10, -10, 0], [10, -10, 0], [0, 10, 0]]], np.float32)
    tri_n = np.array([[[0, 0, 1]] * 3], np.float32)
    from core.materials import bsdf, closure
    mats = Materials.from_list([{"diffuse": [0.5] * 3, "alpha": 0.25}])
    m = bsdf.material_table(mats)
    d = np.tile(np.array([0.6, 0.0, -0.8], np.float32), (n, 1))
    for mode in (store.MODE_CAUSTIC, store.MODE_GLOBAL):
        out = [np.zeros(n, bool), np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32),
               np.zeros((n, 3), np.float32), np.zeros(n, bool), np.zeros((n, 3), np.float32),
               np.zeros((n, 3), np.float32), np.zeros((n, 3))]
        n_diff, n_spec = np.zeros(n, np.int32), np.zeros(n, np.int32)
        scatter.scatter_kernel(tri_v, tri_n, np.zeros(1, np.int32), 20.0, closure.table(mats),
                               np.any(m["diffuse"] > 0, axis=1),
                               np.any(m["specular"] > 0, axis=1) | np.any(m["transmission"] > 0, axis=1),
                               np.zeros((0, 3)), np.zeros(0, np.int32), np.zeros((0, 3)),
                               np.zeros((0, 3)), np.full(n, 0.25),
                               np.zeros(n, np.int32),
                               np.full(n, 0.3, np.float32), np.full(n, 0.3, np.float32), d,
                               np.ones((n, 3)), np.arange(n, dtype=np.int64), n_diff, n_spec,
                               np.zeros(n), np.int64(5), np.arange(5, dtype=np.int64), np.int64(0), mode,
                               store.STORE_ALL, False, *out)
        stored, alive, o_new, d_new, f_new = out[0], out[4], out[5], out[6], out[7]
        straight = alive & np.all(d_new == d, axis=1)
        assert straight.mean() == pytest.approx(0.75, abs=0.01)
        assert np.all(f_new[straight] == 1.0) and np.all(o_new[straight, 2] < 0)
        assert np.all(n_spec == 0)
        if mode == store.MODE_CAUSTIC:
            assert not stored.any() and alive.sum() == straight.sum()
        else:
            # stored at full flux whether it passes or not; the rest bounce diffusely
            assert stored.all()
            bounced = alive & ~straight
            assert bounced.mean() == pytest.approx(0.25 * 0.5, abs=0.01)
            assert np.all(n_diff[bounced] == 1) and np.all(n_diff[straight] == 0)


def test_cutout_with_photon_terms_matches_the_blend_in_sppm_and_final_gathering():
    """Indirect light: the floor under the plane receives 0.75 of the sun (direct photons
    pass); the plane's underside sees the floor. Final gathering and SPPM agree on the
    full image within noise (two independent estimators of the same transport)."""
    scene = _cutout_scene(res=12)
    fg = integrator.render(scene, RenderSettings(samples=16, adaptive_threshold=0.0, seed=2,
                                                 global_photons=100_000, caustics=False,
                                                 final_gather_rays=32))
    sp = sppm.render(scene, RenderSettings(seed=2, progressive_passes=24, photons_per_pass=50_000))
    a = fg.passes["combined"][:, 4:8].mean(axis=(0, 1))
    b = sp.passes["combined"][:, 4:8].mean(axis=(0, 1))
    np.testing.assert_allclose(a, b, rtol=0.05)


def test_image_alpha_cuts_the_plane_out_where_it_is_zero():
    """An 8 x 1 alpha mask (4 texels 0 for x < 0, 4 texels 1 for x > 0) on the green plane
    of _cutout_scene: left of the blend zone the bare floor fully lit, right of it the
    plane, all exact (no pass-through noise where the opacity is 0 or 1)."""
    s = _cutout_scene()
    mask = np.zeros((1, 8, 4), np.float32)
    mask[..., 3] = [0, 0, 0, 0, 1, 1, 1, 1]
    rows = [{"diffuse": [0.8] * 3}, {"diffuse": [0.9, 0.3, 0.1], "alpha_texture": 0}]
    # the plane spans x in [-0.5, 0.5] -> u from texel centre 0 (1/16) to texel 7 (15/16)
    mesh = planar_uvs(s.mesh, [-0.5 - 1 / 14, 0, 0], [8 / 7, 0, 0], [0, 1, 0])
    scene = Scene(mesh, Materials.from_list(rows), s.lights, s.camera,
                  textures=Textures.from_images([mask]))
    d = integrator.render(scene, RenderSettings(samples=4, caustics=False,
                                                indirect_mode="off")).passes["direct"]
    e = 1.0 / np.pi
    np.testing.assert_allclose(d[:, 4:7], np.broadcast_to(0.8 * e, d[:, 4:7].shape), rtol=1e-5)
    np.testing.assert_allclose(d[:, 9:12], np.broadcast_to(np.array([0.9, 0.3, 0.1]) * e,
                                                          d[:, 9:12].shape), rtol=1e-5)
