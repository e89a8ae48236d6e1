"""The repository root imported as the extension package ``smbs_caustics``, the way Blender imports
it as ``bl_ext.<repo>.smbs_caustics`` (no bpy needed to import this module)."""
import importlib.util
import sys

from . import ROOT

EXTENSION = "smbs_caustics"


def load_extension():
    """Import the repository root as the package ``smbs_caustics`` (once)."""
    if EXTENSION not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            EXTENSION, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
        module = importlib.util.module_from_spec(spec)
        sys.modules[EXTENSION] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[EXTENSION]
            raise
    return sys.modules[EXTENSION]
