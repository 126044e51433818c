"""Image Texture inside shader programs against Cycles, through emission (the harness of
tests/blender/shader_scenes.py: a plane per case whose Emission colour is the node's
output, Cycles at the pixel centres in this bpy process, our compiled program at the same
points; agreement as tests/blender/test_shader_nodes.py: 1e-3 per pixel relative to
max(1, |Cycles|) on 99 % of the non-edge pixels).

The images are written here as files (PNG 8 and 16-bit by a small writer, EXR by
OpenEXR) and loaded by Blender, so Cycles reads the files itself and we read Blender's
``Image.pixels``: what each stores is exercised, not a shared buffer.
"""

import struct
import zlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import shader_scenes as ss  # noqa: E402
from tests.blender import test_textures as tt  # noqa: E402
from tests.blender.export_probe import export  # noqa: E402
from tests.blender.test_shader_nodes import check, link, node  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

W, H = 7, 5   # texels: odd sizes, so a row/column mix-up shows


def write_png(path, texels):
    """(H, W, 4) uint8 or uint16 RGBA, row 0 at the TOP, as a PNG file."""
    a = np.ascontiguousarray(texels)
    depth = 8 if a.dtype == np.uint8 else 16
    h, w = a.shape[:2]
    raw = a.astype(">u2").tobytes() if depth == 16 else a.tobytes()
    stride = w * 4 * depth // 8
    rows = b"".join(b"\0" + raw[y * stride:(y + 1) * stride] for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + \
            struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, 6, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)
    return path


def write_grey_png(path, texels):
    """(H, W) uint8 grey, row 0 at the TOP, as a one-channel PNG file (colour type 0)."""
    a = np.ascontiguousarray(texels, np.uint8)
    h, w = a.shape
    rows = b"".join(b"\0" + a[y].tobytes() for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + \
            struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)
    return path


def write_exr(path, texels):
    """(H, W, 4) float32 RGBA, or (H, W) float32 luminance (one channel, "Y"), row 0 at the
    top, as a single-part float EXR."""
    import OpenEXR
    if texels.ndim == 2:
        channels = {"Y": np.ascontiguousarray(texels, np.float32)}
    else:
        channels = {c: np.ascontiguousarray(texels[..., i], np.float32)
                    for i, c in enumerate("RGBA")}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(path)
    return path


def texels(dtype, seed=3, alpha=False):
    rng = np.random.default_rng(seed)
    if dtype == np.float32:
        a = rng.uniform(0.0, 3.0, (H, W, 4)).astype(np.float32)  # HDR values
        a[..., 3] = 1.0
        return a
    top = np.iinfo(dtype).max
    a = rng.integers(0, top + 1, (H, W, 4)).astype(dtype)
    if not alpha:
        a[..., 3] = top
    return a


@pytest.fixture(scope="module")
def image_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("images")
    return {"png8": write_png(str(d / "byte.png"), texels(np.uint8)),
            "png16": write_png(str(d / "short.png"), texels(np.uint16, 4)),
            "alpha": write_png(str(d / "alpha.png"), texels(np.uint8, 6, alpha=True)),
            "exr": write_exr(str(d / "float.exr"), texels(np.float32, 5)),
            "grey_png": write_grey_png(str(d / "grey.png"), texels(np.uint8, 7)[..., 0]),
            "grey_exr": write_exr(str(d / "grey.exr"), texels(np.float32, 8)[..., 0]),
            "udim": [write_png(str(d / f"tiles.{n}.png"), texels(np.uint8, n))
                     for n in (1001, 1002, 1011)],
            "dir": d}


def load(path, colorspace="sRGB", name=None):
    img = bpy.data.images.load(path, check_existing=False)
    if name:
        img.name = name
    if colorspace:
        img.colorspace_settings.name = colorspace
    return img


def image_plane(path, interpolation="Linear", extension="REPEAT", colorspace="sRGB",
                scale=(2.3, 1.7, 1.0), location=(-0.6, -0.35, 0.0), projection="FLAT",
                output="Color", udim=False, times_alpha=False):
    """UV -> Mapping (scale, location) -> Image Texture -> output (times its Alpha output
    by a Vector Math Multiply when ``times_alpha``: the Alpha output used)."""
    def build(tree, color):
        if udim:
            img = load(path)
            img.source = 'TILED'
        else:
            img = load(path, colorspace)
        tc = node(tree, "ShaderNodeTexCoord")
        mp = node(tree, "ShaderNodeMapping", vector_type='POINT')
        mp.inputs["Scale"].default_value = scale
        mp.inputs["Location"].default_value = location
        link(tree, tc.outputs["UV"], mp.inputs["Vector"])
        tex = node(tree, "ShaderNodeTexImage", image=img, interpolation=interpolation,
                   extension=extension, projection=projection)
        link(tree, mp.outputs[0], tex.inputs["Vector"])
        if times_alpha:
            vm = node(tree, "ShaderNodeVectorMath", operation='MULTIPLY')
            link(tree, tex.outputs["Color"], vm.inputs[0])
            link(tree, tex.outputs["Alpha"], vm.inputs[1])
            link(tree, vm.outputs[0], color)
        else:
            link(tree, tex.outputs[output], color)
    return build


def test_image_interpolation_and_extension_through_mapping_match_cycles(image_files):
    png = image_files["png8"]
    specs = [(f"{i} {e}", image_plane(png, i, e))
             for i in ("Linear", "Closest") for e in ("REPEAT", "EXTEND", "CLIP", "MIRROR")]
    specs += [("Linear Non-Color", image_plane(png, colorspace="Non-Color")),
              ("Closest Non-Color", image_plane(png, "Closest", colorspace="Non-Color")),
              ("Cubic Repeat", image_plane(png, "Cubic")),
              ("Smart Mirror", image_plane(png, "Smart", "MIRROR"))]
    result = ss.compare(specs)
    assert not result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})


def test_sixteen_bit_png_and_float_exr_match_cycles(image_files):
    specs = [("16-bit Linear", image_plane(image_files["png16"])),
             ("16-bit Closest", image_plane(image_files["png16"], "Closest")),
             ("16-bit Non-Color", image_plane(image_files["png16"], colorspace="Non-Color")),
             ("EXR Linear", image_plane(image_files["exr"], colorspace=None)),
             ("EXR Closest Extend", image_plane(image_files["exr"], "Closest", "EXTEND",
                                                colorspace=None))]
    result = ss.compare(specs)
    assert not result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})


def test_one_channel_png_and_exr_match_cycles(image_files):
    """Images with one channel (a grey PNG, colour type 0; a float EXR with only "Y"):
    Blender loads them as grey RGBA, and they render as Cycles renders them, without a
    warning."""
    specs = [("grey PNG Linear", image_plane(image_files["grey_png"])),
             ("grey PNG Closest", image_plane(image_files["grey_png"], "Closest")),
             ("grey PNG Non-Color", image_plane(image_files["grey_png"], colorspace="Non-Color")),
             ("Y EXR Linear", image_plane(image_files["grey_exr"], colorspace=None)),
             ("Y EXR Closest", image_plane(image_files["grey_exr"], "Closest", colorspace=None))]
    result = ss.compare(specs)
    assert not result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})


def test_straight_alpha_associated_and_unassociated_match_cycles(image_files):
    """A Straight RGBA PNG: Color alone is the associated colour (Cycles premultiplies at
    load); Color x Alpha with the Alpha output used is the colour unassociated after
    filtering, decoded from sRGB, times alpha (not the same: the decode is non-linear)."""
    png = image_files["alpha"]
    specs = [("Color", image_plane(png)), ("Color Closest", image_plane(png, "Closest")),
             ("Alpha", image_plane(png, output="Alpha")),
             ("Color x Alpha", image_plane(png, times_alpha=True)),
             ("Color x Alpha Closest", image_plane(png, "Closest", times_alpha=True)),
             ("Non-Color x Alpha", image_plane(png, colorspace="Non-Color", times_alpha=True))]
    result = ss.compare(specs)
    assert not result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})
    a, b = result["ours"][:ss.PIXELS, :ss.PIXELS], result["ours"][ss.PIXELS:2 * ss.PIXELS,
                                                                   :ss.PIXELS]
    assert np.abs(a - b).max() > 0.05  # the two paths differ where Cycles' do


def test_image_inside_a_program_renders_texel_times_irradiance_over_pi():
    """The sun-lit plane of tests/blender/test_textures.py with the image behind a Mapping
    node (so it is sampled by the material's program, not the direct texture path): each
    block is its texel's linear colour x E cos / pi."""
    made = {}

    def material():
        made["image"], made["stored"] = tt.block_image("Blocks", "sRGB")
        mat = tt.textured_material("Mapped", made["image"], reroute=False)
        tree = mat.node_tree
        tex = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeTexImage")
        tc = node(tree, "ShaderNodeTexCoord")
        mp = node(tree, "ShaderNodeMapping", vector_type='POINT')
        link(tree, tc.outputs["UV"], mp.inputs["Vector"])
        link(tree, mp.outputs[0], tex.inputs["Vector"])
        return mat

    scene = tt.sun_plane_scene(material)
    exported = export(scene).scene
    assert exported.textures.count == 0 and exported.program_images.count == 1
    assert exported.materials.programs[0] is not None
    img = tt.render_photon_map(scene)
    want = tt.srgb_decode(made["stored"]) * tt.SUN * np.cos(tt.TILT) / np.pi
    got = tt.block_interiors(img)
    rel = np.abs(got - want[:, :, None, :]) / want[:, :, None, :]
    print(f"\nworst pixel {100 * rel.max():.3f} % off texel x E cos / pi")
    assert rel.max() < 0.02


def test_udim_plane_matches_cycles(image_files):
    """Tiles 1001, 1002 and 1011 over UV [0, 2) x [0, 2): the tile 1012 is missing
    (Cycles' magenta there, ours too)."""
    first = image_files["udim"][0]
    specs = [("UDIM Linear", image_plane(first, scale=(2.0, 2.0, 1.0), location=(0, 0, 0),
                                         udim=True)),
             ("UDIM Closest", image_plane(first, "Closest", scale=(2.0, 2.0, 1.0),
                                          location=(0, 0, 0), udim=True))]
    result = ss.compare(specs)
    assert not result["warnings"]
    check(result, [n for n, _ in specs])
    ours = result["ours"][:ss.PIXELS, :ss.PIXELS]
    # the top right quarter of the plane (u >= 1, v >= 1) is tile 1012: magenta
    np.testing.assert_array_equal(ours[2:ss.PIXELS // 2 - 2, ss.PIXELS // 2 + 2:-2],
                                  np.broadcast_to([1.0, 0.0, 1.0], (12, 12, 3)))


def test_missing_image_is_named_and_magenta_like_cycles(image_files):
    lost = str(image_files["dir"] / "nowhere.png")

    def missing(tree, color):
        img = bpy.data.images.new("Lost", 4, 4)
        img.source = 'FILE'
        img.filepath = lost  # no such file: Blender has no pixels for it
        tex = node(tree, "ShaderNodeTexImage", image=img)
        link(tree, tex.outputs["Color"], color)

    def empty(tree, color):
        tex = node(tree, "ShaderNodeTexImage")
        link(tree, tex.outputs["Color"], color)

    specs = [("Lost", missing), ("Empty", empty)]
    result = ss.compare(specs)
    check(result, [n for n, _ in specs])
    planes = result["ours"][:ss.PIXELS, :2 * ss.PIXELS]  # the 2 x 2 grid's top row
    np.testing.assert_array_equal(planes, np.broadcast_to([1.0, 0.0, 1.0], planes.shape))
    text = " | ".join(result["warnings"])
    assert '"Lost"' in text and "magenta" in text, text
    assert "no image" in text, text


def test_byte_images_are_stored_as_bytes(image_files):
    """Native precision: 4 bytes per texel for an 8-bit image, 8 for 16-bit data, 16 for
    float (and for a 16-bit colour image, which Cycles filters in linear)."""
    warnings = []
    table = ss.ProgramImageTable(warnings)
    for key, space in (("png8", "sRGB"), ("png16", "Non-Color"), ("exr", None)):
        table.slot(load(image_files[key], space), "test")
    images = table.images()
    assert not warnings
    assert images.bytes.size == W * H * 4 and images.shorts.size == W * H * 4
    assert images.floats.size == W * H * 4
    assert images.nbytes == W * H * (4 + 8 + 16)
    # the 8-bit texels are the file's bytes, exactly (row 0 at the bottom)
    np.testing.assert_array_equal(images.bytes.reshape(H, W, 4), texels(np.uint8)[::-1])
    np.testing.assert_array_equal(images.shorts.reshape(H, W, 4), texels(np.uint16, 4)[::-1])


BOX_NORMALS = [  # object-space normals: each zone of Cycles' box weights, both signs
    ("X", (0.95, 0.2, 0.1)), ("-X", (-0.9, 0.3, -0.2)), ("-Y", (0.3, -0.9, 0.2)),
    ("Y", (0.1, 0.9, 0.25)), ("-Z", (0.2, 0.1, -0.95)), ("XY", (0.6, 0.55, 0.1)),
    ("-YZ", (0.1, -0.55, 0.6)), ("-XZ", (-0.58, 0.1, 0.55)), ("XYZ", (0.57, -0.57, 0.58))]


def projected_plane(path, projection, blend=0.3, interpolation="Linear"):
    """Object coordinates -> Mapping -> Image Texture with ``projection``: the vector
    crosses the image's edges (Repeat) and, for Sphere / Tube, has z != 0.5."""
    def build(tree, color):
        img = load(path, "sRGB")
        tc = node(tree, "ShaderNodeTexCoord")
        mp = node(tree, "ShaderNodeMapping", vector_type='POINT')
        mp.inputs["Scale"].default_value = (0.7, 0.6, 0.8)
        mp.inputs["Location"].default_value = (0.45, 0.55, 0.7)
        link(tree, tc.outputs["Object"], mp.inputs["Vector"])
        tex = node(tree, "ShaderNodeTexImage", image=img, interpolation=interpolation,
                   projection=projection)
        tex.projection_blend = blend
        link(tree, mp.outputs[0], tex.inputs["Vector"])
        link(tree, tex.outputs["Color"], color)
    return build


def turn_to(normals):
    """setup for ss.compare: plane k shows its object-space normal normals[k] (None:
    unturned) to the camera (shader_scenes.turn_mesh)."""
    from mathutils import Vector

    def setup(planes):
        for plane, n in zip(planes, normals):
            if n is not None:
                q = Vector(n).normalized().rotation_difference(Vector((0.0, 0.0, 1.0)))
                ss.turn_mesh(plane, tuple(q.to_euler()))
    return setup


def test_box_sphere_and_tube_projections_match_cycles(image_files):
    """Box on the faces of a turned cube (each plane's mesh counter-rotated, so its
    object-space normal is one of BOX_NORMALS: every zone of Cycles' weights, blend 0.3,
    and one with blend 0), Sphere and Tube on an unturned plane."""
    png = image_files["png8"]
    specs = [(f"Box {k} blend 0.3", projected_plane(png, "BOX")) for k, _ in BOX_NORMALS]
    specs += [("Box XY blend 0", projected_plane(png, "BOX", blend=0.0)),
              ("Box XYZ Closest", projected_plane(png, "BOX", interpolation="Closest")),
              ("Sphere", projected_plane(png, "SPHERE")), ("Tube", projected_plane(png, "TUBE"))]
    normals = [n for _, n in BOX_NORMALS] + [BOX_NORMALS[5][1], BOX_NORMALS[8][1], None, None]
    result = ss.compare(specs, setup=turn_to(normals))
    assert not result["warnings"], result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})


def test_other_colour_spaces_and_packed_images_match_cycles(tmp_path):
    """Byte images in OCIO spaces other than sRGB and scene linear (converted texel by
    texel to scene linear: Blender's conversion here, OCIO's in Cycles), 16-bit in one, and
    a packed image whose file is gone. Texels in [0.35, 0.65]: the Rec.2020 -> Rec.709
    conversion stays positive (our images are clamped at 0)."""
    rng = np.random.default_rng(11)
    mid = rng.integers(90, 166, (H, W, 4)).astype(np.uint8)
    mid[..., 3] = 255
    png = write_png(str(tmp_path / "mid.png"), mid)
    mid16 = (mid.astype(np.uint16) * 257)
    png16 = write_png(str(tmp_path / "mid16.png"), mid16)
    packed_path = write_png(str(tmp_path / "packed.png"), texels(np.uint8, 8))

    def packed(tree, color):
        img = load(packed_path)
        img.pack()
        tex = node(tree, "ShaderNodeTexImage", image=img)
        tc = node(tree, "ShaderNodeTexCoord")
        link(tree, tc.outputs["UV"], tex.inputs["Vector"])
        link(tree, tex.outputs["Color"], color)

    specs = [(f"8-bit {s}", image_plane(png, colorspace=s))
             for s in ("Linear Rec.2020", "Filmic Log", "Display P3", "ACEScg")]
    specs += [("16-bit Linear Rec.2020", image_plane(png16, colorspace="Linear Rec.2020")),
              ("8-bit Linear Rec.2020 Closest", image_plane(png, "Closest",
                                                           colorspace="Linear Rec.2020")),
              ("Packed, file removed", packed)]
    import os

    def setup(planes):
        os.remove(packed_path)  # Cycles and the exporter read the packed copy
    result = ss.compare(specs, setup=setup)
    assert not result["warnings"], result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})
