"""The compiled shader program (docs/shading.md): its format (``program``), the per-point
inputs it reads (``inputs``), Cycles' node definitions as numba functions (``hash``,
``noise``, ``voronoi``,
``converters``, ``color``, ``textures``), and the kernel that runs a program over a batch
of hit points (``interpreter.evaluate``)."""
