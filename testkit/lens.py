"""A biconvex lens mesh (vertices and faces, no bpy): the conformance scenes' lens and the random
distractor scenes' (testkit/distractors.py) are the same mesh."""
from __future__ import annotations

import math


def biconvex_lens(radius_of_curvature, aperture, rim, segments=96, rings=24):
    """A biconvex lens: two spherical caps joined by a thin cylindrical rim band
    (so that smooth shading does not bend the caps' normals at their edge)."""
    R, a = radius_of_curvature, aperture
    sag = R - math.sqrt(R * R - a * a)
    verts = [(0.0, 0.0, rim + sag)]
    for r in range(1, rings + 1):
        rr = a * r / rings
        z = rim + math.sqrt(R * R - rr * rr) - (R - sag)
        for s in range(segments):
            ph = 2 * math.pi * s / segments
            verts.append((rr * math.cos(ph), rr * math.sin(ph), z))
    top_rim = 1 + (rings - 1) * segments
    bottom_start = len(verts)
    for r in range(rings, 0, -1):
        rr = a * r / rings
        z = -(rim + math.sqrt(R * R - rr * rr) - (R - sag))
        for s in range(segments):
            ph = 2 * math.pi * s / segments
            verts.append((rr * math.cos(ph), rr * math.sin(ph), z))
    verts.append((0.0, 0.0, -(rim + sag)))
    faces = []
    for s in range(segments):  # top fan
        faces.append((0, 1 + s, 1 + (s + 1) % segments))
    for r in range(rings - 1):  # top rings
        a0, b0 = 1 + r * segments, 1 + (r + 1) * segments
        for s in range(segments):
            s1 = (s + 1) % segments
            faces.append((a0 + s, b0 + s, b0 + s1, a0 + s1))
    for s in range(segments):  # the rim band
        s1 = (s + 1) % segments
        faces.append((top_rim + s, bottom_start + s, bottom_start + s1, top_rim + s1))
    for r in range(rings - 1):  # bottom rings, outside in
        a0, b0 = bottom_start + r * segments, bottom_start + (r + 1) * segments
        for s in range(segments):
            s1 = (s + 1) % segments
            faces.append((a0 + s, b0 + s, b0 + s1, a0 + s1))
    last = len(verts) - 1
    base = bottom_start + (rings - 1) * segments
    for s in range(segments):  # bottom fan
        faces.append((base + (s + 1) % segments, base + s, last))
    return verts, faces
