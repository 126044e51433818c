"""Shader programs at the hits (core/prepared.py ``HitShader``): a program's closure
parameters reach the camera pass, the photons, final gathering and SPPM; a constant
program renders exactly like the material without one; a UV-driven base colour gives the
analytic Lambert radiance per pixel."""

from dataclasses import replace

import numpy as np
import pytest

from core.integrators import photon_mapping, sppm
from core.prepared import prepare
from core.scene import closures, shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, LIGHT_SUN, Camera, Lights, Materials, \
    Scene, SceneError
from core.settings import RenderSettings
from core.shading import program as pg
from core.shading.converters import MATH_OPS

W = pg.INSTRUCTION_WIDTH
RES = 8


def ins(op, ints, regs):
    row = [op] + list(ints) + [0] * (4 - len(ints)) + list(regs)
    return row + [-1] * (W - len(row))


def colour_outputs(reg):
    return [[reg, pg.TARGET_CLOSURE, 0, closures.COLOR + c] for c in range(3)]


def constant_program(value_sqrt):
    """COLOR = value_sqrt * value_sqrt, computed at every point (one Math MULTIPLY)."""
    code = [ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [0, 0, 0, 1])]
    return pg.ShaderProgram.build(code, [value_sqrt], colour_outputs(1), 2, name="constant")


def uv_program():
    """COLOR = (U, U, U) of the first UV map."""
    code = [ins(pg.OP_INPUT, [pg.SOURCE_UV, 0], [0])]
    return pg.ShaderProgram.build(code, [], colour_outputs(0), 3, name="uv")


def sun(strength):
    m = shapes.look_at([0, 0, 1], [0, 0, 0])
    m[:3, 3] = 0.0
    return {"kind": LIGHT_SUN, "to_world": m, "power": strength, "angle": 0.0}


def scene(program, colour=0.25, walls=True, roughness=0.0):
    """A 2 m floor (UV (0, 0) to (1, 1) over x, y in [-1, 1]) seen from above, a sun
    straight down, and (walls) four white walls 2.5 m high around it for indirect light.
    roughness > 0 makes the floor Oren-Nayar (its photon terms then go through the BSDF
    estimate, gather.bsdf_terms)."""
    floor = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    parts = [(floor, 0)]
    if walls:
        for c, u in (([0, 1.5, 1.25], [1.5, 0, 0]), ([0, -1.5, 1.25], [1.5, 0, 0]),
                     ([1.5, 0, 1.25], [0, 1.5, 0]), ([-1.5, 0, 1.25], [0, 1.5, 0])):
            parts.append((shapes.quad(c, u, [0, 0, 1.25]), 1))
    mesh = shapes.assemble(parts)
    corners = mesh.vertices[mesh.triangles[mesh.material_index == 0]]
    uvs = np.array(mesh.uvs, copy=True)
    uvs[mesh.material_index == 0] = (corners[..., :2] + 1.0) / 2.0
    mesh = replace(mesh, uvs=uvs.astype(np.float32))
    # The legacy diffuse lobe as the exporter writes it: the photon terms of hits
    # without a program still read it (prepared.surfaces). Roughness 0: Lambert.
    floor_row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE,
                               "params": {"color": colour, "roughness": roughness}}],
                 "program": program,
                 "diffuse": [colour] * 3}
    mats = Materials.from_list([floor_row, {"diffuse": [0.8, 0.8, 0.8]}])
    cam = Camera(to_world=shapes.look_at([0, 0, 3], [0, 0, 0], (0, 1, 0)), width=RES,
                 height=RES, film_size=np.array([2.0, 2.0]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, mats, Lights.from_list([sun(3.0)]), cam)


SETTINGS = RenderSettings(samples=2, global_photons=3000, caustic_photons=1000,
                          final_gather_rays=4, threads=2)


@pytest.mark.parametrize("roughness", [0.0, 0.5], ids=["lambert", "oren_nayar"])
@pytest.mark.parametrize("mode", ["final_gather", "preview"])
def test_a_constant_program_renders_exactly_like_the_material(mode, roughness):
    st = SETTINGS.with_values(indirect_mode=mode)
    plain = photon_mapping.render(scene(None, 0.25, roughness=roughness), st).passes
    programmed = photon_mapping.render(scene(constant_program(0.5), 0.9, roughness=roughness),
                                       st).passes
    assert plain["indirect"].max() > 0 and plain["direct"].max() > 0
    for name, image in plain.items():
        np.testing.assert_array_equal(programmed[name], image, err_msg=name)


def test_a_constant_program_in_sppm_equals_the_material():
    st = SETTINGS.with_values(integrator="progressive", progressive_passes=2, photons_per_pass=2000)
    plain = sppm.render(scene(None, 0.25), st).passes
    programmed = sppm.render(scene(constant_program(0.5), 0.9), st).passes
    for name, image in plain.items():
        np.testing.assert_array_equal(programmed[name], image, err_msg=name)


def test_a_uv_base_colour_gives_the_lambert_radiance_of_each_pixel():
    # Sun of 3 W/m^2 straight down on a Lambert floor: L = albedo * E / pi, albedo = U,
    # U linear across the image: the pixel's mean U is its centre's.
    out = photon_mapping.render(scene(uv_program(), walls=False),
                                SETTINGS.with_values(samples=16)).passes["direct"]
    u = (np.arange(RES) + 0.5) / RES
    expected = np.broadcast_to((u * 3.0 / np.pi)[None, :, None], out.shape)
    np.testing.assert_allclose(out, expected, rtol=0.03, atol=1e-3)


def test_the_radiance_cache_reads_a_programmed_floor_at_each_gather_hit(monkeypatch):
    """Final gathering from a wall that sees only the floor's light: through the radiance
    cache and through a full k-NN estimate at every gather hit, the wall's indirect light
    agrees (means per channel within 2 %). The floor's base colour is U (mean 0.5) over a
    hidden constant colour of 0.9: a cache of rho / pi E with the constant rho (instead of
    E / pi times the hit's programmed albedo) made the wall about 1.5 x too bright."""
    from core.integrators import gather

    sc = scene(uv_program(), colour=0.9)
    # Inside the box, looking at the +y wall (the sun lights only the floor).
    sc = replace(sc, camera=Camera(
        to_world=shapes.look_at([0, -1.4, 1.25], [0, 1.5, 1.25], (0, 0, 1)), width=16,
        height=16, film_size=np.array([2.0, 2.0]), kind=CAMERA_ORTHOGRAPHIC))
    st = RenderSettings(samples=4, seed=5, caustics=False, global_photons=40_000,
                        final_gather_rays=256, threads=2)
    cached = photon_mapping.render(sc, st)
    monkeypatch.setattr(gather, "build_radiance_cache",
                        lambda terms, prepared, settings, **kw: None)
    full = photon_mapping.render(sc, st)
    a, b = cached.passes["indirect"], full.passes["indirect"]
    assert b.min() >= 0 and b.mean() > 0
    np.testing.assert_allclose(a.mean(axis=(0, 1)), b.mean(axis=(0, 1)), rtol=0.02)


def test_programmed_hits_get_closure_rows_of_their_own():
    """Hits on the programmed floor get rows past the materials holding the program's
    colour; hits on the walls (no program) keep the prepared table and their material."""
    prepared = prepare(scene(constant_program(0.5), 0.9))
    with prepared:
        shader = prepared.hit_shader
        assert shader.active
        prim = np.flatnonzero(prepared.tri_material == 0).astype(np.int32)
        u = np.full(prim.shape, 0.25, np.float32)
        d = np.tile([0.0, 0.0, -1.0], (prim.shape[0], 1))
        tab, rows = shader.closures_at(prim, u, u, d, prepared.tri_material[prim])
        assert np.all(rows >= prepared.closures.first.shape[0])
        np.testing.assert_array_equal(tab.params[tab.first[rows], closures.COLOR], 0.25)
        # Only the programmed hits get rows of their own: the walls keep theirs.
        wall = np.flatnonzero(prepared.tri_material == 1)[:1].astype(np.int32)
        tab2, rows2 = shader.closures_at(wall, u[:1], u[:1], d[:1],
                                         prepared.tri_material[wall])
        assert tab2 is prepared.closures and rows2[0] == 1


def test_a_program_writing_a_missing_closure_is_refused():
    code = [ins(pg.OP_INPUT, [pg.SOURCE_UV, 0], [0])]
    bad = pg.ShaderProgram.build(code, [], [[0, pg.TARGET_CLOSURE, 3, closures.ROUGHNESS]], 3,
                                 name="bad")
    with pytest.raises(SceneError, match="closure 3"):
        scene(bad).validate()


def test_the_lobe_masks_follow_what_the_program_can_produce():
    """A floor whose Base Color is the program's (U) over a hidden constant colour of 0:
    the constant row has no diffuse lobe, the program's hits do, so photons are stored
    there (has_diffuse) and the picture does not depend on the hidden constant."""
    dark = prepare(scene(uv_program(), colour=0.0))
    with dark:
        assert dark.has_diffuse[0] and dark.lobes["diffuse"][0]
        assert not dark.lobes["rough"][0] and not dark.lobes["delta"][0]
    st = SETTINGS.with_values(samples=2)
    a = photon_mapping.render(scene(uv_program(), colour=0.0), st)
    b = photon_mapping.render(scene(uv_program(), colour=0.9), st)
    assert a.passes["indirect"].max() > 0
    for name, image in b.passes.items():
        np.testing.assert_allclose(a.passes[name], image, rtol=1e-6, atol=1e-7, err_msg=name)


def test_materials_sharing_a_program_evaluate_it_once_bit_for_bit():
    """``HitShader.shade`` evaluates a program once over every material running it (equal
    programs, not only the same object) and each other program apart: each hit's
    closure parameters are bit for bit those of shading its material's hits alone."""
    sc = scene(uv_program())
    mesh = sc.mesh
    mi = np.array(mesh.material_index, copy=True)
    mi[mi == 1] = np.arange(np.count_nonzero(mi == 1)) % 2 + 1  # walls: materials 1, 2
    row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE, "params": {"color": 0.5}}],
           "diffuse": [0.5] * 3}
    mats = Materials.from_list([{**row, "program": uv_program()},
                                {**row, "program": uv_program()},
                                {**row, "program": constant_program(0.7)}])
    sc = replace(sc, mesh=replace(mesh, material_index=mi), materials=mats)
    pr = prepare(sc, 2)
    hs = pr.hit_shader
    assert hs.program_group.tolist() == [0, 0, 1]
    rng = np.random.default_rng(3)
    n = 300
    prim = rng.integers(0, mi.shape[0], n).astype(np.int32)
    u = rng.uniform(0, 0.5, n).astype(np.float32)
    v = rng.uniform(0, 0.5, n).astype(np.float32)
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    mat = pr.tri_material[prim]
    assert set(mat.tolist()) == {0, 1, 2}

    def params(tab, rows):
        return np.stack([tab.params[tab.first[r]] for r in rows])

    tab, rows = hs.closures_at(prim, u, v, d, mat)
    together = params(tab, rows)
    for m in range(3):
        sel = np.flatnonzero(mat == m)
        t1, r1 = hs.closures_at(prim[sel], u[sel], v[sel], d[sel], mat[sel])
        assert np.array_equal(params(t1, r1), together[sel])
    assert np.allclose(together[mat == 2, closures.COLOR], 0.49, atol=1e-6)
