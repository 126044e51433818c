"""Differences between the Blender versions Photon Map supports, in one place.

Supported: Blender 4.2 LTS to 5.2 LTS as an extension (CPython 3.11 up to 5.0, 3.13 from
5.1), and Debian's 3.4 as a legacy add-on. Everything that reads or writes Blender data
asks this module instead of testing ``bpy.app.version`` itself:

- Node trees. An ID's ``node_tree`` is used only when ``use_nodes`` is on, until Blender
  deprecates ``use_nodes`` for that ID type (materials and worlds in 5.0, lights by 5.2:
  they then always use their tree, and new ones come with one; removal in 6.0). RNA says
  which (``is_deprecated``), so ``use_nodes`` is neither read nor written once deprecated.
- Socket names. Principled BSDF v2 (4.0) renamed its inputs ("Emission" -> "Emission
  Color", "Transmission" -> "Transmission Weight", "Specular" -> "Specular IOR Level",
  "Subsurface" -> "Subsurface Weight", "Clearcoat" -> "Coat Weight", "Sheen" -> "Sheen
  Weight"); 4.x+ mix and math nodes say "Factor" where 3.x said "Fac". ``input_socket``
  finds an input by today's name or any older one. 3.x's Principled (v1) has scalar
  "Specular Tint" and "Sheen Tint" (a blend from white to the base colour's hue) where 4.0
  has colours: the node reader turns them into colours (export_nodes.NodeReader.tint);
  3.x's distributions include "SHARP" (roughness 0, export_shaders).
- 5.2's Principled BSDF has a boolean "Thin Wall" input (``thin_wall``), absent before.
  Otherwise the shader nodes' input names are the same from 4.2 to 5.2 (checked input by
  input in bpy 4.2.23 and 5.2.3); newer inputs and nodes: Principled "Diffuse Roughness"
  and the Metallic BSDF (4.3), Glass "Thin Film Thickness" / "Thin Film IOR" (after 4.2).
  ``input_socket`` returns None for an input the running Blender lacks, and the exporter
  reads it as the closure contract's default. It also returns None for an input Blender
  hides (5.2: the Metallic BSDF's IOR / Extinction under F82, Base Color / Edge Tint
  under Physical Conductor), which Cycles does not read either.
- The Bump node reads its height one whole ray differential away up to 4.3, 0.1 of one
  in 4.4, and its "Filter Width" input (default 0.1) from 4.5 (``BUMP_FILTER_WIDTH``).
- EEVEE's engine id is "BLENDER_EEVEE_NEXT" in 4.2 to 4.5 (``EEVEE``).
- The compositor: from 5.0 a ``CompositorNodeTree`` node group in
  ``scene.compositing_node_group`` whose Group Output "Image" is the result; before, the
  scene's own ``node_tree`` with ``use_nodes`` and a Composite node (``denoise_compositor``).
- bpy 4.2 as a Python module crashes (SIGSEGV) while the interpreter shuts down once any
  registered property has an ``update`` callback, even after unregistering; the headless
  CLI leaves through ``exit_process`` (os._exit after flushing) there.
"""

from __future__ import annotations

import bpy

VERSION: tuple[int, int, int] = tuple(bpy.app.version)
"""The running Blender's (major, minor, patch)."""


EEVEE = 'BLENDER_EEVEE_NEXT' if (4, 2, 0) <= VERSION < (5, 0, 0) else 'BLENDER_EEVEE'
"""EEVEE's engine id: 4.2 to 4.5 call the rewritten EEVEE "BLENDER_EEVEE_NEXT"."""


CRASHES_AT_EXIT = VERSION < (5, 0, 0)
"""bpy 4.x's module does not survive its own teardown at process exit: 4.2 segfaults once
properties with update callbacks were registered (measured with bpy 4.2.23), and 4.5 can
hang for ever in a static destructor (bpy 4.5.15: ``GlobalState::~GlobalState`` destroys the
condition variable its ``delayed_close_thread`` still waits on; seen in gdb on a CLI run that
had already printed its error and called exit(1)). 5.0.1, 5.1.2 and 5.2.3 exit cleanly."""


VORONOI_PCG_HASH = VERSION >= (5, 0, 0)
"""Cycles' Voronoi places its feature points with the PCG integer hashes from Blender 5.0
(Cycles commit c24e0712c, June 2025); 4.x hashed the cells' float coordinates with lookup3
(the shader program's Voronoi flag 2)."""


BUMP_FILTER_WIDTH = 1.0 if VERSION < (4, 4, 0) else 0.1
"""The Bump node's offset w (in pixels of the ray differential: the height is read at
P + w dPdx and P + w dPdy) where the node has no "Filter Width" input (before 4.5): a
whole differential up to 4.3, 0.1 in 4.4 (Cycles commit d132f2a13, Jan 2025, "reduce ray
differentials size for bump mapping": BUMP_DX 0.1); 4.5 made it the input, default 0.1
(commit 9f427b00d)."""


def exit_process(code: int):
    """End the process with ``code``: ``sys.exit``, or where bpy crashes at shutdown
    (CRASHES_AT_EXIT) flush the standard streams and ``os._exit`` past the teardown."""
    import os
    import sys

    if CRASHES_AT_EXIT:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def always_nodes(idblock) -> bool:
    """True when ``idblock``'s type always renders with its node tree: its ``use_nodes``
    is deprecated (materials, worlds from 5.0; lights from 5.2) or gone."""
    prop = type(idblock).bl_rna.properties.get("use_nodes")
    return prop is None or bool(getattr(prop, "is_deprecated", False))

# Today's input name -> names the same input had in older Blender versions.
SOCKET_ALIASES: dict[str, tuple[str, ...]] = {
    "Emission Color": ("Emission",),
    "Transmission Weight": ("Transmission",),
    "Specular IOR Level": ("Specular",),
    "Subsurface Weight": ("Subsurface",),
    "Coat Weight": ("Clearcoat",),
    "Coat Roughness": ("Clearcoat Roughness",),
    "Sheen Weight": ("Sheen",),
    "Factor": ("Fac",),
}


def node_tree(idblock):
    """The node tree Cycles would render ``idblock`` (material, world or light) with, or None.

    Always the tree once ``use_nodes`` is deprecated for its type (``always_nodes``);
    before that, only with ``use_nodes`` on.
    """
    tree = getattr(idblock, "node_tree", None)
    if tree is None or always_nodes(idblock):
        return tree
    return tree if getattr(idblock, "use_nodes", False) else None


def ensure_node_tree(idblock):
    """``idblock``'s node tree, switching ``use_nodes`` on only where a tree is not
    always used (never touching the deprecated setter in 5.x). Returns the tree."""
    if node_tree(idblock) is None:
        idblock.use_nodes = True
    return idblock.node_tree


def input_socket(node, *names):
    """The first input of ``node`` called one of ``names`` or an older name of one
    (SOCKET_ALIASES); None when it has none of them."""
    for name in names:
        for candidate in (name, *SOCKET_ALIASES.get(name, ())):
            sock = node.inputs.get(candidate)
            if sock is not None:
                return sock
    return None


def thin_wall(node) -> bool:
    """True when a Principled BSDF's "Thin Wall" input (5.2+) is switched on (unlinked)."""
    sock = node.inputs.get("Thin Wall")
    return bool(sock is not None and getattr(sock, "default_value", False))


DENOISE_TREE = "Photon Map Denoise"
"""Name of the compositor node group (5.0+) or marker node (4.x) denoise_compositor makes."""


DEFAULT_COMPOSITOR_NODES = frozenset({"CompositorNodeRLayers", "CompositorNodeComposite",
                                      "CompositorNodeViewer", "NodeReroute"})
"""What 4.x puts in a scene's new compositor tree (4.2: Render Layers -> Composite; 4.5 adds
a Reroute and a Viewer): a tree of only these is not the user's own compositor."""


def denoise_compositor(scene, on: bool) -> str:
    """Set up (``on``) or remove the compositor that denoises a Photon Map render:
    Render Layers (Image, Denoising Albedo, Denoising Normal) -> Denoise (OpenImageDenoise,
    shipped with Blender) -> the compositor's output, with ``use_compositing`` on.

    Leaves a scene's own compositor alone and says so: returns "" when done, else a
    message for the user.
    """
    scene.render.use_compositing = True if on else scene.render.use_compositing
    if hasattr(scene, "compositing_node_group"):  # 5.0+
        current = scene.compositing_node_group
        ours = current is not None and current.name.startswith(DENOISE_TREE)
        if not on:
            if ours:
                scene.compositing_node_group = None
                bpy.data.node_groups.remove(current)
            return ""
        if current is not None:
            return "" if ours else (f"scene '{scene.name}' has its own compositor "
                                    f"('{current.name}'): add a Denoise node to it by hand")
        tree = bpy.data.node_groups.new(DENOISE_TREE, "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        out = tree.nodes.new("NodeGroupOutput")
        scene.compositing_node_group = tree
    else:  # 4.x: the scene's own tree
        if not on:
            tree = scene.node_tree
            if tree is not None and tree.nodes.get(DENOISE_TREE) is not None:
                tree.nodes.clear()
                scene.use_nodes = False
            return ""
        scene.use_nodes = True
        tree = scene.node_tree
        if tree.nodes.get(DENOISE_TREE) is not None:
            return ""
        if any(n.bl_idname not in DEFAULT_COMPOSITOR_NODES for n in tree.nodes):
            return (f"scene '{scene.name}' has its own compositor: add a Denoise node to it "
                    f"by hand")
        tree.nodes.clear()
        out = tree.nodes.new("CompositorNodeComposite")
    layers = tree.nodes.new("CompositorNodeRLayers")
    layers.scene = scene
    denoise = tree.nodes.new("CompositorNodeDenoise")
    denoise.name = DENOISE_TREE
    links = tree.links
    links.new(layers.outputs["Image"], denoise.inputs["Image"])
    for name in ("Albedo", "Normal"):
        source = layers.outputs.get(f"Denoising {name}")
        if source is not None:
            links.new(source, denoise.inputs[name])
    links.new(denoise.outputs["Image"], out.inputs["Image"])
    return ""
