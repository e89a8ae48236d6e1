"""Shared fixtures. The repository root is the extension package; tests import it as
``smbs_caustics``, the way Blender imports it as ``bl_ext.<repo>.smbs_caustics``."""
import importlib

import pytest

from testkit.extension import load_extension


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


@pytest.fixture
def composite(empty_bpy):
    """The extension's blender/composite.py (the caustic layer in the compositor), in a fresh session."""
    return importlib.import_module(load_extension().__name__ + ".smbs_addon.blender.composite")
