"""``python -m smbs_addon bake IN.blend --frames A-B[:STEP]`` (or ``--frame N``): a frame range.

The .blend is opened once and its scene exported at each frame (``frame_set``: animated transforms,
lights, camera, modifiers and shape keys, world); each frame is baked as a bake of that scene alone
(its image depends only on the scene at that frame, the settings and the seed: frame 12 of a range is
frame 12 baked alone, bit for bit) and written, with its statistics JSON, to the output pattern with
the frame for its ``#`` run (io.sequence), whole or not at all (io.exr.save_outputs). A second run
skips a frame whose EXR says it holds the same bake (the same code, settings and scene: the same
pixels), unless --overwrite. The range's summary (baking.frames.RangeSummary: per frame time, rays,
error bar; totals; flicker) goes beside the frames, also when a frame fails or a signal stops the
range: the frames written are kept, and the message names the frame that failed.
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from ..baking.bake import bake
from ..baking.engine import check_samples
from ..baking.frames import RangeSummary
from ..core import signals
from ..core.errors import BakeCancelled, SceneError, WriteError
from ..core.version import code_version
from ..io.exr import json_writer, read_channels, read_header, remove_stale, save_outputs
from ..io.sequence import frame_path, summary_path, with_frames
from .exits import EXIT_OK, EXIT_USAGE, cancelled
from .inputs import NpzInput, check_writable
from .outputs import albedo_for, bake_outputs, header_says_same, stats_of


@dataclasses.dataclass
class FrameRun:
    """A range bake's fixed parts: the input, its frames, the settings, where each frame goes."""

    inp: object
    frames: list
    settings: object
    pattern: Path
    stats: Path | None  # a single --frame's statistics JSON (args.stats), else beside each EXR
    overwrite: bool
    say: object
    progress: object
    warn: object
    keep_partial: bool = False

    def paths(self, f: int) -> tuple[Path, Path]:
        out = frame_path(self.pattern, f)
        return out, self.stats if self.stats is not None else out.with_suffix(".json")


def frames_of(args, inp) -> list:
    """The frames asked for: --frame N, --frames A-B[:STEP], or --frames scene (the .blend's range)."""
    if args.frame is not None:
        return [args.frame]
    if args.frames == "scene":
        first, last, step = inp.frame_range()
        return list(range(first, last + 1, max(step, 1)))
    return list(args.frames)


def range_command(args, settings, inp, progress, say) -> int:
    """Bake the frames (see the module's notes); the exit code of the range."""
    if isinstance(inp, NpzInput):
        print("smbs_addon: error: an .npz scene holds one frame; --frames and --frame need the .blend",
              file=sys.stderr)
        return EXIT_USAGE
    frames = frames_of(args, inp)
    out = Path(args.out) if args.out else Path(args.input).with_suffix(".caustics.exr")
    ranged = args.frames is not None
    pattern = with_frames(out) if ranged else out
    summary_file = (Path(args.stats) if args.stats else summary_path(pattern)) if ranged else None
    for p in (frame_path(pattern, frames[0]), summary_file):
        if p is not None:
            check_writable(p)
    warn = lambda m: print(f"warning: {m}", file=sys.stderr)  # noqa: E731
    run = FrameRun(inp, frames, settings, pattern, None if ranged else (Path(args.stats) if args.stats else None),
                   args.overwrite, say, progress, warn, args.keep_partial)
    summary = RangeSummary(frames, dataclasses.asdict(settings), str(pattern),
                           frames[1] - frames[0] if len(frames) > 1 else 1)
    code = EXIT_OK
    try:
        for i, f in enumerate(frames):
            code = _frame(run, summary, i, f)
            if code != EXIT_OK:
                break
    except BakeCancelled as e:
        signum = e.signum or signals.requested()
        _write_summary(summary_file, summary, say)
        done = [r["frame"] for r in summary.rows if r["status"] in ("baked", "skipped")]
        print(f"smbs_addon: {f'stopped by {signals.name(signum)}' if signum else 'cancelled'} at frame {f}; "
              f"nothing of it was written{_kept(done)}", file=sys.stderr)
        return cancelled(signum)
    except (SceneError, OSError) as e:
        summary.add(f, "failed", str(run.paths(f)[0]), error=str(e))
        _write_summary(summary_file, summary, say)
        done = [r["frame"] for r in summary.rows if r["status"] in ("baked", "skipped")]
        kind = type(e) if not isinstance(e, WriteError) else OSError
        raise kind(f"frame {f}: {e}{_kept(done)}") from None
    _write_summary(summary_file, summary, say)
    if ranged:
        _say_range(summary, say)
    return code


def _kept(done) -> str:
    if not done:
        return ""
    return f" (frames written and kept: {_spans(done)})"


def _spans(frames) -> str:
    """1, 2, 3, 5 -> '1-3, 5'."""
    out, start, prev = [], None, None
    for f in frames:
        if start is None:
            start = prev = f
        elif f == prev + 1:
            prev = f
        else:
            out.append(f"{start}-{prev}" if prev != start else f"{start}")
            start = prev = f
    if start is not None:
        out.append(f"{start}-{prev}" if prev != start else f"{start}")
    return ", ".join(out)


def _up_to_date(run, out, stats_path, settings, digest) -> tuple[bool, str]:
    """(skip?, why not) for a frame whose EXR may exist already."""
    if run.overwrite or not out.exists():
        return False, ""
    meta = read_header(out)
    why = header_says_same(meta, settings, digest, code_version())
    if why is None and not stats_path.exists():
        why = f"no {stats_path.name} beside it"
    return why is None, why or ""


def _frame(run, summary, i, f) -> int:
    """Bake frame f (the i-th), or skip it; EXIT_OK, or the exit code a signal's partial bake has."""
    signals.check()
    out, stats_path = run.paths(f)
    for p in (out, stats_path):
        remove_stale(p)
        check_writable(p)
    scene = run.inp.scene_at(f, run.warn)
    settings = dataclasses.replace(run.settings, frame=int(f))
    digest = scene.digest()
    skip, why = _up_to_date(run, out, stats_path, settings, digest)
    if skip:
        channels, meta = read_channels(out)
        rgb = [channels[c] for c in "RGB"]
        summary.add(f, "skipped", str(out), stats_of(meta), np.stack(rgb, axis=-1), channels.get("std"))
        run.say(f"frame {f}: {out} holds this bake already (the same code, settings and scene), skipped")
        return EXIT_OK
    if why:
        run.say(f"frame {f}: {out} holds another bake ({why}); baking it again")
    check_samples(scene, settings)
    n = len(run.frames)

    def progress(frac, msg):
        run.progress((i + frac) / n, f"frame {f} ({i + 1}/{n}): {msg}")

    result = bake(scene, settings, progress=progress, keep_partial=run.keep_partial)
    albedo = albedo_for(run.inp, scene, result, run.warn)
    outputs, rgb, std = bake_outputs(settings, result, out, stats_path, albedo, digest)
    signals.check()
    save_outputs(outputs, before_replace=signals.check)
    summary.add(f, "baked", str(out), result.stats, rgb, std)
    err = result.stats.get("relative_error")
    run.say(f"frame {f}: {result.stats['time_s']:.1f} s, {result.stats['rays']:,} rays, "
            f"error {'+-%.1f%%' % (100 * err) if err is not None else 'unknown'}; wrote {out}")
    if result.stats.get("stopped_by") == "signal":
        return cancelled(signals.requested())
    return EXIT_OK


def _write_summary(path, summary, say) -> None:
    if path is None or not summary.rows:
        return
    save_outputs([(path, json_writer(summary.to_dict()))])
    say(f"wrote {path}")


def _say_range(summary, say) -> None:
    d = summary.to_dict()
    t, fl = d["totals"], d["flicker"]
    say(f"frames: {t['baked']} baked, {t['skipped']} skipped (up to date), {t['time_s']:.1f} s, {t['rays']:,} rays"
        + (f", error +-{t['relative_error_max']:.1%} at most" if t["relative_error_max"] is not None else ""))
    if fl["pairs"]:
        say(f"flicker: {fl['measured']:.1%} RMS change from frame to frame on the caustic, {fl['predicted']:.1%} "
            f"from the error bars of independent noise ({fl['pairs']} pairs)")

