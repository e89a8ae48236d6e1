"""EXR read/write through OpenImageIO, with statistics in the header.

Images are (H, W, C) float arrays, top row first. Files are written atomically:
a temporary file beside the target, then a rename, so a crash never leaves half
an image.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..core.errors import SceneError


def write_exr(path, image: np.ndarray, metadata: dict | None = None, extra: dict | None = None) -> Path:
    """Write a linear float32 EXR (RGB or RGBA). metadata values go in the header; extra
    maps channel names (no dots: Blender would read the file as multilayer) to (H,W)
    images stored after the colour, e.g. the bake's per-pixel ``std``."""
    import OpenImageIO as oiio

    path = Path(path)
    img = np.ascontiguousarray(image, dtype=np.float32)
    if img.ndim == 2:
        img = img[:, :, None]
    h, w, c = img.shape
    names = ("R", "G", "B", "A")[:c] if c <= 4 else tuple(f"C{i}" for i in range(c))
    for name, plane in (extra or {}).items():
        if "." in name or name in names:
            raise ValueError(f"extra channel name '{name}' must be new and without a dot")
        img = np.concatenate([img, np.asarray(plane, np.float32).reshape(h, w, 1)], axis=2)
        names += (name,)
    c = img.shape[2]
    if not path.parent.exists():
        raise SceneError(f"output folder '{path.parent}' does not exist")
    if not os.access(path.parent, os.W_OK):
        raise SceneError(f"output folder '{path.parent}' is not writable")
    if path.is_dir():
        raise SceneError(f"cannot write '{path}': it is a folder")
    spec = oiio.ImageSpec(w, h, c, oiio.FLOAT)
    spec.channelnames = names
    spec.attribute("compression", "zip")
    spec.attribute("oiio:ColorSpace", "lin_rec709")
    for k, v in (metadata or {}).items():
        if isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)):
            # float attributes are 32-bit: a seed or ray count above 2^24 would be rounded
            v = int(v)
            spec.attribute(f"smbs:{k}", v if -2**31 <= v < 2**31 else str(v))
        elif isinstance(v, (float, np.floating)):
            spec.attribute(f"smbs:{k}", float(v))
        else:
            spec.attribute(f"smbs:{k}", v if isinstance(v, str) else json.dumps(v))
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.exr")
    try:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            why = (out.geterror() if out is not None else "") or oiio.geterror() or "cannot create it"
            raise SceneError(f"cannot write '{path}': {why.replace(str(tmp), str(path))}")
        try:
            if not out.write_image(img):
                raise SceneError(f"cannot write '{path}': {out.geterror()}")
        finally:
            out.close()
        os.replace(tmp, path)
    except BaseException:  # whatever failed (or interrupted) the write: no half file is left behind
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_json(path, obj) -> Path:
    """Write obj as indented JSON through a temporary file beside path, renamed over it: a failed
    or interrupted write leaves the old file whole and no temporary file."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_text(json.dumps(obj, indent=2))
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def read_exr(path, channel: str | None = None) -> tuple[np.ndarray, dict]:
    """Read an image as (H, W, C) float32 plus its smbs:* header entries: its colour
    channels (R, G, B, A, whichever it has; all channels if it has none of them), or with
    channel, that one channel as (H, W)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise SceneError(f"cannot read image '{path}': {oiio.geterror()}")
    try:
        spec = inp.spec()
        img = inp.read_image(oiio.FLOAT)
        meta = {}
        for a in spec.extra_attribs:
            if a.name.startswith("smbs:"):
                meta[a.name[5:]] = a.value
    finally:
        inp.close()
    img = np.asarray(img, np.float32).reshape(spec.height, spec.width, spec.nchannels)
    names = list(spec.channelnames)
    if channel is not None:
        if channel not in names:
            raise SceneError(f"image '{path}' has no channel '{channel}' (it has {', '.join(names)})")
        return img[:, :, names.index(channel)], meta
    colour = [names.index(c) for c in ("R", "G", "B", "A") if c in names]
    return (img[:, :, colour] if colour else img), meta


def read_passes(path) -> dict:
    """Every channel of every part of a multi-part EXR (Blender's multilayer render: a part per pass,
    channels named 'ViewLayer.Pass.X'), as (H, W) float32 keyed 'Pass.X' (the view layer's name
    dropped): render passes to read in code, not images to look at (read_exr)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise SceneError(f"cannot read image '{path}': {oiio.geterror()}")
    out, part = {}, 0
    try:
        while inp.seek_subimage(part, 0):
            px = np.asarray(inp.read_image(oiio.FLOAT), np.float32)
            for i, name in enumerate(inp.spec().channelnames):
                out[".".join(name.rsplit(".", 2)[-2:])] = px[..., i]
            part += 1
    finally:
        inp.close()
    return out


def exr_metadata(settings, result) -> dict:
    """The EXR header entries of a bake (also written by the Blender operator)."""
    st = result.stats
    meta = {"method": settings.method, "spp": settings.spp, "seed": settings.seed,
            "time_s": st["time_s"], "rays": st["rays"],
            "noise_relative": st["noise"]["relative_noise"], "stats": st}
    for key in ("relative_error", "seconds_to_halve_error"):  # absent (None): not measurable
        if st.get(key) is not None:
            meta[key] = float(st[key])
    if getattr(result, "per_albedo", None) is not None:  # a pipeline reading R, G, B alone would miss it
        meta["composite"] = ("R, G, B + per_albedo_R, _G, _B x the render's Diffuse Color pass (the caustic on "
                             "textured receivers seen directly, per unit albedo)")
    return meta


def exr_channels(result) -> dict:
    """The EXR's channels beside the colour: ``std``, each pixel's standard deviation of
    the mean luminance (where the noise is, for a compositor); with textured receivers
    ``per_albedo_R``, ``_G``, ``_B`` (BakeResult.per_albedo: the caustic on them per unit albedo,
    for the render's Diffuse Color pass to multiply; the colour is then BakeResult.layer())."""
    std = getattr(result, "std", None)
    out = {} if std is None else {"std": std}
    per_albedo = getattr(result, "per_albedo", None)
    if per_albedo is not None:
        out.update({f"per_albedo_{c}": per_albedo[:, :, i] for i, c in enumerate("RGB")})
    return out
