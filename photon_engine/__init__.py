"""The Blender side of Photon Map: the only package that imports ``bpy``.

Ranked modules (a lower one never imports a higher one):
properties -> export -> render -> engine -> ui; cli drives it all headless. overlay (the
viewport photon display) imports only bpy, so any of them may import it.

This file is also imported as the top-level package ``photon_engine`` by
``python -m photon_engine`` (see ``__main__.py``), so it must not import ``bpy``, ``core``
or anything above it at module level: everything happens inside ``register()``.
"""


def register():
    import bpy
    from . import engine, overlay, properties, ui

    for cls in properties.classes:
        bpy.utils.register_class(cls)
    bpy.utils.register_class(engine.PhotonMapRenderEngine)
    ui.register()
    overlay.register()


def unregister():
    import bpy
    from . import engine, overlay, properties, ui

    overlay.unregister()
    ui.unregister()
    bpy.utils.unregister_class(engine.PhotonMapRenderEngine)
    for cls in reversed(properties.classes):
        bpy.utils.unregister_class(cls)
