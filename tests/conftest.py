"""Shared fixtures. The repository root is the extension package; tests import it as
``smbs_caustics``, the way Blender imports it as ``bl_ext.<repo>.smbs_caustics``."""
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
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


@pytest.fixture
def empty_bpy():
    """A factory-fresh, empty Blender session."""
    bpy = pytest.importorskip("bpy")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy


@pytest.fixture
def addon():
    """The extension package, registered for the test and unregistered after it."""
    pytest.importorskip("bpy")
    module = load_extension()
    module.register()
    yield module
    module.unregister()
