"""Scenes built by script in any Blender, from 3.4 (Debian's ``blender``) to bpy 5.0.

A real Blender executable cannot open .blend files saved by a newer Blender, so the tests
build their scenes inside the Blender that renders them:

    blender -b --factory-startup --python-exit-code 1 --python script_scenes.py -- NAME OUT.blend

saves the scene ``NAME`` (a function below) to OUT.blend. In bpy, call the function
directly. Only API that exists in both 3.4 and 5.0 is used; Principled BSDF inputs are
set by their 4.0+ name or the 3.x one ("Emission Color" / "Emission").
The constants are the scenes' physical values; the tests derive expected pixels from them.
Units: metres; sun strength in W/m^2; radiance in W/(m^2 sr).
"""

from __future__ import annotations

import importlib.util
import math
import pathlib
import sys

import bpy

# passes_scene: three 1 m squares side by side on z = 0, seen from straight above by an
# orthographic camera, lit by a sun straight down and a uniform world.
SUN_STRENGTH = math.pi  # irradiance pi W/m^2: a white Lambert surface has radiance 1
WORLD_RADIANCE = (0.05, 0.1, 0.2)
ALBEDO = (0.2, 0.5, 0.8)  # left square: Principled, metallic 0
EMISSION = (1.0, 0.5, 0.25)  # middle square: Principled, black base, emission colour
EMISSION_STRENGTH = 2.0
MIRROR = (0.9, 0.9, 0.9)  # right square: Principled, metallic 1, roughness 0
SQUARE_CENTRES = (-1.0, 0.0, 1.0)  # x of left, middle, right squares
PASSES_VIEW = (2.7, 54, 18)  # ortho_scale (m), resolution x, y: 0.05 m per pixel

# animated_scene: a red cube slides over a grey floor while the camera follows it more
# slowly; orthographic, straight down, sun straight down (no visible shadow).
FRAMES = (1, 2, 3)
CUBE_X = (-1.0, 0.0, 1.0)  # cube centre x at each frame
CAMERA_X = (0.0, 0.5, 1.0)  # camera x at each frame
CUBE_SIZE = 0.5
CUBE_ALBEDO = (0.8, 0.1, 0.1)
FLOOR_ALBEDO = (0.5, 0.5, 0.5)
ANIMATION_VIEW = (4.0, 64, 32)  # ortho_scale (m), resolution x, y: 0.0625 m per pixel


def _scenes():
    """tests/blender/scenes.py, loaded by path (no ``tests`` package inside Blender 3.4)."""
    if "photon_map_test_scenes" not in sys.modules:
        path = pathlib.Path(__file__).with_name("scenes.py")
        spec = importlib.util.spec_from_file_location("photon_map_test_scenes", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        sys.modules[spec.name] = module
    return sys.modules["photon_map_test_scenes"]


def _set_input(node, names, value):
    for name in names:
        if name in node.inputs:
            node.inputs[name].default_value = value
            return
    raise KeyError(f"{node.name} has none of the inputs {names}")


def principled(name, base=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5,
               emission=(0.0, 0.0, 0.0), emission_strength=1.0, specular=0.5):
    """A material with one Principled BSDF (colours linear RGB). specular: Specular IOR
    Level (3.x: Specular); 0 removes the dielectric specular layer, leaving Lambert."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # before 5.0 a new material has no nodes
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new('ShaderNodeBsdfPrincipled')
    out = nodes.new('ShaderNodeOutputMaterial')
    mat.node_tree.links.new(bsdf.outputs['BSDF'], out.inputs['Surface'])
    _set_input(bsdf, ("Base Color",), (*base, 1.0))
    _set_input(bsdf, ("Metallic",), metallic)
    _set_input(bsdf, ("Roughness",), roughness)
    _set_input(bsdf, ("Emission Color", "Emission"), (*emission, 1.0))
    _set_input(bsdf, ("Emission Strength",), emission_strength)
    _set_input(bsdf, ("Specular IOR Level", "Specular"), specular)
    return mat


def uniform_world(radiance):
    """A node world whose Background is ``radiance`` (strength 1)."""
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:
        world.use_nodes = True
    background = next(n for n in world.node_tree.nodes if n.bl_idname == 'ShaderNodeBackground')
    background.inputs['Color'].default_value = (*radiance, 1.0)
    background.inputs['Strength'].default_value = 1.0
    bpy.context.scene.world = world
    return world


def _sun_straight_down():
    # A sun shines along its local -Z; unrotated, straight down. angle 0: a delta light.
    return _scenes().add_light('SUN', location=(0.0, 0.0, 3.0), power=SUN_STRENGTH, angle=0.0)


def passes_scene():
    """Diffuse, emissive and mirror squares (left to right) filling the view."""
    s = _scenes()
    scene = s.reset()
    scale, width, height = PASSES_VIEW
    s.set_resolution(width, height)
    # No specular layer on the diffuse and emissive squares: their Direct pass is analytic.
    materials = (principled("Diffuse", base=ALBEDO, specular=0.0),
                 principled("Emitter", base=(0.0, 0.0, 0.0), emission=EMISSION, specular=0.0,
                            emission_strength=EMISSION_STRENGTH),
                 principled("Mirror", base=MIRROR, metallic=1.0, roughness=0.0))
    for x, mat in zip(SQUARE_CENTRES, materials):
        s.add_plane(size=1.0, location=(x, 0.0, 0.0), material=mat, name=mat.name)
    _sun_straight_down()
    uniform_world(WORLD_RADIANCE)
    s.add_camera(location=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0), ortho_scale=scale)
    # PNG in the file: the command line's -F must switch to the multilayer EXR.
    scene.render.image_settings.file_format = 'PNG'
    return scene


REGION_BORDER = (0.2, 0.7, 0.3, 0.8)  # min_x, max_x, min_y, max_y: columns 10-37, rows 5-14 up


def region_scene(crop=None):
    """passes_scene with the Render Region on (crop: Crop to Render Region), or off (None)."""
    scene = passes_scene()
    if crop is not None:
        r = scene.render
        r.use_border, r.use_crop_to_border = True, crop
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = REGION_BORDER
    return scene


def animated_scene():
    """Frames 1-3: the cube and the camera keyframed at every frame (see the constants)."""
    s = _scenes()
    scene = s.reset()
    scale, width, height = ANIMATION_VIEW
    s.set_resolution(width, height)
    scene.frame_start, scene.frame_end = FRAMES[0], FRAMES[-1]
    s.add_plane(size=8.0, material=s.diffuse_material("Floor", FLOOR_ALBEDO), name="Floor")
    bpy.ops.mesh.primitive_cube_add(size=CUBE_SIZE, location=(CUBE_X[0], 0.0, CUBE_SIZE / 2))
    cube = bpy.context.active_object
    cube.name = "Cube"
    cube.data.materials.append(s.diffuse_material("Red", CUBE_ALBEDO))
    _sun_straight_down()
    camera = s.add_camera(location=(CAMERA_X[0], 0.0, 5.0), look_at=(CAMERA_X[0], 0.0, 0.0),
                          ortho_scale=scale)
    for frame, cube_x, camera_x in zip(FRAMES, CUBE_X, CAMERA_X):
        cube.location.x = cube_x
        cube.keyframe_insert("location", frame=frame)
        camera.location.x = camera_x
        camera.keyframe_insert("location", frame=frame)
    scene.frame_set(FRAMES[0])
    return scene


def main(argv):
    """``-- NAME OUT.blend``: build scene NAME and save it (Blender's own arguments before --)."""
    name, out = argv[argv.index("--") + 1:][:2]
    builders = {"passes_scene": passes_scene, "animated_scene": animated_scene,
                "region_whole": region_scene, "region_crop": lambda: region_scene(True),
                "region_in_place": lambda: region_scene(False)}
    builders[name]()
    bpy.ops.wm.save_as_mainfile(filepath=str(pathlib.Path(out).resolve()))


if __name__ == "__main__":
    main(sys.argv)
