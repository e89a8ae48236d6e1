"""Eye paths: camera rays, the receivers they reach through mirrors and glass, Cycles' bent view
normals, and the splats of light-traced paths into the camera.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.jit import JIT, LANES
from .records import (
    CAM_AXES, CAM_CLIP, CAM_CLIP_END, CAM_H, CAM_INV, CAM_ORIGIN, CAM_ORTHO, CAM_PIX_AREA, CAM_PIX_H, CAM_PIX_W,
    CAM_REGION, CAM_XMIN, CAM_YMIN, HIDDEN_PASSES, REC_BETA, REC_NG, REC_NS, REC_P, REC_W, VIEW_NEAR, VIEW_PLANE)
from ..scene.arrays import CONDUCTOR, DIELECTRIC, DIFFUSE, RAY_CAMERA, RAY_GLOSSY, RAY_TRANSMISSION
from ..scene.light_paths import DIFFUSE_EVENTS, GLOSSY_EVENTS, TRANSMISSION_EVENTS
from .typed import TypedOnce

from ..shading.absorption import absorbed1, medium_after1
from ..core.vec3 import add3, cols3, dot1, neg3, scale3, sub3
from ..shading.optics import bump_shadowing1, scatter1
from ..shading.coat import coat_factor1, table_weight1
from ..core.embree import intersect1, occluded1, ray_state
from .rays import next_past
from .chain import spawn1
from .keyed import keyed_uniform3


@njit(inline="always", **JIT)
def view_normal1(vn, vp, t, px, py, p, ng, ns, to_cam, foot):
    """The shading normal Cycles' camera ray through raster position (px, py) meets at p, a point of
    a bumped diffuse receiver that projects there (ng, ns: its geometric and smooth shading
    normals; to_cam: unit, towards the camera; foot: the width a pixel covers there): the normal of
    Scene.view_normals' sub-pixel there (vn, vp: view_normals, view_points; t: eye.view_tables'
    raster to the view's), turned to ns's side (Cycles' faces the camera), where the sub-pixel's
    point is p's surface (on its plane, near it: VIEW_PLANE, VIEW_NEAR); else ns."""
    h, w = vn.shape[0], vn.shape[1]
    c = min(max(int(math.floor(t[0] * px + t[1])), 0), w - 1)
    r = min(max(int(math.floor(t[2] * py + t[3])), 0), h - 1)
    q = (float(vp[r, c, 0]) - p[0], float(vp[r, c, 1]) - p[1], float(vp[r, c, 2]) - p[2])
    f = foot / t[0]
    slant = max(abs(dot1(to_cam, ng)), 0.02)
    if not (abs(dot1(q, ng)) <= VIEW_PLANE * f + 1e-6 * (abs(p[0]) + abs(p[1]) + abs(p[2]))
            and dot1(q, q) <= (VIEW_NEAR * f / slant) ** 2):
        return ns
    n = (float(vn[r, c, 0]), float(vn[r, c, 1]), float(vn[r, c, 2]))
    ln = math.sqrt(dot1(n, n))
    if not ln > 0.5:
        return ns
    k = (1.0 if dot1(to_cam, ng) * dot1(ns, ng) >= 0 else -1.0) / ln
    return (k * n[0], k * n[1], k * n[2])


@njit(**JIT)
def view_normal_rows(vn, vp, t, px, py, p, ng, ns, to_cam, foot, out):
    """view_normal1 per row into out (N,3)."""
    for i in range(p.shape[0]):
        n = view_normal1(vn, vp, t, px[i], py[i], cols3(p, i, 0), cols3(ng, i, 0), cols3(ns, i, 0), cols3(to_cam, i, 0),
                         foot[i])
        out[i, 0], out[i, 1], out[i, 2] = n[0], n[1], n[2]


@njit(**JIT)
def _cam_mat(cam, a, v):
    """The 3x3 matrix kept row by row at cam[a:a + 9] (CAM_AXES, CAM_INV) times v."""
    return (cam[a] * v[0] + cam[a + 1] * v[1] + cam[a + 2] * v[2],
            cam[a + 3] * v[0] + cam[a + 4] * v[1] + cam[a + 5] * v[2],
            cam[a + 6] * v[0] + cam[a + 7] * v[1] + cam[a + 8] * v[2])


@njit(inline="always", **JIT)
def _camera_ray(cam, x, y):
    """camera.CameraModel.rays of raster position (x, y), moved to the near clip plane: (origin,
    unit direction, the distance from there to the far clip plane: Cycles' camera rays end at
    the depth clip_end, as they start at the depth clip_start)."""
    fx = cam[CAM_XMIN] + x * cam[CAM_PIX_W]
    fy = cam[CAM_YMIN] + (cam[CAM_H] - y) * cam[CAM_PIX_H]
    if cam[CAM_ORTHO] > 0:
        lo, ld = (fx, fy, 0.0), (0.0, 0.0, -1.0)
    else:
        r = 1.0 / math.sqrt(fx * fx + fy * fy + 1.0)
        lo, ld = (0.0, 0.0, 0.0), (fx * r, fy * r, -r)
    o = add3((cam[CAM_ORIGIN], cam[CAM_ORIGIN + 1], cam[CAM_ORIGIN + 2]), _cam_mat(cam, CAM_AXES, lo))
    d = _cam_mat(cam, CAM_AXES, ld)
    stretch = math.sqrt(dot1(d, d))  # 1 unless the axes are sheared
    d = scale3(1.0 / stretch, d)
    far = (cam[CAM_CLIP_END] - cam[CAM_CLIP]) * stretch / abs(ld[2])
    return add3(o, scale3(cam[CAM_CLIP] * stretch / abs(ld[2]), d)), d, far


@njit(**JIT)
def camera_rays(cam, x, y):
    """_camera_ray per raster position (CameraModel.pixel_rays): (origins on the near clip
    plane, unit directions)."""
    n = x.shape[0]
    o, d = np.empty((n, 3)), np.empty((n, 3))
    for i in range(n):
        oi, di, _ = _camera_ray(cam, x[i], y[i])
        for c in range(3):
            o[i, c], d[i, c] = oi[c], di[c]
    return o, d


@njit(inline="always", **JIT)
def _camera_clear(ray, o, d, tmax, tng, tri_object, hid, eps):
    """Whether nothing camera rays meet lies on o + t d, 0 < t < tmax (the shadow ray towards the
    camera, counted as kind 1): the surfaces of objects camera rays do not meet (hid & RAY_CAMERA,
    Scene.hidden_kinds) are passed, up to HIDDEN_PASSES of them."""
    if hid.shape[0] == 0:
        return not occluded1(ray, o, d, tmax, 1)
    for _ in range(HIDDEN_PASSES + 1):
        pr, t = intersect1(ray, o, d, tmax, 1)
        if pr < 0:
            return True
        if not hid[tri_object[pr]] & RAY_CAMERA:
            return False
        g = (tng[pr, 0], tng[pr, 1], tng[pr, 2])
        o = spawn1(add3(o, scale3(t, d)), g, d, eps)  # tracer.spawn
        tmax -= t
    return False


@njit(inline="always", **JIT)
def put_record(rec, rec_i, row, p, g, n, w, b, lane, k, m):
    """A diffuse vertex's record at row `row` of rec (REC_* columns: point, geometric and shading
    normals, the direction w away from it along the path, the throughput or flux b) and rec_i (its
    lane, the specular vertices k before it, its material m)."""
    for c in range(3):
        rec[row, REC_P + c], rec[row, REC_NG + c], rec[row, REC_NS + c] = p[c], g[c], n[c]
        rec[row, REC_W + c], rec[row, REC_BETA + c] = w[c], b[c]
    rec_i[row, 0], rec_i[row, 1], rec_i[row, 2] = lane, k, m


@njit(**LANES)
def _camera_splat_rows(ray, cam, margin, rec, mat, mats, first_order, eps, textured, view, hide, out):
    """camera_splats' loop (its caller holds the arrays). Returns (rays cast, splats
    written)."""
    v_flag, v_n, v_p, v_t = view.flags, view.normals, view.points, view.t
    tng, tri_object, hid = hide.tng, hide.tri_object, hide.hid
    rx, ry, val, alb = out.rx, out.ry, out.val, out.alb
    mat_color = mats.color
    x0, x1, y0, y1 = cam[CAM_REGION], cam[CAM_REGION + 1], cam[CAM_REGION + 2], cam[CAM_REGION + 3]
    org = (cam[CAM_ORIGIN], cam[CAM_ORIGIN + 1], cam[CAM_ORIGIN + 2])
    ortho = cam[CAM_ORTHO] > 0
    a = CAM_AXES
    rays = n = 0
    for i in range(rec.shape[0]):
        y = cols3(rec, i, REC_P)
        ng, ns, w = cols3(rec, i, REC_NG), cols3(rec, i, REC_NS), cols3(rec, i, REC_W)
        # camera.CameraModel.project
        q = sub3(y, org)
        c0, c1, c2 = _cam_mat(cam, CAM_INV, q)
        depth = -c2
        if not (depth >= cam[CAM_CLIP] and depth <= cam[CAM_CLIP_END]):
            continue
        if ortho:
            fx, fy, dist, cos_axis = c0, c1, depth, 1.0
        else:
            fx, fy = c0 / depth, c1 / depth
            dist = math.sqrt(dot1(q, q))
            cos_axis = depth / dist if dist > 0 else 0.0
        px = (fx - cam[CAM_XMIN]) / cam[CAM_PIX_W]
        py = cam[CAM_H] - (fy - cam[CAM_YMIN]) / cam[CAM_PIX_H]
        if not (px > x0 - margin and px < x1 + margin and py > y0 - margin and py < y1 + margin):
            continue
        # camera.CameraModel.towards
        if ortho:
            to_cam = (cam[a + 2], cam[a + 5], cam[a + 8])
            tmax = depth - cam[CAM_CLIP]
        else:
            to_cam = scale3(1.0 / max(dist, 1e-300), neg3(q))
            tmax = dist * (1.0 - cam[CAM_CLIP] / max(depth, 1e-300))
        m = mat[i]
        sn = ns
        if v_t[0] > 0 and v_flag[m]:  # a bumped receiver: its normal as Cycles' camera ray meets it (eye.view_bumped)
            ns = view_normal1(v_n, v_p, v_t, px, py, y, ng, sn, to_cam,
                              cam[CAM_PIX_W] * (1.0 if ortho else dist))
        ci_g, co_g, ci_s = dot1(w, ng), dot1(to_cam, ng), dot1(w, ns)
        if not (ci_g * co_g > 0 and ci_s * (1.0 if ci_g > 0 else -1.0) > 0):  # same side, lit per shading normal
            continue
        o = spawn1(y, ng, to_cam, eps)  # tracer.spawn
        rays += 1
        if not _camera_clear(ray, o, to_cam, tmax - eps, tng, tri_object, hid, eps):
            continue
        # the diffuse BSDF with the shading-normal correction of the adjoint (Veach 5.3), the
        # camera's importance (CameraModel.importance)
        corr = abs(ci_s) / max(abs(ci_g), 1e-12) * bump_shadowing1(sn, ns, w, mats.bump_correction[m] != 0)
        if ortho:
            imp = abs(co_g) / cam[CAM_PIX_AREA]
        else:
            c3 = max(cos_axis, 1e-12) ** 3
            imp = abs(co_g) / (max(dist, 1e-300) ** 2 * cam[CAM_PIX_AREA] * c3)
        tw = table_weight1(mats.weight, m, dot1(to_cam, ns))  # under a glossy coat
        k = corr * imp / math.pi * tw
        kc = coat_factor1(mats, m, ns, to_cam, w, first_order)  # and what on-minus-off keeps of it
        rx[n], ry[n] = px, py
        tex = textured.shape[0] > 0 and textured[m]
        for c in range(3):
            val[n, c] = rec[i, REC_BETA + c] * mat_color[m, c] * k * kc[c]
            if alb.shape[0] > 0:  # Cycles' Diffuse Color pass there (Film.splat)
                alb[n, c] = mat_color[m, c] * tw if tex else 0.0
        n += 1
    return rays, n


@TypedOnce
@njit(**JIT)
def camera_splats(rt, cam, margin, rec, mat, mats, first_order, eps, textured, view, hide, out):
    """reference.splat_records: the light tracer's records (rec: REC_* columns; mat: their
    materials, diffuse with albedo mats.color[mat] under a Principled coat: layer.py, first_order: the
    records are x0's own caustic, not light after a diffuse bounce): each diffuse vertex connected
    to the camera
    (cam: CameraModel.kernel_params; margin: the film's filter width in pixels around the render
    region), its shadow ray cast here, the splat's raster position and value (the flux times the
    diffuse BSDF, Veach's shading-normal correction and the camera's importance) written to out
    (Splats) rx, ry, val; with textured (Scene.mat_textured, or empty) and out.alb (as val, or
    empty), the albedo of each splat on a textured material (Film.splat), zero elsewhere; view
    (ViewTables, eye.view_tables): a bumped receiver's normals as the camera sees them; hide
    (CameraHiding): the shadow rays pass the surfaces camera rays do not meet.
    Returns (shadow rays cast, splats written, the ray counters)."""
    ray = ray_state(rt)
    rays, n = _camera_splat_rows(ray, cam, margin, rec, mat, mats, first_order, eps, textured, view, hide, out)
    return rays, n, ray.counts


@njit(**LANES)
def _eye_rows(ray, cam, rx, ry, sample, key, geo, receivers, mats, rules, eps, out):
    """eye_lanes' loop over its lanes (its caller holds the arrays). Returns the
    records written."""
    tv, tng, tns, tri_material, mat_kind = geo.tv, geo.tng, geo.tns, geo.tri_material, geo.mat_kind
    tri_object, hid = geo.tri_object, geo.hid
    max_bounces, min_specular, scale_eta = rules.max_bounces, rules.min_specular, rules.scale_eta
    rec, rec_i, prior = out.rec, out.rec_i, out.prior
    nrec = 0
    for lane in range(rx.shape[0]):
        o, d, far = _camera_ray(cam, rx[lane], ry[lane])
        b = (1.0, 1.0, 1.0)
        ngl = nt = 0  # the camera's glossy and transmission bounces so far
        medium = -1
        bit = RAY_CAMERA  # the kind of the next ray: the camera's, then the latest event's
        for depth in range(max_bounces + 1):
            pr, t, p, g, n, b1, b2 = next_past(ray, o, d, tv, tng, tns, tri_object, hid, bit, eps)
            if pr < 0 or (depth == 0 and t > far):  # past the far clip plane the camera sees nothing
                break
            b = absorbed1(mats.kind, mats.absorb, medium, tri_material[pr], d, g, t, b)
            m = tri_material[pr]
            kind = mat_kind[m]
            if kind == DIFFUSE:
                if depth >= min_specular and receivers[tri_object[pr]]:
                    put_record(rec, rec_i, nrec, p, g, n, neg3(d), b, lane, depth, m)
                    prior[nrec, DIFFUSE_EVENTS] = 0
                    prior[nrec, GLOSSY_EVENTS], prior[nrec, TRANSMISSION_EVENTS] = ngl, nt
                    nrec += 1
                break
            if depth >= max_bounces or not (kind == CONDUCTOR or kind == DIELECTRIC):
                break
            ok, dd, bb, _ = scatter1(keyed_uniform3(key, sample[lane], depth, 0), neg3(d), n, g, m, kind, mats, b,
                                     scale_eta, False)
            if not ok:
                break
            if dot1(d, g) * dot1(dd, g) < 0:  # bounces.specular_kind
                ngl += 1
                bit = RAY_GLOSSY
            else:
                nt += 1
                bit = RAY_TRANSMISSION
            o = spawn1(p, g, dd, eps)  # tracer.spawn
            medium = medium_after1(m, kind, dd, g)
            d, b = dd, bb
    return nrec


@TypedOnce
@njit(**JIT)
def eye_lanes(rt, cam, rx, ry, sample, key, geo, receivers, mats, rules, eps, out):
    """eye.eye_receivers' paths: from the camera (cam: CameraModel.kernel_params; rx, ry: raster
    positions, each ray starting on the near clip plane) through mirrors and glass
    (optics.scatter1, the lobe picked by keyed_uniform(key, sample[lane], depth, 0): a sample's
    path does not depend on which others are traced with it; rules (EyePaths): scale_eta, radiance
    in physical units) to the first diffuse surface, recorded in out (EyeOut: rec, REC_* columns
    with the eye path's throughput; rec_i: lane, specular vertices before it, material; prior: the
    camera's diffuse, glossy and transmission bounces, Cycles' counts) where it is a receiver after
    at least rules.min_specular specular vertices; up to rules.max_bounces of them. Each ray passes
    the objects its kind does not meet (the camera's, then glossy or transmission: geo's
    Scene.hidden_kinds). Returns the records written and the ray counters (embree.ray_state)."""
    ray = ray_state(rt)
    nrec = _eye_rows(ray, cam, rx, ry, sample, key, geo, receivers, mats, rules, eps, out)
    return nrec, ray.counts
