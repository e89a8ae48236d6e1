"""The command line's commands beside bake: prepare (compile the kernels) and compare (an equal-time
table of methods)."""
from __future__ import annotations

import glob
import sys
from pathlib import Path

import numpy as np

from ..baking import prepare
from ..baking.compare import Reference, compare, json_report, table_lines
from ..core.compiles import counted
from .arguments import bake_settings
from .inputs import check_writable, load_input
from ..core import signals
from ..baking import merge
from ..io.exr import exr_writer, json_writer, read_channels, save_outputs, write_json
from ..io.sequence import frame_path
from .exits import EXIT_NOT_READY, EXIT_OK

def prepare_command(args, say) -> int:
    """python -m smbs_addon prepare: compile the kernels (smbs_addon.baking.prepare)."""
    if args.check:  # for scripts: prepare --check || prepare
        state = prepare.ready()
        say({True: "kernels: compiled for this machine; bakes load them from the cache",
             False: "kernels: not compiled for this code on this machine; the first bake compiles them "
                    "(a few minutes), `python -m smbs_addon prepare` does it now",
             None: "kernels: cannot tell whether they are compiled (this numba keeps its cache otherwise)"}[state])
        return EXIT_OK if state else EXIT_NOT_READY
    out = prepare.prepare(args.jobs, say=say, cancel=lambda: bool(signals.requested()))
    say(f"prepared: {counted(out['kernels'], 'kernel')} compiled in {out['seconds']:.1f} s "
        f"({counted(out['jobs'], 'process')}); bakes on this machine load them from the cache")
    return EXIT_OK


def compare_command(args, say) -> int:
    """python -m smbs_addon compare: an equal-time table of the scene (smbs_addon.baking.compare)."""
    settings = bake_settings(args, args.methods[0], args.batches)  # one sample per pixel per batch
    out = Path(args.out) if args.out else None
    if out is not None:
        check_writable(out)
    if args.reference and Path(args.reference).is_dir():
        raise IsADirectoryError(f"reference '{args.reference}' is a folder, not an EXR")
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


def _merge_inputs(names, frame) -> list:
    """The inputs of a merge: # runs filled with the frame, patterns (* ? []) matched, in order."""
    out = []
    for name in names:
        name = str(frame_path(name, frame)) if frame is not None else name
        if not Path(name).exists() and glob.has_magic(name):
            found = sorted(glob.glob(name))
            if not found:
                raise FileNotFoundError(f"no file matches '{name}'")
            out += found
        elif Path(name).is_dir():
            raise IsADirectoryError(f"input '{name}' is a folder, not an EXR")
        elif not Path(name).is_file():
            raise FileNotFoundError(f"input '{name}' does not exist")
        else:
            out.append(name)
    return out


def merge_command(args, say) -> int:
    """python -m smbs_addon merge OUT IN...: bakes of one frame merged (smbs_addon.baking.merge)."""
    out = frame_path(args.output, args.frame) if args.frame is not None else Path(args.output)
    stats_path = Path(args.stats) if args.stats else out.with_suffix(".json")
    check_writable(out)
    check_writable(stats_path)
    names = _merge_inputs(args.inputs, args.frame)
    parts = [merge.part(n, *read_channels(n)) for n in names]
    channels, meta, stats = merge.merge(parts)
    rgb = np.stack([channels[c] for c in "RGB"], axis=-1)
    rest = ["std"] + sorted(n for n in channels if n not in ("R", "G", "B", "std"))
    signals.check()
    save_outputs([(out, exr_writer(rgb, meta, {n: channels[n] for n in rest})), (stats_path, json_writer(stats))],
                 before_replace=signals.check)
    errs = ", ".join("unknown" if p["relative_error"] is None else f"+-{p['relative_error']:.1%}"
                     for p in stats["merged_from"])
    say(f"merged {len(parts)} bakes ({stats['samples']:g} samples per pixel, {stats['batches_done']} batches): error "
        f"+-{stats['relative_error']:.1%} (the inputs: {errs})")
    say(f"wrote {out} and {stats_path}")
    return EXIT_OK
