"""Command line: ``python -m smbs_addon bake IN [options]``, ``... compare IN --time S``
(an equal-time table of the scene's methods), ``... export IN OUT`` and ``... prepare`` (compile
the kernels before the first bake).

IN is a .blend file (opened with the bpy module) or an exported .npz scene.
Exit codes a render farm can trust (exits.py): 0 done (also for a scene with no caustic to
bake: its layer is all zero and the output says why), 1 the scene cannot be baked,
2 bad arguments, 3 unreadable input or unwritable output (the previous output unchanged), 128 +
the signal's number when SIGINT (130), SIGTERM (143) or SIGHUP (129) stopped it (signals.py);
``prepare --check``: 0 the kernels are compiled for this machine, 1 not (or no telling).
"""
from __future__ import annotations

import sys
from pathlib import Path

from .arguments import bake_settings, build_parser
from .inputs import check_writable, load_input, open_input
from .commands import compare_command, merge_command, prepare_command
from .frames import range_command
from .outputs import albedo_for, bake_outputs
from .progress import Progress
from ..io.exr import bytes_writer, save_outputs
from .report import summary_lines
from ..baking.settings import shard_of
from ..core import signals
from ..core.errors import BakeCancelled, SceneError
from ..baking.bake import bake
from ..baking.engine import check_samples
from . import signals as cli_signals
from .exits import EXIT_IO, EXIT_OK, EXIT_SCENE, EXIT_USAGE, cancelled


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    restore = cli_signals.install()
    try:
        return _run(args)
    finally:
        if restore is not None:
            restore()


def _run(args) -> int:
    say = (lambda *a: None) if getattr(args, "quiet", False) else print
    out = None
    try:
        if args.command == "export":
            out = Path(args.output)
            check_writable(out)
            scene = load_input(args.input, warn=lambda m: print(f"warning: {m}", file=sys.stderr))
            signals.check()

            save_outputs([(out, bytes_writer(scene.npz_bytes()))], before_replace=signals.check)
            say(f"wrote {out}")
            return EXIT_OK
        if args.command == "compare":
            return compare_command(args, say)
        if args.command == "prepare":
            return prepare_command(args, say)
        if args.command == "merge":
            return merge_command(args, say)
        return _bake_command(args, say)
    except SceneError as e:
        print(f"smbs_addon: error: {e}", file=sys.stderr)
        return EXIT_SCENE
    except OSError as e:
        print(f"smbs_addon: error: {e}", file=sys.stderr)
        return EXIT_IO
    except BakeCancelled as e:
        signum = e.signum or signals.requested()  # prepare's processes stop by a cancel() that asks the flag
        print(f"smbs_addon: {f'stopped by {signals.name(signum)}' if signum else 'cancelled'}; nothing was written",
              file=sys.stderr)
        return cancelled(signum)
    except KeyboardInterrupt:  # signals not ours (main() off the main thread)
        print("smbs_addon: cancelled; nothing was written", file=sys.stderr)
        return cancelled(2)


def _bake_command(args, say) -> int:
    stop_rule = args.time is not None or args.noise is not None
    if args.keep_partial and not stop_rule:
        print("smbs_addon: error: --keep-partial keeps the whole batches a bake by --time or --noise has done "
              "when a signal stops it; a bake by --spp has no such part to keep", file=sys.stderr)
        return EXIT_USAGE
    spp = args.spp if args.spp is not None else (args.batches if stop_rule else 16)
    settings = bake_settings(args, args.method, spp, args.time or 0.0, args.noise or 0.0)
    if args.shard is not None:
        try:
            settings = shard_of(settings, *args.shard)
        except SceneError as e:
            print(f"smbs_addon: error: --shard: {e}", file=sys.stderr)
            return EXIT_USAGE
    progress = Progress(args.quiet, sys.stderr.isatty())
    if args.frames is not None or args.frame is not None:
        inp = open_input(args.input)
        return range_command(args, settings, inp, progress, say)
    out = Path(args.out) if args.out else Path(args.input).with_suffix(".caustics.exr")
    stats_path = Path(args.stats) if args.stats else out.with_suffix(".json")
    check_writable(out)
    check_writable(stats_path)
    warn = lambda m: print(f"warning: {m}", file=sys.stderr)  # noqa: E731
    inp = open_input(args.input)
    scene = inp.scene_at(None, warn)
    try:
        check_samples(scene, settings)
    except SceneError as e:
        print(f"smbs_addon: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    signals.check()

    headed = []

    def on_plan(lines):  # before any caustic is traced (auto adds its choices after its pilots)
        if not headed:
            say("plan:")
            headed.append(True)
        for line in lines:
            say(f"  {line}")

    result = bake(scene, settings, progress=progress, on_plan=on_plan, keep_partial=args.keep_partial)
    if not args.quiet and progress.tty:
        print(file=sys.stderr)
    albedo = albedo_for(inp, scene, result, warn)
    outputs = bake_outputs(settings, result, out, stats_path, albedo, scene.digest())[0]
    signals.check()  # a signal after the bake's last look at it: nothing is written
    save_outputs(outputs, before_replace=signals.check)
    for line in summary_lines(result.stats):
        say(line)
    say(f"wrote {out} and {stats_path}")
    if result.stats.get("stopped_by") == "signal":
        return cancelled(signals.requested())
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
