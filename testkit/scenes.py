"""Tiny scenes built in code for the tests, with their analytic answers."""
from __future__ import annotations

import math

import numpy as np

from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.trace.camera import CameraModel

MIRROR_RHO, FLOOR_ALBEDO = 0.9, 0.8


def mirror_scene(resolution=(160, 120), power=100.0, radius=0.25):
    """A flat mirror tilted 45 degrees sends a disk light straight down onto the floor.

    The light at (-2, 0, 1.5) faces +x; its mirror image is a disk at height 3.5
    facing down, centred over the origin."""
    b = SceneBuilder("mirror")
    floor = b.material("floor", "diffuse", color=(FLOOR_ALBEDO,) * 3)
    mirror = b.material("mirror", "conductor", color=(MIRROR_RHO,) * 3)
    b.plane("Floor", (0, 0, 0), 10, floor, receiver=True)
    b.plane("Mirror", (0, 0, 1.5), 1.5, mirror, normal=np.array([-1, 0, -1]) / math.sqrt(2), caster=True)
    b.light("Disk", "AREA", location=(-2, 0, 1.5), target=(0, 0, 1.5), power=power, shape="DISK",
            size=2 * radius)
    b.set_camera((0, -6, 5), (-0.2, 0, 0), lens=35, resolution_x=resolution[0], resolution_y=resolution[1])
    return b.build()


def disk_irradiance(points, center, normal, radius, radiance, n=256):
    """Irradiance on upward-facing floor points from a one-sided Lambertian disk (quadrature)."""
    normal = np.asarray(normal, float)
    s = np.cross(normal, [0.0, 1.0, 0.0] if abs(normal[1]) < 0.9 else [1.0, 0.0, 0.0])
    s /= np.linalg.norm(s)
    t = np.cross(normal, s)
    # midpoint rule in (r^2, phi): equal-area cells
    r = radius * np.sqrt((np.arange(n) + 0.5) / n)
    phi = 2 * math.pi * (np.arange(n) + 0.5) / n
    R, P = np.meshgrid(r, phi, indexing="ij")
    q = center + (R * np.cos(P))[..., None] * s + (R * np.sin(P))[..., None] * t
    dA = math.pi * radius**2 / (n * n)
    out = []
    for x in np.atleast_2d(points):
        v = q - x
        d2 = (v * v).sum(-1)
        cos_x = np.maximum(v[..., 2], 0) / np.sqrt(d2)
        cos_l = np.maximum(-(v @ normal), 0) / np.sqrt(d2)
        out.append(radiance * (cos_x * cos_l / d2).sum() * dA)
    return np.array(out)


def water_scene(light="point", size=4.0, ior=1.33, resolution=64, sun_tilt_deg=30.0):
    """A flat water surface at z=1 over a floor at z=0; an ortho camera under
    the water at z=0.9 looks straight down at a 2 x 2 patch of floor."""
    b = SceneBuilder("water")
    floor = b.material("floor", "diffuse", color=(FLOOR_ALBEDO,) * 3)
    water = b.material("water", "dielectric", color=(1, 1, 1), ior=ior)
    b.plane("Floor", (0, 0, 0), 20, floor)
    b.plane("Water", (0, 0, 1), size, water)
    if light == "point":
        b.light("Point", "POINT", location=(0, 0, 4), power=1000.0, radius=0.05)
    else:
        tilt = math.radians(sun_tilt_deg)
        d = np.array([-math.sin(tilt), 0.0, -math.cos(tilt)])
        b.light("Sun", "SUN", location=(0, 0, 10), target=np.array([0, 0, 10]) + d, power=3.0,
                angle=math.radians(0.5))
    b.set_camera((0, 0, 0.9), (0, 0, 0), type=1, ortho_scale=2.0, resolution_x=resolution,
                 resolution_y=resolution, clip_start=0.01)
    return b.build()


def fresnel(cos_i, eta):
    """Unpolarised Fresnel reflectance from air into a medium of index eta (textbook form)."""
    sin_t = math.sqrt(max(0.0, 1 - cos_i**2)) / eta
    cos_t = math.sqrt(1 - sin_t**2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


def point_through_water(rho, intensity, h_light, h_water, eta):
    """Floor irradiance at radial distance rho from below a point light of
    intensity I at height h_light above a flat water surface of depth h_water."""
    # solve rho = h_light tan(ti) + h_water tan(tt) for ti by bisection
    lo, hi = 0.0, math.pi / 2 - 1e-9
    for _ in range(200):
        ti = 0.5 * (lo + hi)
        tt = math.asin(math.sin(ti) / eta)
        if h_light * math.tan(ti) + h_water * math.tan(tt) < rho:
            lo = ti
        else:
            hi = ti
    ti = 0.5 * (lo + hi)
    tt = math.asin(math.sin(ti) / eta)
    dtt = math.cos(ti) / (eta * math.cos(tt))
    drho = h_light / math.cos(ti) ** 2 + h_water / math.cos(tt) ** 2 * dtt
    T = 1 - fresnel(math.cos(ti), eta)
    if rho < 1e-9:  # limit sin(ti)/rho -> 1/drho
        return intensity * T / drho**2
    return intensity * T * math.sin(ti) / (rho * drho)


def glass_sphere_scene(resolution=(64, 48), ior=1.5, light_size=1.0, power=400.0, height=1.2):
    """A glass ball (radius 0.5, centre 1.2 above the floor, so the floor lies
    beyond the ball's focus) under a square area light: the refractive caustic
    through two refractions (TT) plus the faint reflection (R)."""
    b = SceneBuilder("glass sphere")
    floor = b.material("floor", "diffuse", color=(FLOOR_ALBEDO,) * 3)
    glass = b.material("glass", "dielectric", color=(1, 1, 1), ior=ior)
    b.plane("Floor", (0, 0, 0), 10, floor)
    b.uv_sphere("Ball", (0, 0, height), 0.5, glass, segments=64, rings=32)
    b.light("Area", "AREA", location=(0.3, 0.2, 5.0), target=(0.3, 0.2, 0), power=power, size=light_size)
    b.set_camera((0, -2.0, 3.0), (0, 0, 0.0), lens=35, resolution_x=resolution[0], resolution_y=resolution[1])
    return b.build()


def ring_scene(resolution=(64, 48)):
    """A gold-ish conductor ring (open cylinder, radius 1, height 0.4) on the
    floor lit from the side: the cardioid caustic inside it (single R)."""
    b = SceneBuilder("ring")
    floor = b.material("floor", "diffuse", color=(FLOOR_ALBEDO,) * 3)
    metal = b.material("ring", "conductor", color=(0.9, 0.8, 0.5))
    b.plane("Floor", (0, 0, 0), 10, floor)
    seg = 128
    ang = np.linspace(0, 2 * math.pi, seg + 1)[:-1]
    ring = np.stack([np.cos(ang), np.sin(ang)], -1)
    V = np.concatenate([np.c_[ring, np.zeros(seg)], np.c_[ring, np.full(seg, 0.4)]])
    N = np.concatenate([np.c_[-ring, np.zeros(seg)]] * 2)  # inward-facing shading normals
    F = [[i, i + seg, (i + 1) % seg + seg, (i + 1) % seg] for i in range(seg)]
    b.mesh("Ring", V, F, metal, normals=N)
    b.light("Area", "AREA", location=(-4, 0, 1.6), target=(0, 0, 0), power=800, size=0.3)
    b.set_camera((0, 0, 3.2), (0, 0, 0), lens=40, resolution_x=resolution[0], resolution_y=resolution[1])
    return b.build()


def wavy_mirror_scene(resolution=(64, 48), amplitude=0.04, wavelength=0.3, n=96, normal_mapped=False):
    """A bumpy metal sheet (smooth-shaded height field) tilted over the floor
    under an area light: many seeds land on facets that face away from the
    light (back-lit), where small Newton steps get stuck."""
    b = SceneBuilder("wavy mirror")
    floor = b.material("floor", "diffuse", color=(FLOOR_ALBEDO,) * 3)
    metal = b.material("metal", "conductor", color=(0.95, 0.9, 0.8))
    b.plane("Floor", (0, 0, 0), 12, floor)
    u = np.linspace(-1, 1, n + 1)
    X, Y = np.meshgrid(u, u, indexing="ij")
    k = 2 * math.pi / wavelength
    Z = amplitude * np.sin(k * X) * np.sin(k * Y)
    dzdx = amplitude * k * np.cos(k * X) * np.sin(k * Y)
    dzdy = amplitude * k * np.sin(k * X) * np.cos(k * Y)
    Nl = np.stack([-dzdx, -dzdy, np.ones_like(Z)], -1)
    Nl /= np.linalg.norm(Nl, axis=-1, keepdims=True)
    # local frame: the sheet faces down-left, 1.5 above the origin
    tilt = math.radians(45)
    R = np.array([[math.cos(tilt), 0, math.sin(tilt)], [0, 1, 0], [-math.sin(tilt), 0, math.cos(tilt)]])
    R = R @ np.diag([1.0, 1.0, 1.0])
    # normal_mapped: flat geometry, bumpy shading normals only (a normal map sampled
    # at the vertices), the paper's Figure 12 kind of caster
    P = np.stack([X, Y, np.zeros_like(Z) if normal_mapped else Z], -1).reshape(-1, 3)
    flip = np.diag([1.0, 1.0, -1.0])  # make the bumpy side face down
    V = (P @ flip.T) @ R.T + np.array([0, 0, 1.5])
    N = (Nl.reshape(-1, 3) @ flip.T) @ R.T
    idx = np.arange((n + 1) * (n + 1)).reshape(n + 1, n + 1)
    F = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], -1).reshape(-1, 4)
    F = F[:, ::-1]  # winding: geometric normals down, with the shading normals
    b.mesh("Sheet", V, F, metal, normals=N)
    b.light("Area", "AREA", location=(-3, 0, 1.5 - 0.0), target=(0, 0, 1.5), power=600, size=0.4)
    b.set_camera((0, -5, 4), (0.2, 0, 0), lens=35, resolution_x=resolution[0], resolution_y=resolution[1])
    return b.build()


def world_mirror_scene(resolution=(64, 48), world=0.5, width=40.0, height=1.0, x=1.0, image=None):
    """A floor under a world of constant radiance `world` (or the map `image` (H, W, 3), as it is)
    and no lamp, a mirror standing on it (the plane x = `x`, `width` wide along y, `height` tall)
    facing -x, a camera looking straight down from above the floor before the mirror."""
    b = SceneBuilder("world mirror")
    floor = b.material("floor", "diffuse", color=(FLOOR_ALBEDO,) * 3)
    mirror = b.material("mirror", "conductor", color=(MIRROR_RHO,) * 3)
    b.plane("Floor", (0, 0, 0), width, floor, receiver=True)
    w = width / 2
    b.mesh("Mirror", np.array([[x, -w, 0], [x, w, 0], [x, w, height], [x, -w, height]]), np.array([[0, 1, 2, 3]]),
           mirror, caster=True)
    b.world((1.0,) * 3 if image is not None else (world,) * 3, image=image)
    b.set_camera((0, 0, 3), (0, 0, 0), lens=35, resolution_x=resolution[0], resolution_y=resolution[1])
    return b.build()


def world_through_mirror(p, world=0.5, width=40.0, height=1.0, x=1.0):
    """world_mirror_scene's caustic radiance at floor point p (before the mirror): the floor's
    albedo / pi x the irradiance of the sky reflected in the mirror. A direction of azimuth phi
    about the mirror's normal and angle theta from the zenith meets the mirror (distance d) below
    its top where cot(theta) <= k cos(phi), k = height / d; over theta that holds the irradiance
    rho L cos^2(theta_0) / 2 = rho L / 2 x k^2 cos^2 / (1 + k^2 cos^2), integrated over the phi that
    meet the mirror's width (pi (1 - 1 / sqrt(1 + k^2)) for an endless mirror)."""
    d = x - p[0]
    k = height / d
    phi = np.linspace(math.atan((-width / 2 - p[1]) / d), math.atan((width / 2 - p[1]) / d), 4001)
    f = (k * np.cos(phi)) ** 2 / (1 + (k * np.cos(phi)) ** 2)
    E = MIRROR_RHO * world / 2 * float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(phi)))
    return FLOOR_ALBEDO / math.pi * E


def hammered_mirror_scene(resolution=(48, 36)):
    """The paper's Figure 12 kind of caster, closer than wavy_mirror_scene(normal_mapped=True):
    a flat metal sheet whose normal map is fine and gentle, like hammered metal (20 bumps
    across, normals tilted up to 32 degrees, sampled on a 257 x 257 grid). Far from the
    mirror solution every bump is a local minimum of the walk."""
    return wavy_mirror_scene(resolution, amplitude=0.01, wavelength=0.1, n=256, normal_mapped=True)


def pane_scene(thickness=0.1, resolution=(32, 24)):
    """A standing glass pane (flat-shaded box) above a floor, lit from the floor's side of it:
    the light reflected off the pane's back face is a T R T chain that enters and leaves by
    the front face, with x0 and the light on the same side of it."""
    b = SceneBuilder("pane")
    floor = b.material("floor", "diffuse", color=(FLOOR_ALBEDO,) * 3)
    glass = b.material("glass", "dielectric", color=(1, 1, 1), ior=1.5)
    b.plane("Floor", (0, 0, 0), 10, floor)
    hx, hy, hz = 1.2, thickness / 2, 0.6
    v = np.array([(x, y, z + 0.8) for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
    f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    b.mesh("Pane", v, f, glass, caster=True)
    b.light("Key", "AREA", location=(0.3, -1.5, 2.5), target=(0.3, -0.5, 0.0), power=500.0, shape="DISK", size=0.3)
    b.set_camera((0, -4.0, 2.0), (0, 0, 0.5), lens=35, resolution_x=resolution[0],
                 resolution_y=resolution[1])
    return b.build()


def seed_chains(scene, types: str, x0, rng):
    """Plain SMS seed chains of one chain type from floor points x0 (normal +z), as a bake seeds
    its walks: (ctx, ng0, light, chain), the light's points and the seeds drawn from rng."""
    from smbs_addon.walks.manifold import Ctx
    from smbs_addon.walks.seeds import Seeder
    from smbs_addon.shading.light_samples import sample_light
    from smbs_addon.baking.plan import make_plan
    from smbs_addon.trace.tracer import Tracer

    plan = make_plan(scene, "OFF")
    ctx = Ctx(scene, Tracer(scene, threads=2), plan, {})
    n = len(x0)
    ng0 = np.tile([0.0, 0.0, 1.0], (n, 1))
    light = sample_light(scene, 0, n, rng)
    chain = Seeder(scene, plan.casters, types, "sms").seed(ctx, rng, types, x0, ng0, light)
    return ctx, ng0, light, chain


def lens_scene(extra: bool, resolution=(96, 72), far=(0, 0, -3), world=0.0):
    """The glass ball of glass_sphere_scene; with extra, a spot aimed at the empty
    sky (first in the list of lights, so every light after it moves one place) and a glass
    ball at ``far``: under the floor (hidden from the light and the camera), or out of the
    frame beyond the floor's edge. world: a world of that constant grey (first of the lights, as
    the export puts it), if above 0."""
    b = SceneBuilder("lens")
    if world > 0:
        b.world((world,) * 3)
    floor = b.material("floor", "diffuse", color=(0.8,) * 3)
    glass = b.material("glass", "dielectric", color=(1, 1, 1), ior=1.5)
    if extra:
        b.light("SkySpot", "SPOT", location=(0, 0, 3), target=(0, 0, 10), power=500, spot_size=math.radians(30))
    b.plane("Floor", (0, 0, 0), 10, floor)
    b.uv_sphere("Ball", (0, 0, 1.2), 0.5, glass, segments=64, rings=32)
    if extra:
        b.uv_sphere("FarGlass", far, 0.5, glass, segments=32, rings=16)
    b.light("Area", "AREA", location=(0.3, 0.2, 5.0), target=(0.3, 0.2, 0), power=400, size=1.0)
    b.set_camera((0, -2.0, 3.0), (0, 0, 0.0), lens=35, resolution_x=resolution[0], resolution_y=resolution[1])
    return b.build()


# ------------------------------------------------------------ what the floor's pixels should hold
def pixel_floor_points(scene):
    """Floor (z=0) point seen through each pixel centre: (H,W,3) and a mask."""
    cam = CameraModel(scene.camera)
    jj, ii = np.mgrid[0:cam.H, 0:cam.W]
    o, d, _ = cam.rays(ii.ravel() + 0.5, jj.ravel() + 0.5)
    t = -o[:, 2] / np.where(d[:, 2] != 0, d[:, 2], 1e-30)
    ok = (t > 0) & (d[:, 2] < 0)
    return (o + t[:, None] * d).reshape(cam.H, cam.W, 3), ok.reshape(cam.H, cam.W)


def mirror_expected(scene):
    """mirror_scene's floor under the mirrored disk light: (expected image (H,W), region)."""
    pts, ok = pixel_floor_points(scene)
    region = ok & (np.hypot(pts[..., 0], pts[..., 1]) < 0.6)  # the whole disk is seen in the mirror
    radiance = 100.0 / (math.pi * math.pi * 0.25**2)
    E = disk_irradiance(pts[region], center=np.array([0, 0, 3.5]), normal=[0, 0, -1], radius=0.25,
                        radiance=radiance, n=64)
    expected = np.zeros(region.shape)
    expected[region] = MIRROR_RHO * FLOOR_ALBEDO / math.pi * E
    return expected, region


def water_point_expected(scene):
    """water_scene("point")'s floor under the water: (expected image (H,W), region)."""
    pts, ok = pixel_floor_points(scene)
    rho = np.hypot(pts[..., 0], pts[..., 1])
    region = ok & (rho < 0.9)
    E = np.array([point_through_water(x, 1000.0 / (4 * math.pi), 3.0, 1.0, 1.33) for x in rho[region]])
    expected = np.zeros(region.shape)
    expected[region] = FLOOR_ALBEDO / math.pi * E
    return expected, region


def water_sun_expected(scene):
    """water_scene("sun")'s floor, lit evenly through the flat water: (expected image (H,W), region)."""
    region = np.zeros((scene.camera.height, scene.camera.width), bool)
    region[4:-4, 4:-4] = True  # inside the lit part of the floor with the filter's reach
    c = math.cos(math.radians(30))
    E = 3.0 * c * (1 - fresnel(c, 1.33))
    return np.full(region.shape, FLOOR_ALBEDO / math.pi * E), region


def wavy_water_sun_scene(resolution=(40, 30), amplitude=0.05, k=10.0, n=80, tilt_deg=20.0, angle_deg=4.0,
                         above=False):
    """Wavy water (a smooth-shaded height field A sin(kx) sin(0.7ky) over 3 x 3 m, 1 m over the floor)
    under a sun of angle_deg, tilted tilt_deg; its waves focus above the floor (focal length about
    n / ((n - 1) A k^2) = 0.8 m), so most floor points see the sun through several wave crests: one
    solution from the straight line to the sun and others beside it. The camera under the surface
    looks down at the floor (no refraction on the eye's side); above: from 3 m, through the water,
    as at a pool."""
    b = SceneBuilder("wavy water under a sun")
    floor = b.material("floor", "diffuse", color=(FLOOR_ALBEDO,) * 3)
    water = b.material("water", "dielectric", color=(1, 1, 1), ior=1.33)
    b.plane("Floor", (0, 0, 0), 20, floor)
    u = np.linspace(-1.5, 1.5, n + 1)
    X, Y = np.meshgrid(u, u, indexing="ij")
    Z = 1.0 + amplitude * np.sin(k * X) * np.sin(0.7 * k * Y)
    dzdx = amplitude * k * np.cos(k * X) * np.sin(0.7 * k * Y)
    dzdy = amplitude * 0.7 * k * np.sin(k * X) * np.cos(0.7 * k * Y)
    N = np.stack([-dzdx, -dzdy, np.ones_like(Z)], -1)
    N /= np.linalg.norm(N, axis=-1, keepdims=True)
    idx = np.arange((n + 1) * (n + 1)).reshape(n + 1, n + 1)
    F = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 4)
    b.mesh("Water", np.stack([X, Y, Z], -1).reshape(-1, 3), F, water, normals=N.reshape(-1, 3))
    t = math.radians(tilt_deg)
    d = np.array([-math.sin(t), 0.0, -math.cos(t)])
    b.light("Sun", "SUN", location=(0, 0, 10), target=np.array([0, 0, 10]) + d, power=3.0,
            angle=math.radians(angle_deg))
    b.set_camera((0, 0, 3.0 if above else 0.8), (0, 0, 0), type=1, ortho_scale=1.6, resolution_x=resolution[0],
                 resolution_y=resolution[1], clip_start=0.01)
    return b.build()
