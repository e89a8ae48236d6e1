"""Blender operators. Each module keeps its classes in ``classes``."""
import bpy

from . import bake

classes = (*bake.classes,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
