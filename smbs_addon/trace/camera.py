"""Blender's camera model: view plane, sensor fit, shift, clipping, border.

Raster coordinates: x from the left edge (0..W), y from the TOP edge (0..H),
pixel (i, j) covers [i, i+1) x [j, j+1); images are (H, W, C) top row first.
The view plane follows Blender's ``BKE_camera_params_compute_viewplane``: the
fitted sensor dimension spans the fitted image dimension, shift is a fraction
of that dimension, and the view plane sits at distance 1 (perspective) or is
the ortho window itself (orthographic).
"""
from __future__ import annotations

import numpy as np

from ..scene import arrays as S
from ..core.vec import normalize
from ..kernels import eye
def _border_pixel(frac: float, size: int) -> int:
    """Blender's ``rcti`` border edge: float32(frac) * size, truncated to an int."""
    return int(np.float32(frac) * np.float32(size))


class CameraModel:
    def __init__(self, cam: S.Camera):
        self.cam = cam
        self.W, self.H = cam.width, cam.height
        m = np.asarray(cam.matrix_world, float)
        rot = m[:3, :3]
        self.axes = rot / np.linalg.norm(rot, axis=0)  # columns: x, y, z (scale removed)
        # world -> camera is the true inverse (as in Blender and Cycles): a camera under a
        # non-uniformly scaled parent has sheared, non-orthogonal axes
        self.inv_axes = np.linalg.inv(self.axes)
        self.origin = m[:3, 3].copy()
        self.ortho = cam.type == S.ORTHO
        aspx, aspy = cam.pixel_aspect_x, cam.pixel_aspect_y
        self.ycor = aspy / aspx
        fit = cam.sensor_fit
        if fit == "AUTO":
            horizontal = aspx * self.W >= aspy * self.H
            sensor = cam.sensor_width
        else:
            horizontal = fit == "HORIZONTAL"
            sensor = cam.sensor_width if horizontal else cam.sensor_height
        viewfac = self.W if horizontal else self.ycor * self.H
        pix = (cam.ortho_scale if self.ortho else sensor / cam.lens) / viewfac
        dx, dy = cam.shift_x * viewfac, cam.shift_y * viewfac
        self.xmin = (-0.5 * self.W + dx) * pix
        self.ymin = (-0.5 * self.ycor * self.H + dy) * pix
        self.pix_w = pix  # pixel width on the view plane
        self.pix_h = pix * self.ycor
        self.pixel_area = self.pix_w * self.pix_h
        # render region in raster pixels (x0, x1, y0, y1), y from the top. Blender
        # (re_init_resolution) truncates border * size computed in single precision.
        if cam.use_border:
            bx0, bx1, by0, by1 = (_border_pixel(f, n) for f, n in
                                  zip(cam.border, (self.W, self.W, self.H, self.H)))
            # inside the frame whatever the border says (Scene.validate refuses fractions out of
            # 0..1): the film and the splat kernels index pixels by this region
            bx0, bx1 = min(max(bx0, 0), self.W), min(max(bx1, 0), self.W)
            by0, by1 = min(max(by0, 0), self.H), min(max(by1, 0), self.H)
            self.region = (bx0, bx1, self.H - by1, self.H - by0)
        else:
            self.region = (0, self.W, 0, self.H)

    # ------------------------------------------------------------ projection
    def to_camera(self, p: np.ndarray) -> np.ndarray:
        return (p - self.origin) @ self.inv_axes.T

    def project(self, p: np.ndarray):
        """World points -> (raster x, raster y from top, depth, cos to axis, distance).

        depth is the distance along the view axis; valid where inside the clip
        range and in front of the camera."""
        c = self.to_camera(p)
        depth = -c[:, 2]
        if self.ortho:
            fx, fy = c[:, 0], c[:, 1]
            dist = depth
            cos = np.ones(len(p))
        else:
            safe = np.where(depth > 0, depth, 1.0)
            fx, fy = c[:, 0] / safe, c[:, 1] / safe
            v = p - self.origin
            dist = np.sqrt((v * v).sum(1))  # world distance (equal to |c| unless sheared)
            cos = np.divide(depth, dist, out=np.zeros_like(dist), where=dist > 0)
        rx = (fx - self.xmin) / self.pix_w
        ry = self.H - (fy - self.ymin) / self.pix_h
        valid = (depth >= self.cam.clip_start) & (depth <= self.cam.clip_end)
        return rx, ry, depth, cos, dist, valid

    def rays(self, rx: np.ndarray, ry: np.ndarray):
        """Camera rays through raster positions: origins (N,3), unit directions (N,3),
        and the distance along each ray to the near clip plane."""
        fx = self.xmin + rx * self.pix_w
        fy = self.ymin + (self.H - ry) * self.pix_h
        n = len(rx)
        if self.ortho:
            local_o = np.stack([fx, fy, np.zeros(n)], -1)
            local_d = np.tile([0.0, 0.0, -1.0], (n, 1))
        else:
            local_o = np.zeros((n, 3))
            local_d = normalize(np.stack([fx, fy, -np.ones(n)], -1))
        o = self.origin + local_o @ self.axes.T
        d = local_d @ self.axes.T
        stretch = np.sqrt((d * d).sum(1))  # 1 unless the axes are sheared
        d = d / stretch[:, None]
        tnear = self.cam.clip_start * stretch / np.abs(local_d[:, 2])
        return o, d, tnear

    def clip_far(self, d: np.ndarray) -> np.ndarray:
        """The distance along camera rays of unit directions d (N,3) from the near clip plane,
        where rays() starts them, to the far one: Cycles clips by depth, not by distance."""
        per_depth = 1.0 / np.abs(d @ self.inv_axes[2])  # the rays' length per unit of depth
        return (self.cam.clip_end - self.cam.clip_start) * per_depth

    def kernel_params(self) -> np.ndarray:
        """What rays(), towards() and importance() need, for the kernels (kernels.CAM_* entries:
        eye._camera_ray, eye.camera_splats)."""
        return np.concatenate([self.origin, self.axes.ravel(),
                               [self.xmin, self.ymin, self.pix_w, self.pix_h, self.H, float(self.ortho),
                                self.cam.clip_start, self.cam.clip_end, self.pixel_area], self.inv_axes.ravel(),
                               np.asarray(self.region, np.float64)]).astype(np.float64)

    def pixel_rays(self, step: int = 1):
        """Rays through the centres of the render region's pixels (every step-th on each
        axis): (rows, columns, origins on the near clip plane, unit directions)."""
        x0, x1, y0, y1 = self.region
        jj, ii = np.mgrid[y0:y1:step, x0:x1:step]
        jj, ii = jj.ravel(), ii.ravel()
        return (jj, ii) + self.centre_rays(jj, ii)

    def centre_rays(self, jj: np.ndarray, ii: np.ndarray):
        """Rays through the centres of pixels (rows jj, columns ii): (origins on the near clip
        plane, unit directions), as rays() makes them."""
        return eye.camera_rays(self.kernel_params(), ii + 0.5, jj + 0.5)

    def towards(self, p: np.ndarray, margin: float = 0.0):
        """Connections of world points to the camera: raster positions, unit directions to
        the camera, the distance to leave clear up to the near clip plane, cos to the view
        axis, distance, and valid (in front, within the clip range, inside the render
        region widened by margin pixels)."""
        rx, ry, depth, cos_axis, dist, valid = self.project(p)
        x0, x1, y0, y1 = self.region
        valid &= (rx > x0 - margin) & (rx < x1 + margin) & (ry > y0 - margin) & (ry < y1 + margin)
        if self.ortho:
            to_cam = np.broadcast_to(self.axes[:, 2], p.shape).copy()
            tmax = depth - self.cam.clip_start
        else:
            v = self.origin - p
            to_cam = v / np.maximum(np.sqrt((v * v).sum(1)), 1e-300)[:, None]
            tmax = dist * (1.0 - self.cam.clip_start / np.maximum(depth, 1e-300))
        return rx, ry, to_cam, tmax, cos_axis, dist, valid

    def importance(self, cos_axis: np.ndarray, dist: np.ndarray, cos_surface: np.ndarray):
        """Sensor response per unit of outgoing radiance-weighted flux, before the
        pixel filter: a light-path vertex with throughput beta and BSDF value f
        adds beta * f * importance * filter weight to a pixel.

        Perspective: |cos_y| / (d^2 * a_pix * cos^3 theta); orthographic: |cos_y| / a_pix."""
        if self.ortho:
            return np.abs(cos_surface) / self.pixel_area
        c3 = np.maximum(cos_axis, 1e-12) ** 3
        return np.abs(cos_surface) / (np.maximum(dist, 1e-300) ** 2 * self.pixel_area * c3)
