"""Random builder scenes and distractors that cannot contribute to their caustic (issue 60), and the
issue's own scene (issue_lens_scene: a biconvex lens, not testkit.scenes.lens_scene's ball).

A scene is drawn from a seed (numpy's generator, so a seed is the same scene on every machine):
a floor, one or two casters (a glass ball, a biconvex lens, a tilted mirror, a metal ring, a glass
slab) near its middle, one or two lamps (area, point, spot, sun) aimed at them, sometimes a dim
world, and a camera looking at the casters from anywhere around them. Distractors are objects
and lights that no path of the scene's caustic can meet:

- ``sky_spot``: a spot above everything, aimed at the sky;
- ``up_area``: an area light above everything, facing up;
- ``far_glass``, ``far_mirror``: a glass ball (radius 0.3-0.6) or a level mirror beyond the
  floor's edge (40-80 m away), out of the frame and out of a sun's line (its shadow falls on nothing the camera sees),
  lit by the lamps;
- ``under_glass``: a glass ball under the floor (hidden from the lamps and the camera);
- ``hidden_glass``: a glass ball out of the frame whose Ray Visibility is off for diffuse rays;
- ``unlit_glass``: a glass ball out of every lamp's reach (behind an area light's plane, out of a
  spot's cone, 80-160 m away and above the lamps), where the lamps are area lights and spots
  (drawn from a stream of its own, so the other distractors are those of the same seed without).

A world lights every caster from every side, under the floor and beyond it too: with one, the
distractors are lights alone.

``build(recipe, distractors)`` makes the scene with the distractors put among the scene's own
objects and lights at the places the recipe drew (so every index after them moves), or without.
"""
from __future__ import annotations

import math

import numpy as np

from smbs_addon.scene import arrays as S
from smbs_addon.scene.builder import SceneBuilder, look_at
from smbs_addon.trace.camera import CameraModel
from testkit.lens import biconvex_lens

KINDS = ("sky_spot", "up_area", "far_glass", "far_mirror", "under_glass", "hidden_glass", "unlit_glass")
RES = (48, 36)


def lens_mesh(radius_of_curvature=1.2, aperture=0.5, rim=0.01, segments=96, rings=24, centre=(0.0, 0.0, 0.0)):
    """A biconvex lens (testkit/lens.biconvex_lens, the conformance scenes' too, each quad split into two triangles)
    as (vertices, triangles, smooth vertex normals: the faces' area-weighted mean, as Blender's
    smooth shading)."""
    verts, quads = biconvex_lens(radius_of_curvature, aperture, rim, segments, rings)
    faces = [t for f in quads for t in ([f] if len(f) == 3 else [(f[0], f[1], f[2]), (f[0], f[2], f[3])])]
    V, F = np.array(verts) + np.asarray(centre, float), np.array(faces)
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    N = np.zeros_like(V)
    for k in range(3):
        np.add.at(N, F[:, k], fn)
    return V, F, N / np.linalg.norm(N, axis=1, keepdims=True)


def issue_lens_scene(extra: bool, resolution=(160, 120), world=0.05, power=1000.0):
    """Issue 60's scene, as a new user builds it: a biconvex Glass BSDF lens (IOR 1.5) 1.6 m above a
    20 m floor under a 0.4 m area light at (0.3, -0.2, 6), Blender's default grey world (0.05, the
    export's first light); with extra, a spot at z = 9 aimed straight up and a glass ball of radius
    0.5 at (40, 40, 0.5), far outside the view and beyond the floor, lit by the area light. No
    Cycles caustic flags (a new user sets none)."""
    b = SceneBuilder("lens")
    if world > 0:
        b.world((world,) * 3)
    floor = b.material("Floor", "diffuse", color=(0.8,) * 3)
    glass = b.material("Glass", "dielectric", color=(1.0, 1.0, 1.0), ior=1.5)
    b.plane("Floor", (0, 0, 0), 20, floor)
    V, F, N = lens_mesh(centre=(0.0, 0.0, 1.6))
    b.mesh("Lens", V, F, glass, normals=N)
    b.light("Area", "AREA", location=(0.3, -0.2, 6.0), target=(0.3, -0.2, 0.0), power=power, size=0.4)
    if extra:
        b.light("SkySpot", "SPOT", location=(0.0, 0.0, 9.0), target=(0.0, 0.0, 20.0), power=1000.0)
        b.uv_sphere("FarGlass", (40.0, 40.0, 0.5), 0.5, glass)
    b.set_camera((0.0, -4.0, 3.2), (0.0, 0.0, 0.2), lens=40, resolution_x=resolution[0],
                 resolution_y=resolution[1])
    return b.build()


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def recipe(seed: int, kinds=None) -> dict:
    """A random scene and its distractors (1-3 of KINDS, or of kinds), drawn from seed."""
    rng = np.random.default_rng([60, int(seed)])
    r = {"seed": int(seed), "floor": _u(rng, 8.0, 20.0), "albedo": _u(rng, 0.4, 0.9), "casters": [], "lights": []}
    for i in range(int(rng.integers(1, 3))):
        kind = str(rng.choice(["ball", "lens", "mirror", "ring", "slab"]))
        r["casters"].append({"kind": kind, "name": f"C{i}", "xy": (_u(rng, -1.2, 1.2), _u(rng, -1.2, 1.2)),
                             "size": _u(rng, 0.3, 0.7), "z": _u(rng, 0.4, 1.6), "tilt": _u(rng, 20, 70),
                             "azimuth": _u(rng, 0, 360), "ior": _u(rng, 1.3, 1.8)})
    for i in range(int(rng.integers(1, 3))):
        kind = str(rng.choice(["AREA", "POINT", "SPOT", "SUN"]))
        az, el = math.radians(_u(rng, 0, 360)), math.radians(_u(rng, 40, 80))
        dist = _u(rng, 3.0, 6.0)
        loc = (dist * math.cos(el) * math.cos(az), dist * math.cos(el) * math.sin(az), dist * math.sin(el))
        r["lights"].append({"kind": kind, "name": f"L{i}", "loc": loc, "target": (_u(rng, -0.5, 0.5),
                                                                                 _u(rng, -0.5, 0.5), 0.3),
                            "power": _u(rng, 200, 1000) if kind != "SUN" else _u(rng, 2, 6),
                            "size": _u(rng, 0.2, 1.0), "radius": _u(rng, 0.02, 0.2),
                            "spot": math.radians(_u(rng, 40, 100)), "angle": math.radians(_u(rng, 0.5, 3))})
    r["world"] = _u(rng, 0.01, 0.1) if rng.random() < 0.3 else 0.0
    az, el = math.radians(_u(rng, 0, 360)), math.radians(_u(rng, 25, 60))
    dist = _u(rng, 4.0, 7.0)
    r["camera"] = {"loc": (dist * math.cos(el) * math.cos(az), dist * math.cos(el) * math.sin(az),
                           0.3 + dist * math.sin(el)), "lens": _u(rng, 30, 50)}
    pool = [k for k in (kinds or KINDS) if k != "unlit_glass"]  # unlit_glass: drawn below, from a stream of its own
    if r["world"] > 0:  # a world shines from every side (from below too): any caster is in its light
        pool = [k for k in pool if k in ("sky_spot", "up_area")] or ["sky_spot"]
    n = int(rng.integers(1, 4))
    r["distractors"] = []
    for j in range(n):
        kind = str(rng.choice(pool))
        r["distractors"].append({"kind": kind, "name": f"X{j}{kind.title().replace('_', '')}",
                                 "first": bool(rng.random() < 0.5), "u": rng.random(8).tolist()})
    more = np.random.default_rng([60, int(seed), 1])
    if (kinds is None or "unlit_glass" in kinds) and r["world"] == 0 and more.random() < 0.5 \
            and all(li["kind"] in ("AREA", "SPOT") for li in r["lights"]):
        r["distractors"].append({"kind": "unlit_glass", "name": "XUUnlitGlass", "first": bool(more.random() < 0.5),
                                 "u": more.random(8).tolist()})
    return r


def _sun_dir(light):
    d = np.subtract(light["target"], light["loc"])
    return d / np.linalg.norm(d)


def _far_place(r, u, cam):
    """A point 40-80 m from the middle, beyond the floor, out of the frame and of every sun's line
    (nearer, a glass ball's glory, light reflected inside it back towards the lamps, can land in view
    above the plan's threshold: the plan keeps it then, rightly)."""
    cm = CameraModel(cam)
    suns = [_sun_dir(li) for li in r["lights"] if li["kind"] == "SUN"]
    for k in range(64):
        a = 2 * math.pi * ((u[0] + 0.618034 * k) % 1.0)
        dist = max(40.0, 0.75 * r["floor"] + 5.0) + 40.0 * ((u[1] + 0.41421 * k) % 1.0)
        p = np.array([dist * math.cos(a), dist * math.sin(a), 1.0 * u[2]])
        rx, ry, depth, *_ = cm.project(p[None, :] + np.array([[0, 0, 0], [0, 0, 1.0]]))
        inside = np.any((depth > 0) & (rx > -8) & (rx < cm.W + 8) & (ry > -8) & (ry < cm.H + 8))
        towards = p / np.linalg.norm(p)
        shadow = any(float(np.dot(towards, -s)) > math.cos(math.radians(40)) for s in suns)
        if not inside and not shadow:
            return p
    return np.array([0.0, 0.0, -5.0])  # under the floor, if no place around qualifies


def _unreached(r, c, rad) -> bool:
    """Is the ball (c, rad) out of every lamp's reach: behind an area light's plane (its bounding box's
    corners), or out of a spot's cone (plan._reaches' tests)?"""
    lo, hi = c - rad, c + rad
    corners = np.array([[(lo, hi)[a][0], (lo, hi)[b][1], (lo, hi)[k][2]] for a in (0, 1) for b in (0, 1)
                        for k in (0, 1)])
    for li in r["lights"]:
        loc = np.asarray(li["loc"], float)
        axis = -look_at(loc, li["target"])[:3, 2]
        if li["kind"] == "AREA":
            if np.any((corners - loc) @ axis > 0):
                return False
        elif li["kind"] == "SPOT":
            v = c - loc
            dist = float(np.linalg.norm(v))
            reach = rad + li["radius"]
            ang = math.acos(float(np.clip(np.dot(v / dist, axis), -1, 1))) - math.asin(min(1.0, reach / dist))
            if dist <= reach or ang < 0.5 * li["spot"]:
                return False
        else:
            return False
    return True


def _unlit_place(r, u, cam):
    """A point 80-160 m from the middle, beyond a lamp (on its side, above it), out of the frame and of
    every lamp's reach; None where none qualifies (at 40-80 m, the floor's light after a bounce into
    it, reflected inside it back towards the lamps, could land in view at the plan's threshold)."""
    cm = CameraModel(cam)
    rad = 0.3 + 0.3 * u[4]
    for k in range(64):
        li = r["lights"][k % len(r["lights"])]
        a = math.atan2(li["loc"][1], li["loc"][0]) + math.radians(40) * (((u[0] + 0.618034 * k) % 1.0) - 0.5)
        dist = 80.0 + 80.0 * ((u[1] + 0.41421 * k) % 1.0)
        z = max(x["loc"][2] for x in r["lights"]) + rad + 1.0 + 3.0 * ((u[2] + 0.7071 * k) % 1.0)
        c = np.array([dist * math.cos(a), dist * math.sin(a), z])
        rx, ry, depth, *_ = cm.project(c[None, :])
        inside = np.any((depth > 0) & (rx > -8) & (rx < cm.W + 8) & (ry > -8) & (ry < cm.H + 8))
        if not inside and _unreached(r, c, rad):
            return c, rad
    return None


def build(r: dict, with_distractors: bool, resolution=RES):
    """The scene of recipe r, with its distractors or without."""
    b = SceneBuilder(f"random{r['seed']}")
    floor = b.material("Floor", "diffuse", color=(r["albedo"],) * 3)
    cam = b.set_camera(r["camera"]["loc"], (0.0, 0.0, 0.3), lens=r["camera"]["lens"], resolution_x=resolution[0],
                       resolution_y=resolution[1])
    ds = r["distractors"] if with_distractors else []
    top = 8.0  # above every lamp and caster
    lights = []
    for d in ds:
        if d["kind"] in ("sky_spot", "up_area") and d["first"]:
            lights.append(d)
    lights += r["lights"]
    lights += [d for d in ds if d["kind"] in ("sky_spot", "up_area") and not d["first"]]
    if r["world"] > 0:
        b.world((r["world"],) * 3)
    objects = [d for d in ds if d["kind"] not in ("sky_spot", "up_area") and d["first"]]
    objects += [{"kind": "floor"}] + r["casters"]
    objects += [d for d in ds if d["kind"] not in ("sky_spot", "up_area") and not d["first"]]
    for o in objects:
        k = o["kind"]
        if k == "floor":
            b.plane("Floor", (0, 0, 0), r["floor"], floor)
        elif k in ("ball", "lens", "mirror", "ring", "slab"):
            _caster(b, o)
        else:
            u = o["u"]
            glass = b.material(f"{o['name']}Glass", "dielectric", color=(1.0, 1.0, 1.0), ior=1.4 + 0.3 * u[3])
            if k == "under_glass":
                h = r["floor"] / 4
                c = ((2 * u[0] - 1) * h, (2 * u[1] - 1) * h, -0.6 - 2.0 * u[2])
                b.uv_sphere(o["name"], c, 0.5, glass, segments=32, rings=16)
            elif k in ("far_glass", "hidden_glass"):
                rad = 0.3 + 0.3 * u[4]
                c = _far_place(r, u, cam) + np.array([0, 0, rad])
                vis = S.RAY_ALL & ~S.RAY_DIFFUSE if k == "hidden_glass" else S.RAY_ALL
                b.uv_sphere(o["name"], c, rad, glass, segments=32, rings=16, visibility=vis)
            elif k == "unlit_glass":
                place = _unlit_place(r, u, cam)
                if place is not None:
                    b.uv_sphere(o["name"], place[0], place[1], glass, segments=32, rings=16)
            elif k == "far_mirror":
                metal = b.material(f"{o['name']}Metal", "conductor", color=(0.9, 0.9, 0.9))
                c = _far_place(r, u, cam) + np.array([0, 0, 1.0])
                tilt, az = math.radians(10 * u[5]), 2 * math.pi * u[6]  # level: floor light it sends back lands by it
                n = (math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt))
                b.plane(o["name"], c, 1.0 + u[4], metal, normal=n)
    for li in lights:
        k = li["kind"]
        if k == "sky_spot":
            u = li["u"]
            loc = ((2 * u[0] - 1) * 2, (2 * u[1] - 1) * 2, top + 3 * u[2])
            tilt, az = math.radians(20 * u[3]), 2 * math.pi * u[4]
            aim = (math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt))
            b.light(li["name"], "SPOT", location=loc, target=np.add(loc, aim), power=200 + 800 * u[5],
                    spot_size=math.radians(20 + 40 * u[6]))
        elif k == "up_area":
            u = li["u"]
            loc = ((2 * u[0] - 1) * 2, (2 * u[1] - 1) * 2, top + 3 * u[2])
            b.light(li["name"], "AREA", location=loc, target=np.add(loc, (0.0, 0.0, 1.0)), power=200 + 800 * u[5],
                    size=0.2 + 0.8 * u[6])
        elif k == "SUN":
            b.light(li["name"], "SUN", location=li["loc"], target=li["target"], power=li["power"], angle=li["angle"])
        else:
            b.light(li["name"], k, location=li["loc"], target=li["target"], power=li["power"], size=li["size"],
                    radius=li["radius"] if k != "AREA" else 0.0, spot_size=li["spot"])
    return b.build()


def _caster(b, c):
    x, y = c["xy"]
    s, z = c["size"], c["z"]
    if c["kind"] in ("ball", "lens", "slab"):
        mat = b.material(f"{c['name']}Glass", "dielectric", color=(1.0, 1.0, 1.0), ior=c["ior"])
    else:
        mat = b.material(f"{c['name']}Metal", "conductor", color=(0.95, 0.9, 0.8))
    if c["kind"] == "ball":
        b.uv_sphere(c["name"], (x, y, z + s), s, mat, segments=32, rings=16)
    elif c["kind"] == "lens":
        V, F, N = lens_mesh(2.4 * s, s, 0.01, segments=48, rings=12, centre=(x, y, z + 0.3))
        b.mesh(c["name"], V, F, mat, normals=N)
    elif c["kind"] == "mirror":
        t, a = math.radians(c["tilt"]), math.radians(c["azimuth"])
        b.plane(c["name"], (x, y, z + s), 2 * s, mat, normal=(math.sin(t) * math.cos(a), math.sin(t) * math.sin(a),
                                                              math.cos(t)))
    elif c["kind"] == "ring":
        ph = np.linspace(0, 2 * math.pi, 65)[:-1]
        ring = np.stack([np.cos(ph), np.sin(ph)], -1) * (2 * s)
        V = np.concatenate([np.c_[ring, np.zeros(64)], np.c_[ring, np.full(64, 0.6 * s)]]) + [x, y, 0.0]
        N = np.concatenate([np.c_[-ring / (2 * s), np.zeros(64)]] * 2)
        F = [[i, i + 64, (i + 1) % 64 + 64, (i + 1) % 64] for i in range(64)]
        b.mesh(c["name"], V, F, mat, normals=N)
    else:
        hx, hy, hz = 1.5 * s, 0.6 * s, 0.08 + 0.1 * s
        V = np.array([(x + i * hx, y + j * hy, z + 0.3 + k * hz) for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        F = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        b.mesh(c["name"], V, F, mat)


__all__ = ["KINDS", "RES", "lens_mesh", "issue_lens_scene", "recipe", "build", "look_at"]
