"""Who sees whom: an object's, a light's or the world's Ray Visibility as S.RAY_* bits, Light and
Shadow Linking (the objects an emitter lights, those that shadow it), and the Cycles object settings
the layer does not read (a holdout, a shadow catcher), warned about."""
from __future__ import annotations

from ..scene import arrays as S


_RAYS = (("visible_camera", "camera", S.RAY_CAMERA), ("visible_diffuse", "diffuse", S.RAY_DIFFUSE),
         ("visible_glossy", "glossy", S.RAY_GLOSSY), ("visible_transmission", "transmission", S.RAY_TRANSMISSION),
         ("visible_shadow", "shadow", S.RAY_SHADOW))


def ray_visibility(ob, prefix="visible_") -> int:
    """An object's or a light's Ray Visibility (Object > Visibility) as S.RAY_* bits (prefix "": the
    world's, World > Settings; a setting it lacks counts as on)."""
    return sum(bit for attr, _, bit in _RAYS if getattr(ob, prefix + attr.removeprefix("visible_"), True))


def _link_states(collection, state=None, out=None) -> dict:
    """The objects of a Light Linking collection, each with its Include / Exclude state, as Blender
    resolves them (its depsgraph's light linking cache): an object inside a child collection takes
    that child's state (the first level's, however deep it lies), the collection's own objects theirs;
    the later one counts where an object is met twice (children first, then objects). Keys: original
    objects (an instance is its object's)."""
    out = {} if out is None else out
    for child, link in zip(collection.children, collection.collection_children):
        _link_states(child, link.light_linking.link_state if state is None else state, out)
    for ob, link in zip(collection.objects, collection.collection_objects):
        out[ob.original if getattr(ob, "original", None) is not None else ob] = \
            link.light_linking.link_state if state is None else state
    return out


def linked_objects(ob, which="receiver_collection"):
    """The original objects emitter ob (a light's or an emissive mesh's object) lights by its Light
    Linking's receiver collection (which="blocker_collection": that shadow it, Shadow Linking), as a
    predicate on an original object; None: every object (no collection). Blender, for both: an object
    set to Include is in; once any is, only those; else every object but those set to Exclude."""
    c = getattr(getattr(ob, "light_linking", None), which, None)
    if c is None:
        return None
    states = _link_states(c)
    if any(v == "INCLUDE" for v in states.values()):
        return lambda o: states.get(o) == "INCLUDE"
    return lambda o: states.get(o) != "EXCLUDE"


class LinkedNames:
    """The names of the meshes an emitter (a light's or an emissive mesh's original object) lights by
    its Light Linking (which="blocker_collection": those that shadow it, Shadow Linking); None: every
    object. Memoised per (emitter, which): an emitter's instances share them."""

    def __init__(self, named):
        """named: (original object, mesh name) for every mesh in the scene, in order."""
        self.names_of = {}
        for orig, name in named:
            self.names_of.setdefault(orig, []).append(name)
        self.memo = {}

    def __call__(self, emitter, which="receiver_collection"):
        if (emitter, which) not in self.memo:
            member = linked_objects(emitter, which)
            self.memo[emitter, which] = None if member is None else \
                [nm for o, names in self.names_of.items() if member(o) for nm in names]
        return self.memo[emitter, which]


def say_visibility(ob, warn):
    """Warn about an object's Cycles settings the layer does not read: a holdout, a shadow catcher (the
    layer's caustic on it is added to the render like any receiver's). (Its Ray Visibility is read:
    ray_visibility.)"""
    if getattr(ob, "is_holdout", False):
        warn(f"object '{ob.name}': a holdout; the layer treats it as its material says")
    if getattr(ob, "is_shadow_catcher", False):
        warn(f"object '{ob.name}': a shadow catcher; the caustic on it is composited like any receiver's, "
             f"not into Cycles' shadow catcher pass")
