"""``blender -c smbs_bake IN [options]``: the render-farm command.

The options, outputs and exit codes are those of ``python -m smbs_addon bake``
(the same argparse parser and ``main``): 0 done, 1 the scene cannot be baked,
2 bad arguments, 3 unreadable input or unwritable output, 130 cancelled. An
unexpected failure prints its traceback and returns 1. ``smbs_bake merge OUT IN...``
and ``smbs_bake export IN OUT`` are the command line's merge and export.

Without an input (``blender -b shot.blend -c smbs_bake --frames 1-250``: Blender
loads the file before it runs the command) the command bakes the file Blender
has open.

Blender command ids must be Python identifiers, so the command is
``smbs_bake`` (``smbs-bake`` is refused by ``register_cli_command``). It exists
while the extension is enabled in the preferences Blender starts with.
"""
import traceback

import bpy

COMMAND = "smbs_bake"
_handle = None


def smbs_bake(argv) -> int:
    """The command's handler: ``argv`` is everything after ``-c smbs_bake``."""
    from ..smbs_addon.cli.main import main

    args = [str(a) for a in argv]
    if not args or args[0] not in ("bake", "export", "merge"):
        args.insert(0, "bake")  # `smbs_bake IN ...` means `bake IN ...`
    if args[0] == "bake" and bpy.data.filepath and (len(args) == 1 or args[1].startswith("-")) \
            and not {"-h", "--help"} & set(args):
        args.insert(1, bpy.data.filepath)  # no input: the file Blender has open
    try:
        return int(main(args))
    except SystemExit as e:  # argparse: --help (0) and usage errors (2)
        code = e.code
        if code is None:
            return 0
        return code if isinstance(code, int) else 1
    except KeyboardInterrupt:
        return 130
    except Exception:
        traceback.print_exc()
        return 1


def registered() -> bool:
    return _handle is not None


def register():
    global _handle
    if _handle is None and hasattr(bpy.utils, "register_cli_command"):  # Blender 4.2+
        _handle = bpy.utils.register_cli_command(COMMAND, smbs_bake)


def unregister():
    global _handle
    if _handle is not None:
        handle, _handle = _handle, None
        bpy.utils.unregister_cli_command(handle)
