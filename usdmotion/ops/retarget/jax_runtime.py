"""Where JAX runs for retargeting: the device it picked, its persistent compilation cache
and the store of traced solvers beside it."""

from __future__ import annotations

import hashlib
import os
from functools import lru_cache
from pathlib import Path

import numpy as np


def device_description() -> str:
    """The device JAX computes on, e.g. ``"cpu"`` or ``"gpu (NVIDIA H100)"``."""
    import jax

    device = jax.devices()[0]
    kind = getattr(device, "device_kind", "")
    return device.platform + (f" ({kind})" if kind and kind.lower() != device.platform else "")


def use_cpu_cores() -> int:
    """Give JAX one CPU device per CPU this process may run on, so the LM solve can run its
    frames on all of them (:func:`usdmotion.ops.retarget.solve.solve` splits a chunk's frames
    over the devices). Returns the CPU devices JAX has.

    XLA:CPU runs one computation's small per-frame operations on one core (the solve used
    1.1–1.25 of this machine's 2 cores). The count follows the CPUs, not
    ``USDMOTION_THREADS``: the split decides the float32 rounding of the result, so a batch
    worker limited to one thread writes the same bytes as the single-file command on the
    same machine. It can only be set before JAX's first computation: a process that already
    ran one, or a count the user set (``jax_num_cpu_devices``,
    ``XLA_FLAGS=--xla_force_host_platform_device_count``), keeps what it has."""
    import jax
    from jax._src import xla_bridge

    configured = jax.config.jax_num_cpu_devices > 0 or "force_host_platform_device_count" in os.environ.get(
        "XLA_FLAGS", "")
    if not configured and not xla_bridge.backends_are_initialized():
        try:
            cpus = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            cpus = os.cpu_count() or 1
        jax.config.update("jax_num_cpu_devices", max(1, cpus))
    return len(jax.devices("cpu"))


def enable_compilation_cache() -> str | None:
    """Turn on JAX's persistent compilation cache (for command-line runs); returns its folder.

    Folder: ``$USDMOTION_JAX_CACHE``, else ``$XDG_CACHE_HOME/usdmotion/jax`` (default
    ``~/.cache/usdmotion/jax``); ``USDMOTION_JAX_CACHE=off`` disables it. A cache folder
    the user already configured for JAX is left alone. Repeat runs on the same skeletons
    then skip most of the XLA compile time. The folder is kept under
    ``$USDMOTION_JAX_CACHE_MB`` megabytes (default :data:`CACHE_MB`) by :func:`trim_cache`.
    """

    import jax

    setting = os.environ.get("USDMOTION_JAX_CACHE", "")
    if setting.lower() in ("off", "0", "no", "false") or jax.config.jax_compilation_cache_dir:
        return jax.config.jax_compilation_cache_dir or None
    cache_home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    folder = Path(setting) if setting else cache_home / "usdmotion" / "jax"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    trim_cache(folder, int(_cache_megabytes() * 1e6))
    return str(folder)


def _cache_megabytes() -> float:
    """``$USDMOTION_JAX_CACHE_MB`` (default :data:`CACHE_MB`); a value that is no number ≥ 0
    warns and gives the default."""
    setting = os.environ.get("USDMOTION_JAX_CACHE_MB", "").strip()
    try:
        megabytes = float(setting) if setting else float(CACHE_MB)
    except ValueError:
        megabytes = float("nan")
    if np.isfinite(megabytes) and megabytes >= 0:
        return megabytes
    import warnings

    from usdmotion.errors import UsdMotionWarning

    warnings.warn(f"USDMOTION_JAX_CACHE_MB must be a number of megabytes >= 0, got {setting!r}: keeping the "
                  f"compilation cache under {CACHE_MB} MB", UsdMotionWarning, stacklevel=3)
    return float(CACHE_MB)


#: Default size bound of the compilation cache folder, in megabytes (an executable is
#: 0.1–1 MB, its traced solver ~0.1 MB: a few thousand skeleton pairs and chunk sizes).
CACHE_MB = 2000
#: Entries used more recently than this many seconds are never removed (another process
#: may be reading or writing them).
CACHE_KEEP_RECENT_S = 600.0


def trim_cache(folder: Path, limit_bytes: int, now: float | None = None) -> int:
    """Keep the compilation cache ``folder`` (JAX's ``*-cache`` entries and the traced
    solvers in ``exported/``) under ``limit_bytes``: when it holds more, the least recently
    used files (by access or modification time, whichever is later) are removed until it
    holds 3/4 of the limit; files used in the last :data:`CACHE_KEEP_RECENT_S` seconds are
    kept. A removed entry is compiled or traced again when next needed. Returns the bytes
    removed (files that cannot be read or removed are left alone)."""
    import time

    entries = []
    for pattern in ("*-cache", "exported/*.jaxexport"):
        for path in Path(folder).glob(pattern):
            try:
                stat = path.stat()
            except OSError:
                continue
            entries.append((max(stat.st_atime, stat.st_mtime), stat.st_size, path))
    total = sum(size for _, size, _ in entries)
    if total <= limit_bytes:
        return 0
    now = time.time() if now is None else now
    removed = 0
    for used, size, path in sorted(entries, key=lambda entry: entry[0]):
        if total - removed <= 0.75 * limit_bytes or used > now - CACHE_KEEP_RECENT_S:
            break
        try:
            path.unlink()
        except OSError:
            continue
        removed += size
    return removed


#: Sources whose code the solvers trace (:func:`lower_stored` keys its files by them).
TRACED_SOURCES = ("ops/retarget/*.py", "kinematics.py", "rotations.py", "motion.py", "constants.py")


def lower_stored(fn, args, key) -> object:
    """``fn.lower(*args)`` without tracing ``fn`` again in a later process: where the
    persistent compilation cache is on (:func:`enable_compilation_cache`), the traced
    function is kept as a serialized ``jax.export.Exported`` in its folder's ``exported/``,
    one file per ``key`` (the solver's static structure and argument shapes), JAX's version,
    the backend and the code of :data:`TRACED_SOURCES`; a file is read back and lowered
    instead of tracing. The LM's loop body is ~15,000 lines of HLO: tracing and lowering it
    took 1.0–1.5 s of each retarget command's start-up on a warm compilation cache, reading
    it back 0.1 s, and the compiled solve gives the same bits.
    """
    import jax

    folder = _exported_folder()
    if folder is None:
        return fn.lower(*args)
    path = folder / (hashlib.sha256(repr((key, _code_version())).encode()).hexdigest() + ".jaxexport")
    exported = None
    if path.is_file():
        try:
            exported = jax.export.deserialize(bytearray(path.read_bytes()))
        except Exception:  # noqa: BLE001 - a file JAX cannot read back is traced again and replaced
            exported = None
    if exported is None:
        try:
            exported = jax.export.export(fn)(*args)
            blob = exported.serialize()
        except ImportError:  # serialization needs flatbuffers (a dependency): without it, trace every time
            return fn.lower(*args)
        from usdmotion.errors import OutputError
        from usdmotion.io.atomic import atomic_output

        try:  # all of the file or none of it: two batch workers may write it at once
            with atomic_output(path) as temporary:
                temporary.write_bytes(blob)
        except OutputError:  # a cache folder it cannot write to: traced again next time
            pass
    return jax.jit(exported.call).lower(*args)


def _exported_folder() -> Path | None:
    import jax

    cache = jax.config.jax_compilation_cache_dir
    if not cache:
        return None
    folder = Path(cache) / "exported"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return folder


@lru_cache(maxsize=1)
def _code_version() -> str:
    """Digest of JAX's version, the backend and the source of :data:`TRACED_SOURCES`."""
    import jax

    package = Path(__file__).resolve().parents[2]
    digest = hashlib.sha256(f"{jax.__version__} {jax.default_backend()}".encode())
    for path in sorted(p for pattern in TRACED_SOURCES for p in package.glob(pattern)):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def frame_blocks(shards: int):
    """``args -> args`` placed for a ``shards``-device LM call: arrays split into blocks of
    frames, scalars on every device (unchanged for one device)."""
    if shards == 1:
        return lambda args: args
    import jax
    from jax.sharding import NamedSharding, PartitionSpec

    mesh = frame_mesh(shards)
    return lambda args: [jax.device_put(a, NamedSharding(mesh, PartitionSpec("frames") if a.ndim else PartitionSpec()))
                         for a in args]


def frame_mesh(shards: int):
    """The 1-D device mesh ``("frames",)`` over the first ``shards`` CPU devices."""
    import jax
    from jax.sharding import Mesh

    return Mesh(np.array(jax.devices("cpu")[:shards]), ("frames",))


def frame_shards(chunk: int) -> int:
    """CPU devices a chunk of ``chunk`` frames is split over: every CPU device JAX has
    (:func:`use_cpu_cores`) while a block keeps at least
    :data:`MIN_BLOCK_FRAMES` frames; 1 when JAX computes on an accelerator (one device does a
    chunk in one go)."""
    import jax

    if jax.default_backend() != "cpu":
        return 1
    return max(1, min(len(jax.devices("cpu")), chunk // MIN_BLOCK_FRAMES))


#: Fewest frames per device block of a sharded LM call (smaller chunks run on one device).
MIN_BLOCK_FRAMES = 32
