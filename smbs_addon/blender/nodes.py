"""Reading Cycles' node trees (materials', lights' and the world's): following a link through
reroutes, an input's constant value, the output node Cycles renders from and the shader on its
Surface, an image's linear pixels. Anything the export cannot represent raises ``Unsupported``,
its text saying why (the caller warns and falls back)."""
from __future__ import annotations

import bpy
import numpy as np

_OLD_NODES_FLAG = bpy.app.version < (5, 0, 0)  # use_nodes is deprecated (always on) in 5.0
_LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec.709 weights (colour -> float socket)


class Unsupported(Exception):
    """A material (or world/light node setup) we cannot represent; the text says why."""


def uses_nodes(idblock) -> bool:
    return bool(getattr(idblock, "use_nodes", True)) if _OLD_NODES_FLAG else True


def follow(socket):
    """The (node, output socket) feeding an input socket, through reroutes; None if unlinked."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        links = [lk for lk in socket.links if lk.is_valid and not lk.is_muted]
        if not links:
            return None
        node, out = links[0].from_node, links[0].from_socket
        if node.type == "REROUTE":
            socket = node.inputs[0]
            seen += 1
            continue
        return node, out
    return None


def constant_or(node, name, default):
    """constant of an input a node may lack (older or newer Blender): default where it has none."""
    return constant(node, name) if node.inputs.get(name) is not None else default


def constant(node, name):
    """The constant value of an input socket: its default, or an RGB/Value node feeding it.

    Returns a float or an (3,) array depending on the socket type. Raises Unsupported
    naming the socket if it is driven by anything else (a texture, a math node, ...).
    """
    sock = node.inputs.get(name)
    if sock is None:
        raise Unsupported(f"node '{node.name}' has no input '{name}'")
    want_color = sock.type in ("RGBA", "VECTOR")
    src = follow(sock)
    if src is None:
        val = sock.default_value
    else:
        snode, sout = src
        if snode.type in ("RGB", "VALUE") and not snode.mute:
            val = sout.default_value
        else:
            raise Unsupported(f"input '{name}' of node '{node.name}' is driven by node "
                               f"'{snode.name}' (a constant is needed)")
    try:
        arr = np.array(val[:], float)
    except TypeError:
        arr = np.array(float(val))
    if want_color:
        return np.broadcast_to(arr, (3,)).astype(float) if arr.ndim == 0 else arr[:3].copy()
    if arr.ndim == 0:
        return float(arr)
    return float(np.dot(arr[:3], _LUMA))


def is_linked(node, name) -> bool:
    sock = node.inputs.get(name)
    return sock is not None and follow(sock) is not None


def output_node(tree, out_type):
    """The output node Cycles renders from (None if there is none)."""
    out = None
    if hasattr(tree, "get_output_node"):
        try:
            out = tree.get_output_node("CYCLES")
        except (TypeError, RuntimeError):
            out = None
    if out is None:
        outs = [n for n in tree.nodes if n.type == out_type]
        outs.sort(key=lambda n: (not n.is_active_output, getattr(n, "target", "ALL") == "EEVEE"))
        out = outs[0] if outs else None
    return out


def shader_node(tree, out_type):
    """The shader node linked to the Surface of the active output, through simple cases."""
    out = output_node(tree, out_type)
    if out is None:
        raise Unsupported("node tree has no output node")
    src = follow(out.inputs["Surface"])
    if src is None:
        return None
    node = src[0]
    for _ in range(64):
        if node.mute:
            raise Unsupported(f"node '{node.name}' is muted")
        if node.type == "MIX_SHADER" and not is_linked(node, "Factor"):
            fac = float(node.inputs[0].default_value)
            if fac <= 0.0 or fac >= 1.0:
                nxt = follow(node.inputs[1 if fac <= 0.0 else 2])
                if nxt is None:
                    return None
                node = nxt[0]
                continue
        return node
    raise Unsupported("node tree is too deep")


def image_linear(img, most, read=True):
    """An image's linear RGB (H, W, 3) float32, rows from the bottom up (Cycles reads an 8-bit sRGB
    image through the sRGB curve; float images and the other colour spaces are taken as linear),
    or None: no image, none loaded (a missing file), or one of more than `most` pixels (reading it
    would cost seconds and GBs). read False: an empty (0, 0, 3) array where it could be read."""
    if img is None:
        return None
    try:
        w, h = (int(x) for x in img.size)
        channels = int(img.channels)
    except (AttributeError, RuntimeError, ValueError):
        return None
    if not 0 < w * h <= most or channels < 3:
        return None
    if not read:
        return np.zeros((0, 0, 3), np.float32)
    px = np.empty(w * h * channels, np.float32)
    img.pixels.foreach_get(px)
    rgb = px.reshape(h, w, channels)[:, :, :3]
    if not img.is_float and img.colorspace_settings.name == "sRGB":
        rgb = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4).astype(np.float32)
    return np.ascontiguousarray(rgb)
