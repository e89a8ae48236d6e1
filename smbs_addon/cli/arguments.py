"""The command line's arguments: the parser of every command and the BakeSettings they make."""
from __future__ import annotations

import argparse
from ..baking.settings import BakeSettings, METHODS, SAMPLINGS, SEEDINGS
from ..io.sequence import parse_frames
from .exits import EXIT_USAGE

class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one clear line, not a usage dump
        self.exit(EXIT_USAGE, f"smbs_addon: error: {message}\n")


def _whole(s, least: int):
    try:
        v = int(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{s}' is not a whole number") from None
    if v < least:
        raise argparse.ArgumentTypeError(f"must be at least {least}, not {v}" if least else
                                         f"must not be negative, not {v}")
    return v


def _positive_int(s):
    return _whole(s, 1)


def _seed(s):
    return _whole(s, 0)


def _seconds(s):
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{s}' is not a number of seconds") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, not {s}")
    return v


def _target(s):
    try:
        v = float(s.rstrip("%")) / (100.0 if s.endswith("%") else 1.0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{s}' is not a relative error (0.05 or 5%)") from None
    if not (0 < v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a positive relative error such as 0.05 or 5%, not {s}")
    return v


def _clamp(s):
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{s}' is not a luminance") from None
    if not (0 <= v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be 0 (off) or a positive luminance, not {s}")
    return v


def _frames(s):
    if s.strip().lower() == "scene":
        return "scene"
    try:
        return parse_frames(s)
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"{e}; or 'scene' for the .blend's own frame range") from None


def _frame(s):
    try:
        return int(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{s}' is not a frame number") from None


def _shard(s):
    k, _, n = s.partition("/")
    try:
        k, n = int(k), int(n)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{s}' is not a shard K/N (e.g. 2/4)") from None
    if not (1 <= k <= n):
        raise argparse.ArgumentTypeError(f"'{s}': a shard K/N needs 1 <= K <= N")
    return k, n


def _methods(s):

    ms = tuple(m.strip() for m in s.split(",") if m.strip())
    bad = [m for m in ms if m not in METHODS]
    if bad or not ms:
        raise argparse.ArgumentTypeError(f"'{s}': methods are {', '.join(METHODS)}, comma-separated")
    if len(set(ms)) != len(ms):
        raise argparse.ArgumentTypeError(f"'{s}' lists a method twice")
    return ms


def _bake_options(b):
    """The settings a bake and a comparison share."""
    b.add_argument("--estimator", choices=("unbiased", "biased"), default="unbiased")
    b.add_argument("--trials", type=_positive_int, default=4, help="biased estimator: walks per lane")
    b.add_argument("--seed", type=_seed, default=0)
    b.add_argument("--pilots", type=_seed, default=4096,
                   help="plan: pilot photons per light and caster that find where its caustic lands "
                        "(0: plan by bounds only, bake every caster a light reaches)")
    b.add_argument("--batches", type=_positive_int, default=8, help="independent batches for the noise estimate")
    b.add_argument("--threads", type=_positive_int, default=None, help="worker threads (default: all cores)")
    b.add_argument("--flags", choices=("AUTO", "ON", "OFF"), default="AUTO",
                   help="honour Cycles' caustic caster/receiver/light flags")
    b.add_argument("--sampling", choices=SAMPLINGS, default=SAMPLINGS[0],
                   help="manifold methods: each pixel's sample positions and light samples over the bake 'stratified' "
                        "(default: a scrambled Sobol' sequence per pixel) or 'independent'")
    b.add_argument("--no-world-split", dest="world_split", action="store_false",
                   help="manifold methods: walk a world map's sun and sky alike, instead of walking its bright "
                        "part (a sun's disc) and path tracing the rest (a sky) from the receivers")
    b.add_argument("--no-indirect", dest="indirect", action="store_false",
                   help="leave out caustics seen after further diffuse bounces (first-order only)")
    b.add_argument("--clamp", type=_clamp, default=0.0, metavar="LUMINANCE",
                   help="manifold methods: the largest luminance one solution may add (0, the default: no "
                        "clamp); trades the fireflies of a caustic's folds for a bias the statistics report")


def _frame_options(b):
    f = b.add_mutually_exclusive_group()
    f.add_argument("--frames", type=_frames, default=None, metavar="A-B[:STEP]",
                   help="bake each frame of a range (a .blend: the scene exported at each frame), e.g. 1-250, "
                        "1-250:2, or 'scene' for the .blend's own range; frames whose EXR says it holds the same "
                        "bake are skipped (--overwrite)")
    f.add_argument("--frame", type=_frame, default=None, metavar="N", help="bake frame N of a .blend")
    b.add_argument("--overwrite", action="store_true", help="frames: bake every frame again, even those whose EXR "
                                                            "holds the same bake")
    b.add_argument("--seeding", choices=SEEDINGS, default=None,
                   help="frames: 'fixed' (default), the same random streams every frame, or 'frame', keyed by the "
                        "frame (bench/results/flicker.md measures which flickers less)")
    b.add_argument("--shard", type=_shard, default=None, metavar="K/N",
                   help="bake shard K of N of the samples (its own random streams; by --spp, spp x K // N - spp x "
                        "(K - 1) // N of them; by --noise, the target x sqrt(N)); `merge` puts the shards together")


def bake_settings(args, method: str, spp: int, time_budget: float = 0.0, noise_target: float = 0.0):

    settings = BakeSettings(method=method, spp=spp, seed=args.seed, batches=args.batches,
                            threads=args.threads or 0, use_cycles_flags=args.flags,
                            estimator=args.estimator, trials=args.trials,
                            indirect=args.indirect, time_budget=time_budget,
                            noise_target=noise_target, pilots=args.pilots, clamp_g=args.clamp,
                            sampling=args.sampling, world_split=args.world_split)
    if getattr(args, "seeding", None):
        settings.seeding = args.seeding
    settings.validate()
    return settings


def build_parser() -> argparse.ArgumentParser:

    p = _Parser(prog="python -m smbs_addon", description="Bake caustics for a Blender scene.")
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser("bake", help="bake the caustic layer to an EXR")
    b.add_argument("input", help=".blend file or exported .npz scene")
    b.add_argument("--method", choices=METHODS, default="auto",
                   help="auto (default: per light and effect the cheapest of reference, sms and smbs, by a "
                        "short pilot), smbs, sms, mnee, or the brute-force light-tracing reference")
    _bake_options(b)
    b.add_argument("--spp", type=_positive_int, default=None,
                   help="samples per pixel (default 16); with --time or --noise, per pass of --batches "
                        "batches (default: one per pixel per batch)")
    b.add_argument("--time", type=_seconds, default=None, metavar="SECONDS",
                   help="bake until this many seconds have passed (the whole bake: plan, pre-pass, walks), "
                        "refining the image in passes")
    b.add_argument("--noise", type=_target, default=None, metavar="TARGET",
                   help="bake until the estimated relative error of the layer (relative_error) is at or "
                        "below TARGET, e.g. 0.05 or 5%%; with --time too, whichever comes first")
    b.add_argument("--keep-partial", action="store_true",
                   help="with --time or --noise: when a signal (Ctrl-C, SIGTERM, SIGHUP) stops the bake, write "
                        "the whole batches done so far, with their error bar (the exit code still says a signal "
                        "stopped it)")
    _frame_options(b)
    b.add_argument("--out", default=None, help="output EXR (default: IN with .caustics.exr); for a range, a # run is "
                                               "the frame (out/caustics_####.exr), added as _#### where there is none")
    b.add_argument("--stats", default=None, help="statistics JSON (default: beside the EXR); for a range, the range's "
                                                 "summary (default: the pattern with # as 'summary', .json)")
    b.add_argument("--quiet", action="store_true")
    c = sub.add_parser("compare", help="bake with several methods for the same time and set their errors side by "
                                       "side (an equal-time table of your scene)")
    c.add_argument("input", help=".blend file or exported .npz scene")
    c.add_argument("--time", type=_seconds, required=True, metavar="SECONDS", help="seconds per method")
    c.add_argument("--methods", type=_methods, default=("reference", "sms", "smbs", "mnee"),
                   help="comma-separated, in the table's order (default: reference,sms,smbs,mnee)")
    c.add_argument("--reference", default=None, metavar="EXR",
                   help="the caustic layer to judge against (a long bake's EXR, whose std channel takes its "
                        "own noise out, or Cycles' caustics on minus off): adds RMSE and mean / reference")
    _bake_options(c)
    c.add_argument("--out", default=None, metavar="JSON", help="also write the table's numbers as JSON")
    c.add_argument("--quiet", action="store_true", help="no progress lines")
    r = sub.add_parser("prepare", help="compile the kernels now, so that the first bake on this machine does not "
                                       "(after installing or updating; cached on disk)")
    r.add_argument("--jobs", type=_positive_int, default=None,
                   help="processes compiling at once (default: one per core)")
    r.add_argument("--check", action="store_true",
                   help="compile nothing: exit 0 if the kernels are compiled for this machine, 1 if not")
    m = sub.add_parser("merge", help="merge bakes of one frame (shards, or a bake and more samples baked later) into "
                                     "one EXR, weighted by their samples, with its std and error bar")
    m.add_argument("output", help="the merged EXR (may be one of the inputs: it is replaced only when all is written)")
    m.add_argument("inputs", nargs="+", help="EXRs of bakes of one frame with other seeds or shards; # runs and "
                                             "* ? [] patterns are filled in (--frame) and matched here")
    m.add_argument("--frame", type=_frame, default=None, help="the frame whose files the # runs name")
    m.add_argument("--stats", default=None, help="statistics JSON (default: beside the EXR)")
    m.add_argument("--quiet", action="store_true")
    e = sub.add_parser("export", help="export a .blend to a .npz scene")
    e.add_argument("input")
    e.add_argument("output")
    return p
