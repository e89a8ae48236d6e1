"""Named random streams: every random number of a bake comes from a stream keyed by the seed and
what it is for, so that one seed gives the same image bit for bit whatever the thread count, the
order in which passes run, or what else the scene holds.

A stream's key is (seed, kind, ...): kind one of the constants below, then what the pass keys it
by (a light, a batch, a chunk). Lights and objects are keyed by their names (light_key), not their
indices.
"""
from __future__ import annotations

import zlib

import numpy as np

# stream kinds (the second number of a key)
PHOTONS = 0  # the light tracer's photons: (light, batch, chunk)
EYE = 1  # eye paths through mirrors and glass: (0, batch, chunk); their bent-normal part: (1, batch, chunk)
WALKS = 2  # the manifold walks: (0, batch, chunk)
GUIDE = 3  # the photon pre-pass: (0,)
HANDOFF = 4  # the photon hand-off beside the walks: (light, batch, chunk)
INDIRECT = 5  # photons after a diffuse bounce: (light, batch, chunk)
PILOT_CASTER = 7  # the plan's pilots per light and caster: (light, caster)
PILOT_INDIRECT = 8  # the plan's pilots of light after a diffuse bounce: (light,)
PILOT_VIEW = 9  # the plan's photons weighing a light's flux towards what the camera sees: (light,)
PLAN_LOOK = 10  # the plan's look from the camera (seed 0): (part,)
PILOT_BOUNCE = 11  # the plan's pilots after a diffuse bounce aimed at a left-out caster: (light, caster)
PILOT_PROBE = 12  # the plan's shadow rays probing whether a light reaches a caster: (light, caster)
STRATA = 13  # the scramble of the walks' stratified eye samples (core.qmc): (replicate,), one draw
SKY = 14  # the rest of a split world, path-traced from the receivers (paths.sky): (0, batch, chunk)

# What a bake's streams add after their own key (BakeSettings.stream_suffix), only where set, so that a
# bake of one frame, unsharded, keeps the streams (and the pixels) it always had: a shard of a frame's
# samples (K of N, keyed by K) and, with seeding "frame", the frame. Every stream of one kind has one
# length, so a suffix (a tag and a number) never makes one stream's key another's.
SHARD_TAG = 0x5348  # then the shard, 1..N
FRAME_TAG = 0x4652  # then the frame (negative frames as their 64-bit two's complement)


def light_key(name: str) -> int:
    """The key of a light or an object in a stream: its name's CRC-32."""
    return zlib.crc32(name.encode("utf-8"))


def frame_key(frame: int) -> int:
    """A frame as a stream's number: non-negative (Blender's frames may be negative)."""
    return int(frame) % (1 << 64)


def stream(seed, *key) -> np.random.Generator:
    """The generator of stream (seed, *key)."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), *[int(k) for k in key]]))
