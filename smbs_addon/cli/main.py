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

import sys
from pathlib import Path

from .arguments import bake_settings, build_parser
from .inputs import check_writable, load_input
from .commands import compare_command, prepare_command
from ..io.exr import exr_channels, exr_metadata, write_exr, write_json
from .report import summary_lines
from ..core.errors import BakeCancelled, SceneError
from ..baking.bake import bake
from .exits import EXIT_CANCELLED, EXIT_IO, EXIT_OK, EXIT_SCENE


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)

    say = (lambda *a: None) if getattr(args, "quiet", False) else print
    try:
        if args.command == "export":
            out = Path(args.output)
            check_writable(out)
            load_input(args.input, warn=lambda m: print(f"warning: {m}", file=sys.stderr)).save(out)
            say(f"wrote {out}")
            return EXIT_OK
        if args.command == "compare":
            return compare_command(args, say)
        if args.command == "prepare":
            return prepare_command(args, say)

        stop_rule = args.time is not None or args.noise is not None
        spp = args.spp if args.spp is not None else (args.batches if stop_rule else 16)
        settings = bake_settings(args, args.method, spp, args.time or 0.0, args.noise or 0.0)
        out = Path(args.out) if args.out else Path(args.input).with_suffix(".caustics.exr")
        stats_path = Path(args.stats) if args.stats else out.with_suffix(".json")
        check_writable(out)
        check_writable(stats_path)
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
