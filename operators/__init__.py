"""Blender operators and the ``smbs_bake`` command-line command.

Each operator module keeps its classes in ``classes``.
"""
import bpy

from . import bake, cli, compare, frames, kernels

classes = (*bake.classes, *frames.classes, *compare.classes, *kernels.classes)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    cli.register()


def unregister():
    bake.cancel_all()
    cli.unregister()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
