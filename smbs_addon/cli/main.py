"""Command line: ``python -m smbs_addon bake IN [options]``, ``... compare IN --time S``
(an equal-time table of the scene's methods), ``... export IN OUT`` and ``... prepare`` (compile
the kernels before the first bake).

IN is a .blend file (opened with the bpy module) or an exported .npz scene.
Exit codes a render farm can trust: 0 done (also for a scene with no caustic to
bake: its layer is all zero and the output says why), 1 the scene cannot be baked,
2 bad arguments, 3 unreadable input or unwritable output, 130 cancelled; ``prepare --check``:
0 the kernels are compiled for this machine, 1 not (or no telling).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..core.compiles import counted

EXIT_OK, EXIT_SCENE, EXIT_USAGE, EXIT_IO, EXIT_CANCELLED = 0, 1, 2, 3, 130
EXIT_NOT_READY = 1  # prepare --check


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


def _methods(s):
    from ..baking.settings import METHODS

    ms = tuple(m.strip() for m in s.split(",") if m.strip())
    bad = [m for m in ms if m not in METHODS]
    if bad or not ms:
        raise argparse.ArgumentTypeError(f"'{s}': methods are {', '.join(METHODS)}, comma-separated")
    if len(set(ms)) != len(ms):
        raise argparse.ArgumentTypeError(f"'{s}' lists a method twice")
    return ms


def _prepare(args, say) -> int:
    """python -m smbs_addon prepare: compile the kernels (smbs_addon.baking.prepare)."""
    from ..baking import prepare

    if args.check:  # for scripts: prepare --check || prepare
        state = prepare.ready()
        say({True: "kernels: compiled for this machine; bakes load them from the cache",
             False: "kernels: not compiled for this code on this machine; the first bake compiles them "
                    "(a few minutes), `python -m smbs_addon prepare` does it now",
             None: "kernels: cannot tell whether they are compiled (this numba keeps its cache otherwise)"}[state])
        return EXIT_OK if state else EXIT_NOT_READY
    out = prepare.prepare(args.jobs, say=say)
    say(f"prepared: {counted(out['kernels'], 'kernel')} compiled in {out['seconds']:.1f} s "
        f"({counted(out['jobs'], 'process')}); bakes on this machine load them from the cache")
    return EXIT_OK


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
    b.add_argument("--no-indirect", dest="indirect", action="store_false",
                   help="leave out caustics seen after further diffuse bounces (first-order only)")
    b.add_argument("--clamp", type=_clamp, default=0.0, metavar="LUMINANCE",
                   help="manifold methods: the largest luminance one solution may add (0, the default: no "
                        "clamp); trades the fireflies of a caustic's folds for a bias the statistics report")


def _settings(args, method: str, spp: int, time_budget: float = 0.0, noise_target: float = 0.0):
    from ..baking.settings import BakeSettings

    settings = BakeSettings(method=method, spp=spp, seed=args.seed, batches=args.batches,
                            threads=args.threads or 0, use_cycles_flags=args.flags,
                            estimator=args.estimator, trials=args.trials,
                            indirect=args.indirect, time_budget=time_budget,
                            noise_target=noise_target, pilots=args.pilots, clamp_g=args.clamp)
    settings.validate()
    return settings


def build_parser() -> argparse.ArgumentParser:
    from ..baking.settings import METHODS

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
    b.add_argument("--out", default=None, help="output EXR (default: IN with .caustics.exr)")
    b.add_argument("--stats", default=None, help="statistics JSON (default: beside the EXR)")
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
    e = sub.add_parser("export", help="export a .blend to a .npz scene")
    e.add_argument("input")
    e.add_argument("output")
    return p


def load_input(path: str, warn=print):
    """A Scene from a .npz or a .blend (the latter through the bpy module)."""
    from ..core.errors import SceneError
    from ..scene.arrays import Scene

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"input '{path}' does not exist")
    if p.suffix.lower() == ".npz":
        return Scene.load(p)
    if p.suffix.lower() == ".blend":
        # imported here, not at the top: bpy takes seconds to load and an .npz input does not need
        # it (without bpy, this import raises SceneError saying so)
        from ..blender.open_blend import open_blend

        return open_blend(path, warn)
    raise SceneError(f"input '{path}': expected a .blend or .npz file")


def _check_writable(path: Path):
    parent = path.parent if str(path.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise OSError(f"output folder '{parent}' is a file")
    if not parent.is_dir():
        raise OSError(f"output folder '{parent}' does not exist")
    if not os.access(parent, os.W_OK):
        raise OSError(f"output folder '{parent}' is not writable")
    if path.is_dir():
        raise OSError(f"output '{path}' is a folder")


def _cap_note(trials: dict) -> str:
    share = trials.get("capped_share_min", 0.0)
    return f" (at least {share:.1%} of the layer missing: raise max_trials)" if trials.get("capped") else ""


def summary_lines(stats: dict) -> list[str]:
    lines = [f"scene '{stats['scene']}': {stats['method']}, {stats['resolution'][0]}x{stats['resolution'][1]}, "
             f"{stats['time_s']:.2f} s, {stats['rays']:,} rays"]
    if stats.get("nothing_to_bake"):
        return lines + [f"  nothing to bake: {stats['nothing_to_bake']}; the caustic layer is all zero"]
    if stats.get("compile_s"):
        lines.append(f"  of which compiling the kernels for this machine: {stats['compile_s']:.1f} s "
                     f"({counted(stats.get('kernels_compiled', 0), 'kernel')}; once after installing or updating, "
                     f"later bakes load them from the cache)")
    plan = stats.get("plan", {})
    if plan.get("rays"):
        lines.append(f"  plan: {plan['rays']:,} rays ({plan.get('pilot_photons', 0):,} pilot photons), "
                     f"{plan['time_s']:.2f} s")
    if "walks" in stats:
        lines.append(f"  manifold walks: {stats['walks']:,}, success rate {stats['success_rate']:.1%}, "
                     f"{stats['mutations_per_path']:.2f} mutations per path "
                     f"({stats['mutations_per_success']:.1f} per solution found), "
                     f"chains {', '.join(stats['chain_types'])}")
    for name, s in stats["lights"].items():
        if "walks" in s:
            lm = ", ".join(f"{k} {v:,}" for k, v in s.get("large_mutations", {}).items())
            lines.append(f"  light '{name}': {s['walks']:,} walks, success {s['success_rate']:.1%}, "
                         f"{s['mutations_per_path']:.2f} mutations/path ({s['mutations_per_success']:.1f}/solution), "
                         f"large mutations ({lm}), "
                         f"trials mean {s['trials']['mean']:.2f} max {s['trials']['max']} capped {s['trials']['capped']}"
                         f"{_cap_note(s['trials'])}, "
                         f"{s['rays']:,} rays, {s['time_s']:.2f} s")
        else:
            lines.append(f"  light '{name}': {s['photons']:,} light paths, {s['splats']:,} reached the camera, "
                         f"{s['rays_photon'] + s['rays_camera']:,} rays, {s['time_s']:.2f} s")
    for sk in stats["skipped"]:  # also in the plan's words, printed before the bake
        lines.append(f"  skipped {sk['kind']} '{sk['name']}': {sk['reason']}")
    nz = stats["noise"]
    lines.append(f"  noise: mean {nz['mean']:.4g} over {nz['region_pixels']} caustic pixels, "
                 f"standard error {nz['std_error_of_mean']:.2g}, per-pixel relative noise {nz['relative_noise']:.1%}")
    lines.extend(error_lines(stats))
    if "textured_share" in stats:
        lines.append(f"  textured receivers: {stats['textured_share']:.0%} of the layer lies on them where the camera "
                     f"sees them; it is written per unit albedo (channels per_albedo_R/G/B) for the render's "
                     f"Diffuse Color pass to multiply, and left out of the colour channels")
    return lines


def error_lines(stats: dict) -> list[str]:
    """The bake's error bar and its price, in words (the CLI's summary)."""
    err, halve = stats.get("relative_error"), stats.get("seconds_to_halve_error")
    conv = stats.get("convergence", {})
    if not stats["noise"]["region_pixels"]:
        return ["  error: no caustic in the image, nothing to measure"]
    if err is None:
        return ["  error: unknown (one batch: no spread to measure; bake at least two)"]
    line = f"  error: +-{err:.1%} relative RMS per caustic pixel"
    if halve:
        line += (f"; halving it would take about {_duration(halve)} more "
                 f"({conv.get('seconds_per_batch', 0.0):.2f} s per batch, 4x the batches)")
    out = [line]
    if stats.get("error_leaves_out"):
        out.append("  the error counts noise only, not " + "; ".join(stats["error_leaves_out"]))
    if conv.get("heavy_tail"):
        out.append("  warning: the error is not yet falling as the batches add up (rare bright paths "
                   "still turn up), so it and the time to halve it are optimistic")
    stop = stats.get("stopped_by")
    if stop in ("time", "noise"):
        out.append(f"  stopped by the {stop} rule after {stats.get('batches_done', 0)} batches")
    budget = stats.get("settings", {}).get("time_budget", 0.0)
    work = stats.get("time_s", 0.0) - stats.get("compile_s", 0.0)  # the time rule's clock
    if stop == "time" and stats.get("batches_done", 0) <= 2 and work > 1.1 * budget:
        out.append(f"  warning: the {budget:g} s budget was shorter than the plan, the pre-pass and the two "
                   f"batches an error bar needs ({work:.1f} s)")
    return out


def _duration(s: float) -> str:
    if s < 90:
        return f"{s:.0f} s" if s >= 10 else f"{s:.1f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


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


def _compare(args, say) -> int:
    """python -m smbs_addon compare: an equal-time table of the scene (smbs_addon.baking.compare)."""
    from ..baking.compare import Reference, compare, json_report, table_lines
    from ..io.exr import write_json

    settings = _settings(args, args.methods[0], args.batches)  # one sample per pixel per batch
    out = Path(args.out) if args.out else None
    if out is not None:
        _check_writable(out)
    if args.reference and not Path(args.reference).is_file():
        raise FileNotFoundError(f"reference '{args.reference}' does not exist")
    ref = Reference.from_exr(args.reference) if args.reference else None
    scene = load_input(args.input, warn=lambda m: print(f"warning: {m}", file=sys.stderr))
    n = len(args.methods)

    def progress(i, m):
        if not args.quiet:
            print(f"[{i + 1}/{n}] {m}: {args.time:g} s", file=sys.stderr, flush=True)

    report = compare(scene, args.methods, args.time, settings, ref, progress=progress)
    if out is not None:
        write_json(out, json_report(report))
    print(f"scene '{scene.name}'")
    for line in table_lines(report):
        print(line)
    if out is not None:
        say(f"wrote {out}")
    return EXIT_OK


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from ..core.errors import BakeCancelled, SceneError

    say = (lambda *a: None) if getattr(args, "quiet", False) else print
    try:
        if args.command == "export":
            out = Path(args.output)
            _check_writable(out)
            load_input(args.input, warn=lambda m: print(f"warning: {m}", file=sys.stderr)).save(out)
            say(f"wrote {out}")
            return EXIT_OK
        if args.command == "compare":
            return _compare(args, say)
        if args.command == "prepare":
            return _prepare(args, say)
        from ..baking.bake import bake
        from ..io.exr import write_exr, write_json

        stop_rule = args.time is not None or args.noise is not None
        spp = args.spp if args.spp is not None else (args.batches if stop_rule else 16)
        settings = _settings(args, args.method, spp, args.time or 0.0, args.noise or 0.0)
        out = Path(args.out) if args.out else Path(args.input).with_suffix(".caustics.exr")
        stats_path = Path(args.stats) if args.stats else out.with_suffix(".json")
        _check_writable(out)
        _check_writable(stats_path)
        scene = load_input(args.input, warn=lambda m: print(f"warning: {m}", file=sys.stderr))

        tty = sys.stderr.isatty()
        last = [""]

        def progress(frac, msg):
            if args.quiet:
                return
            if tty:
                print(f"\r{frac:6.1%} {msg}", end="", file=sys.stderr, flush=True)
            elif msg != last[0]:  # logs (render farms): one line per stage
                print(f"{frac:6.1%} {msg}", file=sys.stderr, flush=True)
                last[0] = msg

        headed = []

        def on_plan(lines):  # before any caustic is traced (auto adds its choices after its pilots)
            if not headed:
                say("plan:")
                headed.append(True)
            for line in lines:
                say(f"  {line}")

        result = bake(scene, settings, progress=progress, on_plan=on_plan)
        if not args.quiet and tty:
            print(file=sys.stderr)
        try:
            write_exr(out, result.layer(), exr_metadata(settings, result), exr_channels(result))
        except SceneError as e:  # an output that cannot be written is an I/O failure (exit 3)
            raise OSError(str(e)) from None
        write_json(stats_path, result.stats)
        for line in summary_lines(result.stats):
            say(line)
        say(f"wrote {out} and {stats_path}")
        return EXIT_OK
    except SceneError as e:
        print(f"smbs_addon: error: {e}", file=sys.stderr)
        return EXIT_SCENE
    except OSError as e:
        print(f"smbs_addon: error: {e}", file=sys.stderr)
        return EXIT_IO
    except (BakeCancelled, KeyboardInterrupt):
        print("smbs_addon: cancelled", file=sys.stderr)
        return EXIT_CANCELLED


if __name__ == "__main__":
    sys.exit(main())
