"""Render pass names: the keys of ``RenderOutput.passes`` and their names in Blender.

PASSES lists the terms summed into "combined", in summation order (the seed lecture's
split: emission, environment, direct, specular, caustics, indirect diffuse). BLENDER_PASS_NAMES maps our keys to the pass names
Blender 5 uses in its render results and EXR files ("Emission" and "Environment" are
Blender's own passes; the others are registered by the engine).
"""

PASSES = ("emission", "environment", "direct", "specular", "caustics", "indirect")

BLENDER_PASS_NAMES = {
    "combined": "Combined",
    "emission": "Emission",
    "environment": "Environment",
    "direct": "Direct",
    "specular": "Specular",
    "caustics": "Caustics",
    "indirect": "Indirect",
}
