"""Photon Map: a photon-mapping render engine for Blender (the extension root).

Kept tiny and lazy on purpose: pytest and the headless CLI import this file without
Blender, so nothing here imports ``bpy``; ``register()`` pulls in the Blender side.
Blender 4.2+ reads the metadata from ``blender_manifest.toml``; ``bl_info`` lets older
Blenders load the same folder as a legacy add-on (tested with Debian's Blender 3.4,
tests/blender/test_blender_exe.py).
"""

bl_info = {
    "name": "Photon Map",
    "author": "Photon Map developers",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "Properties > Render > Render Engine > Photon Map",
    "description": "Photon mapping render engine with light units that match Cycles",
    "category": "Render",
}


def register():
    from . import photon_engine
    photon_engine.register()


def unregister():
    from . import photon_engine
    photon_engine.unregister()
