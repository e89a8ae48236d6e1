"""Make docs/images/glass_sphere.png: a Cycles render with its caustics off, beside the same
render with the baked caustic layer added, as the add-on's compositor adds it.

    PYTHONPATH=. .venv/bin/python docs/images/make_result_image.py [--percent 200] [--samples 128] [--spp 256]

1. Cycles renders sample_blends/glass_sphere.blend with Light Paths > Caustics off (a linear
   multilayer EXR with the Diffuse Color pass), at --percent of its resolution.
2. ``python -m smbs_addon bake`` bakes the caustic layer of the same scene at the same size.
3. The layer is added to the render in linear light: R, G, B, plus per_albedo x Diffuse Color
   where the bake wrote per_albedo channels (textured receivers), then both halves go through the
   scene's view transform (Standard: the sRGB curve, clipped) and are set side by side.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
BLEND = ROOT / "sample_blends" / "glass_sphere.blend"
OUT = Path(__file__).resolve().parent / "glass_sphere.png"

RENDER = """
import bpy, sys
src, copy, exr, pct, spp = sys.argv[-5:]
bpy.ops.wm.open_mainfile(filepath=src)
s = bpy.context.scene
s.render.resolution_percentage = int(pct)
bpy.ops.wm.save_as_mainfile(filepath=copy, copy=True)  # the bake reads this copy: same camera, same size
s.cycles.caustics_reflective = s.cycles.caustics_refractive = False
s.cycles.samples = int(spp)
s.cycles.device = 'CPU'
s.render.use_compositing = False
bpy.context.view_layer.use_pass_diffuse_color = True
s.render.image_settings.media_type = 'MULTI_LAYER_IMAGE'  # Blender 5.0: a multilayer OpenEXR
s.render.image_settings.color_depth = '32'
s.render.filepath = exr
bpy.ops.render.render(write_still=True)
"""


def read_channels(path: Path) -> dict[str, np.ndarray]:
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    pixels = buf.get_pixels(oiio.FLOAT)  # (H, W, C), top row first
    return {name: pixels[:, :, i] for i, name in enumerate(buf.spec().channelnames)}


def rgb(channels: dict, prefix: str) -> np.ndarray:
    names = [next(k for k in channels if k.endswith(f"{prefix}{c}")) for c in "RGB"]
    return np.stack([channels[n] for n in names], axis=2)


def srgb(linear: np.ndarray) -> np.ndarray:
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--percent", type=int, default=200, help="of the scene's 160 x 120")
    p.add_argument("--samples", type=int, default=128, help="Cycles samples")
    p.add_argument("--spp", type=int, default=256, help="the bake's samples per pixel")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", type=Path, default=OUT)
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        copy, render, layer = tmp / "scene.blend", tmp / "off.exr", tmp / "layer.exr"
        subprocess.run([sys.executable, "-c", RENDER, str(BLEND), str(copy), str(render), str(a.percent),
                        str(a.samples)], check=True)
        subprocess.run([sys.executable, "-m", "smbs_addon", "bake", str(copy), "--spp", str(a.spp),
                        "--seed", str(a.seed), "--out", str(layer)], check=True, cwd=ROOT)
        r, c = read_channels(render), read_channels(layer)
    off = rgb(r, "Combined.")
    on = off + np.stack([c["R"], c["G"], c["B"]], axis=2)
    if "per_albedo_R" in c:  # textured receivers: per unit albedo x the render's Diffuse Color pass
        on += rgb(c, "per_albedo_") * rgb(r, "DiffCol.")
    halves = [srgb(off), srgb(on)]
    gap = np.ones((off.shape[0], 4, 3))
    image = (np.concatenate([halves[0], gap, halves[1]], axis=1) * 255 + 0.5).astype(np.uint8)

    from PIL import Image, ImageDraw, ImageFont

    img = Image.fromarray(image)
    draw = ImageDraw.Draw(img)
    try:
        font = ImageFont.truetype("DejaVuSans.ttf", 13)
    except OSError:
        font = ImageFont.load_default()
    w = off.shape[1]
    for x, text in ((6, "Cycles, caustics off"), (w + 4 + 6, "+ baked caustic layer")):
        draw.text((x, 5), text, fill=(255, 255, 255), font=font, stroke_width=2, stroke_fill=(0, 0, 0))
    a.out.parent.mkdir(parents=True, exist_ok=True)
    img.save(a.out, optimize=True)
    print(f"wrote {a.out} ({img.width} x {img.height})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
