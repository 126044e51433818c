"""``python -m photon_engine ...`` from the repository root.

The package uses relative imports (``from ..core import ...``), which only resolve when
the repository root is itself a package, as it is once Blender installs the extension
(``bl_ext.user_default.photon_map``). So this bootstrap loads the root as the package
``photon_map`` and runs ``photon_map.photon_engine.cli``.
"""

import importlib
import importlib.util
import pathlib
import sys


def load_extension_package(name="photon_map"):
    """Import the repository root (this file's grandparent) as the package ``name``."""
    if name in sys.modules:
        return sys.modules[name]
    root = pathlib.Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location(
        name, root / "__init__.py", submodule_search_locations=[str(root)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


if __name__ == "__main__":
    load_extension_package()
    cli = importlib.import_module("photon_map.photon_engine.cli")
    code = cli.main(sys.argv[1:])
    if "bpy" in sys.modules:  # leaves past bpy 4.2's crash at interpreter shutdown
        importlib.import_module("photon_map.photon_engine.compat").exit_process(code)
    sys.exit(code)
