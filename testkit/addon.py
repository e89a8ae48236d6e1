"""Looking at what the add-on did in Blender: its images, its compositor nodes, its panels drawn, its
reports, the scene state a bake may change (needs the bpy module)."""
import time
from types import SimpleNamespace

import bpy
import numpy as np

LAYER = "SMBS Caustics"  # the caustic layer's image
ALBEDO = "SMBS Caustics per Albedo"  # the per-albedo image beside it (textured receivers)


def layer_images():
    """The images of ours: the caustic layer and those named after it."""
    return [im for im in bpy.data.images if im.name.startswith(LAYER)]


def layer_image(h=4, w=6, value=1.0):
    """A caustic layer (H,W,3) whose top row is red and bottom row blue: orientation shows."""
    img = np.zeros((h, w, 3), np.float32)
    img[0] = (value, 0.0, 0.0)  # top row red
    img[-1] = (0.0, 0.0, value)  # bottom row blue
    return img


def image_pixels(image):
    """An Image datablock's pixels (H,W,4), bottom row first as Blender keeps them."""
    w, h = image.size
    buf = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(buf)
    return buf.reshape(h, w, 4)


def our_nodes(tree, role):
    """The compositor nodes of ours (composite.TAG) of one role."""
    return [n for n in tree.nodes if n.get("smbs_caustics") == role]


def users_compositor(scene):
    """A compositor of the user's own, Render Layers -> Blur -> Group Output, as the scene's:
    (tree, render layers, blur, output)."""
    tree = bpy.data.node_groups.new("Mine", "CompositorNodeTree")
    tree.interface.new_socket(name="Image", in_out='OUTPUT', socket_type="NodeSocketColor")
    rl = tree.nodes.new("CompositorNodeRLayers")
    blur = tree.nodes.new("CompositorNodeBlur")
    out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(rl.outputs["Image"], blur.inputs["Image"])
    tree.links.new(blur.outputs["Image"], out.inputs[0])
    scene.compositing_node_group = tree
    return tree, rl, blur, out


def scene_state(scene):
    """Everything a bake may change."""
    s = scene.smbs_caustics
    return (len(bpy.data.images), len(bpy.data.node_groups), scene.compositing_node_group,
            s.last_stats, s.cycles_note, s.cycles_kept_out,
            scene.cycles.caustics_reflective, scene.cycles.caustics_refractive)


class Reports(list):
    """The operator's report(level, message) calls, kept."""

    def __call__(self, level, message):
        self.append((next(iter(level)), message))

    def of(self, level):
        return [m for lv, m in self if lv == level]


def run_to_end(bake, timeout):
    """Timer events until the modal job ends: (its result, the status texts it showed)."""
    texts = set()
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        result = bake.step(bpy.context, 'TIMER')
        if result != {'PASS_THROUGH'}:
            return result, texts
        texts.add(bake.text)
        time.sleep(0.01)
    return None, texts


# ------------------------------------------------------------------------- panels
_ICONS = None


def _valid_icon(icon):
    global _ICONS
    if _ICONS is None:
        _ICONS = set(bpy.types.UILayout.bl_rna.functions["prop"].parameters["icon"].enum_items.keys())
    return icon in _ICONS


class Layout:
    """Stands in for UILayout when calling a panel's draw(): checks every prop(), operator(),
    icon and list it is given."""

    def __init__(self, drawn):
        self.drawn = drawn

    def _sub(self, *args, **kwargs):
        return Layout(self.drawn)

    column = row = split = box = _sub

    def _icon(self, kwargs):
        assert _valid_icon(kwargs.get("icon", "NONE")), f"no icon {kwargs['icon']!r}"

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, f"no property {name!r}"
        self._icon(kwargs)
        self.drawn.append(name)

    def operator(self, idname, **kwargs):
        module, name = idname.split(".")
        assert name in dir(getattr(bpy.ops, module)), f"no operator {idname!r}"
        self._icon(kwargs)
        self.drawn.append(idname)

    def label(self, text="", **kwargs):
        self._icon(kwargs)
        self.drawn.append(text)

    def progress(self, factor=0.0, type='BAR', text=""):
        assert 0.0 <= factor <= 1.0
        self.drawn.append(("progress", text))

    def template_list(self, list_type, list_id, dataptr, propname, active_dataptr, active_propname,
                      **kwargs):
        assert hasattr(bpy.types, list_type), f"no UIList {list_type!r}"
        assert propname in dataptr.bl_rna.properties
        assert active_propname in active_dataptr.bl_rna.properties
        self.drawn.append(list_type)


def draw_all(addon, scene, drawn):
    """Every panel of the extension drawn into a Layout that records into drawn: the context it drew in."""
    context = SimpleNamespace(scene=scene, region=None, preferences=bpy.context.preferences)
    for panel in addon.ui.panels.classes:
        if issubclass(panel, bpy.types.Panel):
            panel.draw(SimpleNamespace(layout=Layout(drawn)), context)
    return context
