"""Cycles' Light Paths bounce limits, as Cycles applies them to a caustic path.

Cycles counts a path's scattering events from the camera: each diffuse reflection is a
diffuse bounce, each other reflection (a mirror, a glass's reflection outside or inside) a
glossy bounce, each refraction a transmission bounce, and every one of them a bounce of the
total. The kernel's limits are the scene's Light Paths values plus one ("0 bounces" is direct
light only), and a path whose counter reaches its limit at a scattering event may still take
the light met by the very next ray, and nothing more (PATH_RAY_TERMINATE_AFTER_TRANSPARENT,
set after the increment in path_state_next).

So a caustic path (camera -> specular* -> x0 -> ... -> specular -> light, the light met by the
ray leaving its last specular vertex) is rendered exactly when its scattering events *before
the last one* count at most Diffuse diffuse bounces, Glossy glossy, Transmission transmission
and Max in all. The last event, the specular vertex next to the light, is free: with Diffuse
bounces 0 Cycles renders no caustic at all (x0's own diffuse bounce is not the last), with
Glossy 0 a glass cube still casts T T but not T R T (measured on the conformance cube:
0.657 of its caustic with Glossy 0, 0.861 with 1, nothing with Diffuse 0).

Direct light at a later diffuse vertex (next-event estimation, indirect.gather) is taken
when every event before that vertex fits the limits. ``allowed`` is the one test; the
estimators count the events (``d``, ``g``, ``t``) that it takes.

A scene without limits (built in code, or saved before they were exported) keeps 4 diffuse
bounces and no other limit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UNLIMITED = 1 << 30
DEFAULT_DIFFUSE = 4  # Cycles' default Light Paths > Diffuse, for scenes that carry no limits
# the columns of event counts (M,3) (Receivers.prior, Limits.fits) and of Limits.array(), which adds the total;
# specular_kind's codes
DIFFUSE_EVENTS, GLOSSY_EVENTS, TRANSMISSION_EVENTS, ALL_EVENTS = 0, 1, 2, 3
ONE_DIFFUSE = np.array([1, 0, 0])  # one diffuse bounce (x0's own, or a later vertex's) as event counts


@dataclass(frozen=True)
class Limits:
    """Light Paths > Max Bounces: total, diffuse, glossy, transmission (Cycles' UI values)."""

    total: int = UNLIMITED
    diffuse: int = DEFAULT_DIFFUSE
    glossy: int = UNLIMITED
    transmission: int = UNLIMITED

    @classmethod
    def of(cls, scene) -> "Limits":
        """The scene's limits (Scene.light_paths: total, diffuse, glossy, transmission; a
        negative entry is no limit, and a negative diffuse entry the default 4)."""
        total, diffuse, glossy, transmission = (int(x) for x in scene.light_paths)  # 4: Scene.validate
        return cls(total if total >= 0 else UNLIMITED, diffuse if diffuse >= 0 else DEFAULT_DIFFUSE,
                   glossy if glossy >= 0 else UNLIMITED, transmission if transmission >= 0 else UNLIMITED)

    def allowed(self, d, g, t):
        """Whether events counted d diffuse, g glossy and t transmission (scalars or arrays)
        fit: the events before a caustic path's last one, or before a vertex whose direct
        light is taken."""
        d, g, t = np.asarray(d), np.asarray(g), np.asarray(t)
        return (d <= self.diffuse) & (g <= self.glossy) & (t <= self.transmission) & (d + g + t <= self.total)

    def fits(self, cnt):
        """allowed of event counts (M,3): diffuse, glossy, transmission per row."""
        return self.allowed(cnt[:, DIFFUSE_EVENTS], cnt[:, GLOSSY_EVENTS], cnt[:, TRANSMISSION_EVENTS])

    def array(self) -> np.ndarray:
        """(diffuse, glossy, transmission, total), as the kernels take them (kernels.fits_limits; the
        *_EVENTS columns)."""
        out = np.zeros(4, np.int64)
        out[DIFFUSE_EVENTS], out[GLOSSY_EVENTS], out[TRANSMISSION_EVENTS] = self.diffuse, self.glossy, self.transmission
        out[ALL_EVENTS] = self.total
        return out

    def chain_fits(self, types: str, d=1, g=0, t=0):
        """Whether a chain of type ``types`` (letters from the receiver's side) ending at the
        light fits after events (d, g, t) before its first vertex (default: x0's own diffuse
        bounce, nothing before it). The last letter is the free event."""
        return self.allowed(d, np.asarray(g) + types[:-1].count("R"), np.asarray(t) + types[:-1].count("T"))

    def words(self) -> str:
        def w(v):
            return "no limit" if v >= UNLIMITED else str(v)

        return (f"Light Paths: max {w(self.total)}, diffuse {w(self.diffuse)}, glossy {w(self.glossy)}, "
                f"transmission {w(self.transmission)}")


def specular_kind(d_in, d_out, ng):
    """The bounce kind (the column of the counts: GLOSSY_EVENTS, TRANSMISSION_EVENTS) of specular
    events that turned rays travelling along d_in into d_out at surfaces of geometric normal ng:
    a reflection leaves on the side it came from."""
    return np.where(np.einsum("ij,ij->i", d_in, ng) * np.einsum("ij,ij->i", d_out, ng) < 0, GLOSSY_EVENTS,
                    TRANSMISSION_EVENTS)
