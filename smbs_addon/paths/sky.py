"""The rest of a split world (shading.world_parts: its sky, without the sun's disc), by path tracing from
the receivers: every eye sample's receiver x0, whether the camera sees it directly or through mirrors
or glass, bounces once (cosine) through the specular chain after it, and the sky seen right after a
specular vertex on a caster counts (x0's own caustic), as do the sky's caustic at later diffuse
vertices and, for lights_direct, the sky lighting a later diffuse vertex once a specular vertex on a
caster lies behind (indirect.gather, the light tracer's estimator, complete for these paths). A sky's
radiance is bounded and broad, so a bounce finds it at once; where the walks meet it, near the folds,
it is rare and huge.
"""
from __future__ import annotations

from ..kernels.records import EyePaths
from ..trace.eye import BatchPart, eye_receivers
from .gather import GatherLights, gather


def trace_sky(scene, tracer, cam, film, plan, li: int, part: BatchPart, rng, stats, physical=False, direct=(),
              strata=None) -> None:
    """Eye samples `part` of a batch to their receivers (as the walks' are: eye.eye_receivers), then
    indirect.gather's paths from each, counting light li (scene: the one lit by the sky alone) where
    it is hit after a specular vertex on a caster, and its direct light at later diffuse vertices for
    direct (li or nothing); splatted on film. strata: the eye samples stratified (eye.film_samples)."""
    rc = eye_receivers(scene, tracer, cam, film, plan, part, rng, stats, EyePaths(min_specular=0, scale_eta=physical),
                       strata=strata)
    gather(scene, tracer, film, plan, rc, rng, stats, GatherLights(direct=tuple(direct), hit=(li,), count_first=True),
           physical=physical)
