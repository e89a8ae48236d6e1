"""EXR read/write through OpenImageIO, with statistics in the header, and writes that lose nothing.

Images are (H, W, C) float arrays, top row first.

A write never replaces a good file with a bad one (save_outputs, write_exr, write_json): each
output is written to a temporary file beside its target, read back and compared with what was
meant, and only then renamed over the target. OpenImageIO's open, write and close all report
success when the process's file size limit (ulimit -f; Python ignores SIGXFSZ, so the write is
cut short silently) or a full disk truncates the file, so the read back is what tells. Several
outputs (an EXR and its statistics) are all written and checked before the first replaces
anything. On a failure the previous files stay as they were, no temporary file is left, and the
result is kept in a folder of the temporary folder (or beside the output under a name that says
so); the message names the file, the cause and where the result went.
"""
from __future__ import annotations

import array
import json
import os
import stat
import tempfile
from pathlib import Path

import numpy as np

try:  # POSIX: the file size limit (ulimit -f), file attributes (chattr)
    import fcntl
    import resource
except ImportError:  # pragma: no cover - Windows
    fcntl = resource = None

from ..core.errors import SceneError, WriteError
from ..core.version import code_version

_PENDING: set = set()  # temporary files written and not yet in place (remove_pending)
_FS_IOC_GETFLAGS, _IMMUTABLE, _APPEND = 0x80086601, 0x10, 0x20  # Linux: lsattr's i and a


def remove_pending() -> None:
    """Remove the temporary files of writes under way (a process that must stop at once)."""
    for p in list(_PENDING):
        try:
            os.unlink(p)
        except OSError:
            pass
        _PENDING.discard(p)


def _temporary(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.tmp{path.suffix}")


def _check_folder(path: Path) -> None:
    if not path.parent.exists():
        raise SceneError(f"output folder '{path.parent}' does not exist")
    if not os.access(path.parent, os.W_OK):
        raise SceneError(f"output folder '{path.parent}' is not writable")
    if path.is_dir():
        raise SceneError(f"cannot write '{path}': it is a folder")


def _fixed_flags(path: Path) -> str | None:
    """'immutable' or 'append-only' where the file has that attribute (Linux: chattr +i, +a): then
    no rename may replace it; None otherwise, or where the system cannot tell."""
    if fcntl is None:  # pragma: no cover - not POSIX
        return None
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        buf = array.array("i", [0])
        fcntl.ioctl(fd, _FS_IOC_GETFLAGS, buf, True)
    except OSError:
        return None
    finally:
        os.close(fd)
    return "immutable" if buf[0] & _IMMUTABLE else "append-only" if buf[0] & _APPEND else None


def check_output(path) -> None:
    """Refuse, before a bake, an output that cannot be written in place: its folder missing, a file
    or unwritable (a file is made there and removed: a read-only or special file system such as
    /proc says no only then, whatever the permission bits say to root); the output a folder, or a
    file no rename may replace (immutable or append-only, or another user's in a sticky folder).
    Raises OSError naming the file and the cause."""
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise OSError(f"output folder '{parent}' is a file")
    if not parent.is_dir():
        raise OSError(f"output folder '{parent}' does not exist")
    if path.is_dir():
        raise OSError(f"output '{path}' is a folder")
    probe = parent / f".{path.name}.{os.getpid()}.probe"
    try:
        fd = os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise OSError(f"output folder '{parent}' is not writable ({e.strerror or e})") from None
    if path.exists():
        fixed = _fixed_flags(path)
        if fixed:
            raise OSError(f"output '{path}' is {fixed} (chattr), so it cannot be replaced")
        st, folder = path.stat(), parent.stat()
        uid = os.geteuid() if hasattr(os, "geteuid") else None
        if (folder.st_mode & stat.S_ISVTX and uid not in (None, 0, st.st_uid, folder.st_uid)):
            raise OSError(f"output '{path}' belongs to another user in a folder only its owners may "
                          f"replace files in (sticky), so it cannot be replaced")


def _size_limit(tmp: Path) -> str | None:
    """The process's file size limit (ulimit -f) where tmp has reached it: a write there was cut
    short (a file of exactly that size is taken for one too: no telling without reading it, and
    OpenEXR's reader prints to stderr what it finds wrong in a short file)."""
    if resource is None:  # pragma: no cover - not POSIX
        return None
    try:
        size = tmp.stat().st_size
        soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        if soft != resource.RLIM_INFINITY and size >= soft:
            return f"the file size limit of this process (ulimit -f: {soft} bytes) cut it short"
    except (OSError, ValueError):
        pass
    return None


def _short_write(tmp: Path) -> str | None:
    """Why a file may have been cut short: the process's file size limit or a full disk."""
    limit = _size_limit(tmp)
    if limit:
        return limit
    try:
        st = os.statvfs(tmp.parent)
        if st.f_bavail * st.f_frsize < (1 << 20):
            return "the disk is full"
    except (AttributeError, OSError):
        pass
    return None


def _exr_image(image, extra):
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
    return np.ascontiguousarray(img), names


def _exr_spec(img, names, metadata):
    import OpenImageIO as oiio

    h, w, c = img.shape
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
    return spec


def exr_writer(image: np.ndarray, metadata: dict | None = None, extra: dict | None = None):
    """A writer(file) of the EXR (write_exr) that reads the file back and raises OSError with the
    cause unless it holds exactly these pixels and channels."""
    img, names = _exr_image(image, extra)
    spec = _exr_spec(img, names, metadata)

    def write(tmp: Path) -> None:
        import OpenImageIO as oiio

        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            why = (out.geterror() if out is not None else "") or oiio.geterror() or "cannot create it"
            raise OSError(why)
        try:
            if not out.write_image(img):
                raise OSError(out.geterror() or "the image could not be written")
        finally:
            out.close()
        limit = _size_limit(tmp)
        if limit:
            raise OSError(limit)
        inp = oiio.ImageInput.open(str(tmp))
        if inp is None:
            raise OSError(_short_write(tmp) or f"it does not read back ({oiio.geterror()})")
        try:
            back_spec = inp.spec()
            back = inp.read_image(oiio.FLOAT)
            why = inp.geterror()
        finally:
            inp.close()
        back_names = list(back_spec.channelnames)  # OpenEXR keeps channels in its own order
        same = (back is not None and (back_spec.height, back_spec.width, back_spec.nchannels) == img.shape
                and sorted(back_names) == sorted(names))
        if same:
            back = np.asarray(back, np.float32).reshape(img.shape)[..., [back_names.index(n) for n in names]]
            same = np.array_equal(back, img, equal_nan=True)
        if not same:
            raise OSError(_short_write(tmp) or f"it does not read back as written{f' ({why})' if why else ''}")

    return write


def bytes_writer(data: bytes):
    """A writer(file) of these bytes that checks the file's size and bytes after writing them."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if tmp.stat().st_size != len(data) or tmp.read_bytes() != data:
            raise OSError(_short_write(tmp) or "it does not read back as written")

    return write


def json_writer(obj):
    return bytes_writer(json.dumps(obj, indent=2).encode())


def _cause(e: BaseException, tmp: Path | None = None) -> str:
    """Why writing tmp failed, in words that name no temporary file: the file size limit or a full
    disk where either cut it short (OpenImageIO's words for them say neither), else the error's."""
    if tmp is not None:
        short = _short_write(tmp)
        if short:
            return short
    if isinstance(e, OSError) and e.strerror and e.errno:
        return f"[Errno {e.errno}] {e.strerror}"
    text = str(e) or type(e).__name__
    if tmp is not None:
        text = text.replace(f' "{tmp}"', "").replace(f" '{tmp}'", "").replace(str(tmp), "the file")
    return text


def _write_at(target: Path, writer) -> None:
    """writer into target's temporary file beside it, verified, renamed over target; OSError with
    the cause (_cause) on a failure."""
    tmp = _temporary(target)
    _PENDING.add(tmp)
    try:
        try:
            writer(tmp)
        except Exception as e:
            raise OSError(_cause(e, tmp)) from e
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        _PENDING.discard(tmp)


def _rescue(outputs) -> tuple[str | None, str]:
    """Write the outputs [(path, writer)] somewhere safe: a new folder of the temporary folder
    under their own names, else beside each output as NAME.unsaved-PID.EXT. (where, '') or
    (None, why not)."""
    whys = {}
    try:
        folder = Path(tempfile.mkdtemp(prefix="smbs-unsaved-"))
        try:
            for path, writer in outputs:
                _write_at(folder / Path(path).name, writer)
            return str(folder), ""
        except Exception as e:  # noqa: BLE001 - reported, then the next place is tried
            whys[f"in the temporary folder ({folder.parent})"] = str(e)
            for p in folder.iterdir():
                p.unlink(missing_ok=True)
            folder.rmdir()
    except OSError as e:
        whys["in the temporary folder"] = str(e)
    kept = []
    try:
        for path, writer in outputs:
            path = Path(path)
            spare = path.with_name(f"{path.stem}.unsaved-{os.getpid()}{path.suffix}")
            _write_at(spare, writer)
            kept.append(spare)
        return ", ".join(str(k) for k in kept), ""
    except Exception as e:  # noqa: BLE001
        for k in kept:
            k.unlink(missing_ok=True)
        whys["beside the output"] = str(e)
    if len(set(whys.values())) == 1:
        return None, f"{' nor '.join(whys)}: {next(iter(whys.values()))}"
    return None, "; ".join(f"{k}: {v}" for k, v in whys.items())


def save_outputs(outputs, before_replace=None) -> list:
    """Write every output [(path, writer)] (writer(file) writes and verifies: exr_writer,
    json_writer) to a temporary file beside it, and only once all are whole, call before_replace()
    (which may raise to give up: a cancel) and rename each over its target. On a failure nothing is
    replaced and no temporary file is left; the outputs are written somewhere safe instead, and
    WriteError says which file failed, why, and where the result is. Returns the paths."""
    outputs = [(Path(p), w) for p, w in outputs]
    staged = []
    try:
        for path, writer in outputs:
            _check_folder(path)
            tmp = _temporary(path)
            _PENDING.add(tmp)
            staged.append(tmp)
            try:
                writer(tmp)
            except Exception as e:
                raise _Failed(path, _cause(e, tmp)) from e
        if before_replace is not None:
            before_replace()
        done = 0
        for (path, _), tmp in zip(outputs, staged):
            try:
                os.replace(tmp, path)
            except OSError as e:
                raise _Failed(path, _cause(e, tmp), done) from e
            _PENDING.discard(tmp)
            done += 1
    except _Failed as f:
        for tmp in staged:
            tmp.unlink(missing_ok=True)
            _PENDING.discard(tmp)
        left = outputs[f.done:]
        where, why = _rescue(left)
        previous = ("the previous file is unchanged" if f.path.exists() else "nothing was written there")
        kept = (f"the result ({', '.join(p.name for p, _ in left)}) is kept in {where}" if where else
                f"the result could not be kept elsewhere either ({why})")
        raise WriteError(f"cannot write '{f.path}': {f.cause}; {previous}; {kept}") from None
    except BaseException:  # a cancel, an interrupt: nothing replaced, nothing left behind
        for tmp in staged:
            tmp.unlink(missing_ok=True)
            _PENDING.discard(tmp)
        raise
    return [p for p, _ in outputs]


class _Failed(Exception):
    def __init__(self, path, cause, done=0):
        super().__init__(cause)
        self.path, self.cause, self.done = path, cause, done


def write_exr(path, image: np.ndarray, metadata: dict | None = None, extra: dict | None = None) -> Path:
    """Write a linear float32 EXR (RGB or RGBA), verified before it replaces anything (save_outputs).
    metadata values go in the header; extra maps channel names (no dots: Blender would read the
    file as multilayer) to (H,W) images stored after the colour, e.g. the bake's per-pixel ``std``."""
    path = Path(path)
    _check_folder(path)
    return save_outputs([(path, exr_writer(image, metadata, extra))])[0]


def write_json(path, obj) -> Path:
    """Write obj as indented JSON, verified before it replaces anything (save_outputs)."""
    return save_outputs([(Path(path), json_writer(obj))])[0]


def _read_pixels(path) -> tuple[np.ndarray, list, dict]:
    """An image's pixels as (H, W, C) float32, its channel names and its smbs:* header entries."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise SceneError(f"cannot read image '{path}': {oiio.geterror()}")
    try:
        spec = inp.spec()
        img = inp.read_image(oiio.FLOAT)
        meta = {a.name[5:]: a.value for a in spec.extra_attribs if a.name.startswith("smbs:")}
    finally:
        inp.close()
    if img is None:
        raise SceneError(f"cannot read image '{path}': its pixels do not read")
    return np.asarray(img, np.float32).reshape(spec.height, spec.width, spec.nchannels), list(spec.channelnames), meta


def read_exr(path, channel: str | None = None) -> tuple[np.ndarray, dict]:
    """Read an image as (H, W, C) float32 plus its smbs:* header entries: its colour
    channels (R, G, B, A, whichever it has; all channels if it has none of them), or with
    channel, that one channel as (H, W)."""
    img, names, meta = _read_pixels(path)
    if channel is not None:
        if channel not in names:
            raise SceneError(f"image '{path}' has no channel '{channel}' (it has {', '.join(names)})")
        return img[:, :, names.index(channel)], meta
    colour = [names.index(c) for c in ("R", "G", "B", "A") if c in names]
    return (img[:, :, colour] if colour else img), meta


def read_header(path) -> dict:
    """The smbs:* header entries of an EXR, without reading its pixels ({} where it is not one of
    ours, or does not open)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        oiio.geterror()  # clear it: a file that does not open is just not one to skip
        return {}
    try:
        return {a.name[5:]: a.value for a in inp.spec().extra_attribs if a.name.startswith("smbs:")}
    finally:
        inp.close()


def read_channels(path) -> tuple[dict, dict]:
    """Every channel of an EXR by name, (H, W) float32 each, and its smbs:* header entries."""
    img, names, meta = _read_pixels(path)
    return {n: img[:, :, i] for i, n in enumerate(names)}, meta


def remove_stale(path) -> list:
    """Remove the temporary files a killed process left beside path (save_outputs' ``.NAME.PID.tmp.EXT``,
    where no process PID runs any more: SIGKILL gives no time to clean up); returns those removed. The
    output itself is never partial: it is only ever replaced by a rename."""
    path = Path(path)
    gone = []
    prefix, suffix = f".{path.name}.", f".tmp{path.suffix}"
    try:
        names = [p for p in path.parent.iterdir() if p.name.startswith(prefix) and p.name.endswith(suffix)]
    except OSError:
        return gone
    for p in names:
        pid = p.name[len(prefix):-len(suffix)]
        if not pid.isdigit() or int(pid) == os.getpid() or _alive(int(pid)):
            continue
        try:
            p.unlink()
            gone.append(p)
        except OSError:
            pass
    return gone


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # another user's, or no telling: leave it
    return True


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


def exr_metadata(settings, result, scene_digest: str | None = None, complete: bool = False) -> dict:
    """The EXR header entries of a bake (also written by the Blender operator): the settings and
    statistics, and what a second run and a merge read (baking/merge.py): the code that made it
    (core.version), the key of the settings the image depends on, the scene's digest where known,
    the frame, the shard, the samples per pixel and batches done. complete: R, G, B hold the caustic
    on textured receivers too (the command line's EXR, baking.result.complete_layer)."""
    st = result.stats
    meta = {"method": settings.method, "spp": settings.spp, "seed": settings.seed,
            "time_s": st["time_s"], "rays": st["rays"],
            "noise_relative": st["noise"]["relative_noise"], "stats": st,
            "code": code_version(), "settings_key": settings.image_key(),
            "samples": float(samples_done(settings, st)), "batches_done": int(st.get("batches_done", 0))}
    if scene_digest:
        meta["scene"] = scene_digest
    if settings.frame is not None:
        meta["frame"] = int(settings.frame)
    if settings.shard:
        meta["shard"] = f"{settings.shard}/{settings.shards}"
    for key in ("relative_error", "seconds_to_halve_error"):  # absent (None): not measurable
        if st.get(key) is not None:
            meta[key] = float(st[key])
    if getattr(result, "per_albedo", None) is not None:  # a pipeline reading R, G, B alone would miss it
        meta["composite"] = ("R, G, B: the whole caustic (on textured receivers seen directly, per_albedo_R, _G, _B x "
                             "the Diffuse Color pass Cycles rendered for the bake); per_albedo_* for relighting"
                             if complete else
                             "R, G, B + per_albedo_R, _G, _B x the render's Diffuse Color pass (the caustic on "
                             "textured receivers seen directly, per unit albedo)")
    return meta


def samples_done(settings, stats: dict) -> float:
    """Samples per pixel a bake took: its spp, or for a stop rule by time or noise spp per pass of
    its batches times the passes done (a bake stopped by a signal with --keep-partial likewise)."""
    if stats.get("stopped_by") in ("time", "noise", "signal", "max_batches"):
        return settings.spp * stats.get("batches_done", 0) / settings.batches
    return float(settings.spp)


def exr_channels(result, std=None) -> dict:
    """The EXR's channels beside the colour: ``std``, each pixel's standard deviation of
    the mean luminance (where the noise is, for a compositor; std: another one, that of the
    whole caustic, baking.result.complete_layer); with textured receivers
    ``per_albedo_R``, ``_G``, ``_B`` (BakeResult.per_albedo: the caustic on them per unit albedo,
    for the render's Diffuse Color pass to multiply)."""
    std = getattr(result, "std", None) if std is None else std
    out = {} if std is None else {"std": std}
    per_albedo = getattr(result, "per_albedo", None)
    if per_albedo is not None:
        out.update({f"per_albedo_{c}": per_albedo[:, :, i] for i, c in enumerate("RGB")})
    return out
