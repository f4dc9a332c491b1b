"""The take library: files under the studio's roots, safe look-up by id, lazy metadata.

A take's id is ``"<root index>/<path relative to that root>"`` (POSIX separators). Only
ids that resolve, after following symlinks, to a motion file inside their root are
served; everything else is "not found", so a crafted id can never name a file elsewhere.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from usdmotion.io import AMC_EXTENSIONS, BVH_EXTENSIONS, GLTF_EXTENSIONS, USD_EXTENSIONS

MOTION_EXTENSIONS = BVH_EXTENSIONS + USD_EXTENSIONS + GLTF_EXTENSIONS + AMC_EXTENSIONS
#: Files larger than this are listed with an error instead of being read (a studio must
#: not be taken down by one huge file). 512 MiB is several hours of 120 fps capture.
MAX_FILE_BYTES = 512 * 1024 * 1024


def read_options(**options) -> dict:
    """Keyword arguments of :func:`usdmotion.io.read_motion` for every take (``units``,
    ``up_axis``... as the CLI's reading options give them), ``None`` values left out."""
    return {k: v for k, v in options.items() if v is not None}


@dataclass(frozen=True)
class Entry:
    """One take file: its id, display name and the resolved path (never sent to clients)."""

    id: str
    name: str
    path: Path
    size: int
    mtime_ns: int


class Library:
    """Takes under ``roots`` (folders, searched recursively, or single files)."""

    def __init__(self, roots: list[Path], options: dict | None = None, read=None,
                 skip: list[Path] | None = None) -> None:
        self.roots = [Path(r).resolve() for r in roots]
        #: folders not listed (the output folder's cache of GLB bodies)
        self.skip = {Path(os.path.realpath(p)) for p in skip or []}
        self.options = options or {}
        #: ``read(entry) -> Motion``; the app passes its take cache so a take listed is already read
        self.read = read or (lambda entry: read_take(entry, self.options))
        self._meta: dict[tuple[str, int, int], dict] = {}
        self._lock = threading.Lock()

    def scan(self) -> list[Entry]:
        """Every motion file under the roots, sorted by id (stat only; nothing is read)."""
        entries = []
        for index, root in enumerate(self.roots):
            if root.is_file():
                entry = self._entry(index, root.name)
                entries += [entry] if entry else []
                continue
            for folder, dirs, files in os.walk(root):
                dirs[:] = sorted(d for d in dirs if not d.startswith(".") and Path(folder, d) not in self.skip)
                rel = Path(folder).relative_to(root)
                for name in sorted(files):
                    if name.lower().endswith(MOTION_EXTENSIONS) and not name.startswith("."):
                        entry = self._entry(index, (rel / name).as_posix())
                        entries += [entry] if entry else []
        return sorted(entries, key=lambda e: e.id)

    def resolve(self, take_id: str) -> Entry | None:
        """The entry of ``take_id`` if it names a motion file inside its root, else ``None``."""
        named = _split_id(take_id, len(self.roots))
        return None if named is None else self._entry(*named)

    def get(self, take_id: str, field: str = "take") -> Entry:
        """The entry of ``take_id``; :class:`StudioError` 404 with :meth:`missing_line` if none, 400 if
        the request gave no id (in its ``field``: a query parameter ``?take``, a JSON body's ``take``)."""
        from usdmotion.studio.errors import StudioError

        if not take_id:  # not "usdmotion: error: : not found" (an empty file name)
            raise StudioError(400, f"the request names no take ({field}=ID)")
        entry = self.resolve(take_id)
        if entry is None:
            raise StudioError(404, self.missing_line(take_id))
        return entry

    def missing_line(self, take_id: str) -> str:
        """The one line for a take id that names no take: for a motion file's name under a folder root
        that is not there, the line its reader gives (``usdmotion info`` on that path, run in the root,
        prints the same line); for anything else (out of its root, not a motion file, a malformed id),
        ``usdmotion: error: ID: not found``, which tells nothing about what lies outside the roots."""
        named = _split_id(take_id, len(self.roots))
        if named is not None and self.roots[named[0]].is_dir() and named[1].lower().endswith(MOTION_EXTENSIONS):
            root = self.roots[named[0]]
            path = root / named[1]
            if not os.path.lexists(path) and Path(os.path.realpath(path)).is_relative_to(root):
                entry = Entry(take_id, named[1], path, 0, 0)
                try:
                    read_take(entry, self.options)
                except Exception as exc:  # noqa: BLE001 - the reader's line for a missing file
                    return take_error_line(entry, exc)
        name = named[1] if named is not None else str(take_id)[:200]
        return f"usdmotion: error: {name}: not found"

    def _entry(self, index: int, rel: str) -> Entry | None:
        root = self.roots[index]
        if root.is_file():
            if rel != root.name:
                return None
            path = root
        else:
            path = Path(os.path.realpath(root / rel))
            if not path.is_relative_to(root) or any(path.is_relative_to(s) for s in self.skip):  # out of the root
                return None
        if not path.name.lower().endswith(MOTION_EXTENSIONS):
            return None
        try:
            st = path.stat()
        except OSError:
            return None
        if not path.is_file():
            return None
        return Entry(f"{index}/{rel}", rel, path, st.st_size, st.st_mtime_ns)

    def metadata(self, entry: Entry) -> dict:
        """Joints, frames, fps, duration, rig family and height, or ``{"error": one line}``.

        Cached by path, size and mtime: a file changed on disk is read again.
        """
        key = (str(entry.path), entry.size, entry.mtime_ns)
        with self._lock:
            if key in self._meta:
                return self._meta[key]
        meta = describe_take(entry, self.read)
        with self._lock:
            self._meta[key] = meta
        return meta


def describe_take(entry: Entry, read) -> dict:
    """Library metadata of one take read by ``read(entry)`` (see :meth:`Library.metadata`)."""
    from usdmotion.kinematics import skeleton_height
    from usdmotion.skeleton_names import rig_family

    try:
        motion = read(entry)
        names = [n for n, end in zip(motion.joint_names, motion.end_sites) if not end]
        return {
            "joints": len(names),
            "frames": motion.n_frames,
            "fps": motion.fps,
            "duration_s": motion.duration,
            "rig": rig_family(names) or "unknown",
            "height_m": skeleton_height(motion) * motion.meters_per_unit,
        }
    except Exception as exc:  # noqa: BLE001 - every failure becomes the take's one-line error
        return {"error": take_error_line(entry, exc)}


def read_take(entry: Entry, options: dict):
    """Read a take with the studio's reading options (``read_motion`` keywords; raises
    ``InputError`` for huge files)."""
    from usdmotion.errors import InputError
    from usdmotion.io import read_motion

    if entry.size > MAX_FILE_BYTES:
        raise InputError(entry.name, f"file is {entry.size:,} bytes; the studio reads files up to "
                                     f"{MAX_FILE_BYTES:,} bytes")
    return read_motion(entry.path, **options)


def take_error_line(entry: Entry, exc: BaseException) -> str:
    """The line the CLI prints for ``exc`` (:func:`usdmotion.errors.error_line`:
    ``usdmotion: error: FILE[:LINE]: message``), the take named by its library name (its path under
    its root, as ``usdmotion info`` run in the root names it) instead of its full path."""
    from usdmotion.errors import error_line

    return error_line(exc).replace(str(entry.path), entry.name)


def _split_id(take_id, n_roots: int) -> tuple[int, str] | None:
    """``(root index, relative POSIX path)`` of a well-formed take id, else ``None`` (no ``..``,
    ``.``, empty or absolute parts, no backslash or NUL, a root that exists)."""
    if not isinstance(take_id, str) or len(take_id) > 4096 or "\\" in take_id or "\0" in take_id:
        return None
    head, _, rel = take_id.partition("/")
    if not head.isdigit() or int(head) >= n_roots or not rel:
        return None
    if rel.startswith("/") or any(p in ("..", ".", "") for p in rel.split("/")) or not PurePosixPath(rel).parts:
        return None
    return int(head), rel
