"""Atomic output: write to a temporary file beside the target, then rename.

A failed or interrupted write never leaves a partial file at the target path.
"""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

from usdmotion.errors import OutputError


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success.

    The temporary name keeps the target's extension (``suffix``), which USD needs to
    pick the file format. On any exception the temporary file is removed.

    Raises:
        OutputError: the folder does not exist or is not writable.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise OutputError(f"{path}: folder {folder} does not exist")
    suffix = path.suffix if suffix is None else suffix
    tmp = None
    held = _hold_signals()  # a Ctrl-C between creating the file and knowing its name would leak it
    try:
        try:
            fd, tmp_name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp" + suffix, dir=folder)
        except OSError as exc:
            raise OutputError(f"{path}: cannot write in {folder}: {exc.strerror or exc}") from None
        os.close(fd)
        tmp = Path(tmp_name)
        held = _release_signals(held)  # a signal held meanwhile is raised here, inside the try
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual permissions
        os.replace(tmp, path)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from None
    finally:
        _release_signals(held)
        if tmp is not None:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()


_HELD = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}


def _hold_signals():
    """Block SIGINT/SIGTERM/SIGHUP (main thread only); returns the previous mask or None."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)


def _release_signals(previous) -> None:
    """Restore the mask ``_hold_signals`` returned; a signal that arrived meanwhile is delivered."""
    if previous is not None:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
    return None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
