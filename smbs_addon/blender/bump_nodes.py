"""Which mirrors and glass have a bumped Normal the export bakes (scene/bump.py), and how: one Bump
node's Height (the gradient taken by us) or a driven Normal's vector as it is (a Normal Map, say),
and whether Cycles' bump flips with the surface seen from behind."""
from __future__ import annotations

from .nodes import follow, is_linked, output_node, uses_nodes


# mirrors and glass whose Normal may take a Bump node (bump.py)
BUMPABLE = ("BSDF_GLASS", "BSDF_REFRACTION", "BSDF_GLOSSY", "BSDF_ANISOTROPIC", "BSDF_METALLIC")


def _bump_node(node):
    """The Bump node on a BSDF's Normal that the export bakes (bump.py): one Bump node whose Height
    is linked and whose Normal, Strength and Distance are not; None otherwise."""
    sock = node.inputs.get("Normal")
    src = follow(sock) if sock is not None else None
    if src is None:
        return None
    b = src[0]
    if b.type != "BUMP" or b.mute or not is_linked(b, "Height"):
        return None
    if any(is_linked(b, name) for name in ("Normal", "Strength", "Distance")):
        return None
    return b


def _upstream(socket, limit=256):
    """The nodes feeding an input socket, through every link upstream (None past `limit` nodes)."""
    seen, todo = {}, [socket]
    while todo:
        src = follow(todo.pop())
        if src is None or src[0].name in seen:
            continue
        seen[src[0].name] = src[0]
        if len(seen) > limit:
            return None
        todo.extend(src[0].inputs)
    return list(seen.values())


def normal_source(node):
    """How the export bakes a mirror's or glass's driven Normal (bump.py): ("height", the Bump node)
    where it is one Bump node (its Height baked, the gradient taken by us: a bake's shading points have
    no ray differentials, so Cycles' own Bump would leave the normal unbent there); ("vector", None)
    where no Bump node lies upstream (a Normal Map, say: its output baked as it is); None otherwise
    (or where the Normal is not driven, or reads a node group or the mesh's attributes: _UNBAKED)."""
    b = _bump_node(node)
    if b is not None:
        nodes = _upstream(b.inputs["Height"])
        return None if nodes is None or any(n.type in _UNBAKED for n in nodes) else ("height", b)
    sock = node.inputs.get("Normal")
    if sock is None or follow(sock) is None:
        return None
    nodes = _upstream(sock)
    if nodes is None or any(n.type in _UNBAKED + ("BUMP",) or n.mute for n in nodes):
        return None
    return "vector", None


# nodes whose value the copy of the mesh the export bakes on cannot give: a node group (what it
# holds is not read), the mesh's own attributes (the copy has only positions and the UV map)
_UNBAKED = ("GROUP", "ATTRIBUTE", "VERTEX_COLOR")


# where a Bump node's Height is read (Cycles, checked by renders of a sheet met from above and
# below): a texture coordinate of the position (Object, Camera, Window, Reflection, Normal, the
# Geometry node's Position) is offset in the frame of the flipped normal, so seen from behind the
# bump bends the other way; an attribute (Generated, UV, a UV Map or Attribute node, a texture's
# own default Vector) is offset with the surface, and the bump flips with it
_POSITION_COORDS = {("TEX_COORD", "Object"), ("TEX_COORD", "Camera"), ("TEX_COORD", "Window"),
                    ("TEX_COORD", "Reflection"), ("TEX_COORD", "Normal"), ("NEW_GEOMETRY", "Position"),
                    ("NEW_GEOMETRY", "Normal"), ("NEW_GEOMETRY", "True Normal"), ("NEW_GEOMETRY", "Incoming")}


def _bump_flips(tree, bump_node) -> bool:
    """Does Cycles' Bump node bend the normal with the surface when met from behind (the Height
    read through attributes only), or the other way (through the position: bump.bend's normals
    from behind)? Where both feed the Height, the position's way."""
    nodes = _upstream(bump_node.inputs["Height"]) or []
    names = {n.name for n in nodes}
    for lk in tree.links:
        if lk.is_valid and not lk.is_muted and lk.to_node.name in names | {bump_node.name} \
                and (lk.from_node.type, lk.from_socket.name) in _POSITION_COORDS:
            return False
    return True


def bump_of(mat):
    """How a material whose surface is one mirror or glass BSDF with a driven Normal is baked:
    ("height", Bump node name, Distance (negated where the node inverts), Strength, whether the bump
    flips with the surface seen from behind: _bump_flips) or ("vector", BSDF node name, 0, 0, True);
    None where the export cannot bake it (see normal_source)."""
    tree = mat.node_tree
    if tree is None or not uses_nodes(mat):
        return None
    out = output_node(tree, "OUTPUT_MATERIAL")
    src = follow(out.inputs["Surface"]) if out is not None else None
    if src is None or src[0].mute or src[0].type not in BUMPABLE + ("BSDF_PRINCIPLED",):
        return None
    how = normal_source(src[0])
    if how is None:
        return None
    if how[0] == "vector":
        return "vector", src[0].name, 0.0, 0.0, True
    b = how[1]
    dist = float(b.inputs["Distance"].default_value)
    return ("height", b.name, -dist if b.invert else dist, float(b.inputs["Strength"].default_value),
            _bump_flips(tree, b))
