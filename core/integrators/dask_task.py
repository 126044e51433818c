"""The one function a Dask worker is sent (pickled by value, so a worker needs no package
named like the client's: Blender's ``bl_ext.user_default.photon_map.core`` and a plain
checkout's ``core`` both work). It finds the core on the worker and hands it the task.
Keep it free of module-level state and imports: everything it needs is in its arguments."""


def run_block(core_names, root, scene_payload, settings_values, token, start, stop):
    """Render passes [start, stop) on this worker; returns (start, stop, radiance, stats)
    as plain objects (core.integrators.distributed.render_block_on_worker)."""
    import importlib
    import os
    import sys

    module, tried = None, []
    for attempt in (0, 1):
        for name in core_names:
            try:
                module = importlib.import_module(name + ".integrators.distributed")
                break
            except ImportError as error:
                tried.append(f"{name} ({error})")
        if module is not None or attempt or not root or not os.path.isdir(root):
            break
        sys.path.insert(0, root)  # the client's checkout, when the worker can see it
    if module is None:
        raise ImportError("no Photon Map core on this Dask worker; tried " + ", ".join(tried)
                          + ": put the directory holding core/ on the worker's PYTHONPATH "
                            "(docs/farm.md)")
    return module.render_block_on_worker(scene_payload, settings_values, token, start, stop)
