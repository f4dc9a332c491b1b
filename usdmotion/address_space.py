"""A cap on the process's address space while a library reads a user's file.

USD's crate (``.usdc``) reader sizes its buffers from counts stored in the file and only
then checks them against the file: a damaged 19 kB ``.usdc`` (a fuzz campaign find) made it
allocate and fill 8.5 GB (another one 3.7 GB), and on a 24 GB machine the kernel's OOM
killer ended the process, with no error line. Inside :func:`capped_address_space` such an allocation fails at once
(``std::bad_alloc``, which USD reports as an error) while every real read fits the budget:
:data:`BASE_BYTES` plus :data:`PER_CORE_BYTES` per core (TBB's worker threads, their
stacks and malloc arenas) plus :data:`PER_FILE_BYTE` bytes per byte of the file.

The limit (``RLIMIT_AS``, soft) is process-wide: the first block in sets it from the
address space in use then, nested or concurrent blocks (threads of the Studio) raise it by
their own budgets, and the last block out restores the limit that was there before. A
stricter limit set by the user (``ulimit -v``) is never loosened.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator

#: Address space a capped read may add to what the process held when it began, bytes (a
#: 2-core machine's whole Python, JAX and renderer start in ~2.3 GB from 0.1 GB).
BASE_BYTES = 2 << 30
#: ... plus this much per CPU core (a thread stack and a malloc arena each), bytes.
PER_CORE_BYTES = 256 << 20
#: ... plus this many bytes per byte of the file read (a crate file's values are compressed).
PER_FILE_BYTE = 64

_lock = threading.Lock()
_depth = 0  # blocks running now
_saved: tuple[int, int] | None = None  # the limit before the first block, where a block lowered it


def _in_use() -> int:
    """Bytes of address space the process holds now (``/proc/self/statm``'s size)."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")


def budget(path: str | os.PathLike) -> int:
    """Bytes a read of ``path`` may add to the address space (see the module docstring)."""
    try:
        size = os.path.getsize(path)
    except OSError:
        size = 0
    return BASE_BYTES + PER_CORE_BYTES * (os.cpu_count() or 1) + PER_FILE_BYTE * size


@contextlib.contextmanager
def capped_address_space(path: str | os.PathLike) -> Iterator[None]:
    """Run the block with the address space capped at what is in use plus :func:`budget`
    of ``path`` (no cap where ``RLIMIT_AS`` or ``/proc`` is not there: not Linux)."""
    global _depth, _saved
    try:
        import resource

        extra, in_use = budget(path), _in_use()
    except (ImportError, OSError, ValueError):
        yield
        return
    with _lock:
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        if _depth == 0:  # the first block: capped unless a stricter limit is set already
            cap = in_use + extra
            if soft == resource.RLIM_INFINITY or cap < soft:
                _saved = (soft, hard)
                resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
        elif _saved is not None:  # a block inside or beside it: room for its read too
            cap = soft + extra
            resource.setrlimit(resource.RLIMIT_AS, (cap if hard == resource.RLIM_INFINITY else min(cap, hard), hard))
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and _saved is not None:
                resource.setrlimit(resource.RLIMIT_AS, _saved)
                _saved = None
