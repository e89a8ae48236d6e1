"""Files of a frame range: Blender's ``#`` padding (``out/caustics_####.exr``, frame 1 ->
``out/caustics_0001.exr``), the range's summary beside them, and frame specs (``1-250``,
``1-250:2``, ``12``)."""
from __future__ import annotations

import re
from pathlib import Path

_RUN = re.compile(r"#+")


def has_frames(pattern) -> bool:
    """Does the path hold a run of ``#`` (a frame number goes there)?"""
    return bool(_RUN.search(Path(pattern).name))


def with_frames(pattern) -> Path:
    """The path with a run of ``#`` in its name: as it is, or ``_####`` before its extension (Blender's
    four digits)."""
    p = Path(pattern)
    if has_frames(p):
        return p
    return p.with_name(f"{p.stem}_####{p.suffix}")


def fill_frame(pattern: str, frame: int) -> str:
    """The path of one frame, as text (a Blender path such as ``//caustics_####.exr`` stays one): the
    last run of ``#`` in the file's name replaced by the frame, zero-padded to its length (``-001`` for
    frame -1 in ``####``, as Blender writes it; longer where the frame has more digits)."""
    text = str(pattern)
    cut = max(text.rfind("/"), text.rfind("\\")) + 1  # the folder as written (a Windows path keeps its separators)
    head, name = text[:cut], text[cut:]
    runs = list(_RUN.finditer(name))
    if not runs:
        return text
    r = runs[-1]
    return f"{head}{name[:r.start()]}{int(frame):0{len(r.group())}d}{name[r.end():]}"


def frame_path(pattern, frame: int) -> Path:
    """fill_frame as a Path."""
    return Path(fill_frame(str(pattern), frame))


def summary_path(pattern, suffix: str = ".json") -> Path:
    """The range's summary beside its frames: the run of ``#`` (and a separator before it, if it then
    ends the name) as ``summary``: ``out/caustics_####.exr`` -> ``out/caustics_summary.json``."""
    p = Path(pattern)
    runs = list(_RUN.finditer(p.stem))
    if not runs:
        return p.with_name(f"{p.stem}_summary{suffix}")
    r = runs[-1]
    return p.with_name(f"{p.stem[:r.start()]}summary{p.stem[r.end():]}{suffix}")


def parse_frames(spec: str) -> list[int]:
    """``A-B`` (both included), ``A-B:STEP`` or ``N`` -> the frames, in order; negative frames are
    written with their sign (``-5--1``). ValueError with the reason otherwise."""
    m = re.fullmatch(r"\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*(?::\s*(\d+)\s*)?)?", str(spec))
    if not m:
        raise ValueError(f"'{spec}' is not a frame range (A-B, A-B:STEP or N)")
    a = int(m.group(1))
    if m.group(2) is None:
        return [a]
    b, step = int(m.group(2)), int(m.group(3) or 1)
    if step < 1:
        raise ValueError(f"'{spec}': the step must be at least 1")
    if b < a:
        raise ValueError(f"'{spec}': the range ends ({b}) before it starts ({a})")
    return list(range(a, b + 1, step))
