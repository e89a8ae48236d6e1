"""SMBS Caustics: the Blender extension entry point.

Blender imports this folder as a package (``bl_ext.<repo>.smbs_caustics``), so
every import here is relative. Registration runs in one fixed order, properties
first (operators and panels read them), panels last (they draw operators), and
``unregister()`` undoes it in reverse. The render core (``smbs_addon``) is not
imported here: operators import it inside ``execute()`` so Blender starts fast.
"""
from . import operators
from .ui import panels, properties

# The order matters; unregister walks it backwards.
_MODULES = (properties, operators, panels)


def register():
    done = []
    try:
        for module in _MODULES:
            module.register()
            done.append(module)
    except Exception:
        # Leave Blender as we found it when a later step fails.
        for module in reversed(done):
            module.unregister()
        raise


def unregister():
    for module in reversed(_MODULES):
        module.unregister()
