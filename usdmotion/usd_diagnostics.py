"""USD's C++ diagnostics turned into usdmotion messages.

USD reports problems through its own diagnostic system: errors become a
``Tf.ErrorException`` whose text is several ``Error in 'pxrInternal_…::Func' at line N in
file …/stage.cpp : '…'`` records, and warnings go straight to stderr
(``Warning: in _Init at line 109 of …/skelDefinition.cpp``). Users must see neither:

* :func:`usd_diagnostics` traps both while a stage is read (``pxr.Tf.DiagnosticTrap``),
  re-issues each distinct warning as one :class:`~usdmotion.errors.UsdMotionWarning`
  ``FILE: </prim>: message`` and turns a raised error into one
  :class:`~usdmotion.errors.UsdReadError` naming the file and, for a text-format parse
  error, its ``.usda`` line.
* :func:`usd_error_message` does the latter for a ``Tf.ErrorException`` caught elsewhere.
* :func:`native_stderr` catches what is printed straight to file descriptor 2, past USD's
  diagnostic system and the CLI (a corrupted ``.usdc`` makes the crate reader print
  ``failed call to posix_madvise(…)``, the Python bindings ``TypeError: No to_python …``):
  :func:`usd_diagnostics` redirects fd 2 to a temporary file for the block and turns what
  was captured into its warning, or drops it when the block raised (the error says what
  is wrong); usdmotion's own lines written meanwhile are passed on.
* While :func:`usd_diagnostics` reads a file, the address space is capped
  (:func:`usdmotion.address_space.capped_address_space`): a damaged ``.usdc`` whose counts
  ask for gigabytes fails with ``bad_alloc``, reported as a damaged file, instead of
  filling the machine's memory until the kernel kills the process.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import threading
import warnings
from collections.abc import Iterator

from usdmotion.address_space import capped_address_space
from usdmotion.errors import InputError, UsdMotionWarning, UsdReadError

#: At most this many distinct USD warnings are shown per file (then a count).
MAX_WARNINGS = 5

_RECORD = re.compile(r"Error in '[^']*' at line \d+ in file [^:]* : '(.*?)'\s*(?=\n\s*Error in |\Z)", re.S)
_NAMESPACE = re.compile(r"pxrInternal_v\w*?__pxrReserved__::|\b\w+::")
_CONTROL = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|\x1b\][^\x07]*\x07|[\r\x00-\x08\x0b-\x1f]")
_OUT_OF_BOUNDS = re.compile(r"Read out-of-bounds: \d+ bytes at offset \d+ in a mapping of length \d+")
_WHERE = re.compile(r"^@?(?P<file>[^@\n]*?)@?:(?P<line>\d+):(?:(?P<col>\d+):)?\s*(?P<msg>.*)$", re.S)


def _clean(text: str) -> str:
    """One line without C++ namespaces or stray whitespace."""
    return " ".join(_NAMESPACE.sub("", text).split())


def exception_text(exc: BaseException) -> str:
    """``str(exc)``, even when USD quoted non-UTF-8 bytes of the file in its message (the
    binding's own ``str()`` then fails with ``UnicodeDecodeError``)."""
    try:
        return str(exc)
    except UnicodeDecodeError as failure:
        raw = failure.object
        return raw.decode("utf-8", "replace") if isinstance(raw, bytes) else type(exc).__name__


def usd_error_message(error: str | BaseException) -> tuple[int | None, str]:
    """``(usda_line or None, message)`` of a ``Tf.ErrorException`` (or its text).

    The most specific record wins: a parse error ``file:line:col: …`` over the generic
    ``Failed to open layer @file@`` that follows it.
    """
    text = error if isinstance(error, str) else exception_text(error)
    records = [r.strip() for r in _RECORD.findall(text)] or [text.strip()]
    for record in records:
        where = _WHERE.match(record)
        if where and where["file"]:
            return int(where["line"]), _clean(where["msg"]) or "cannot parse"
    message = _clean(records[0]) if records and records[0] else ""
    if "bad_alloc" in message:  # the crate reader sized a buffer from a damaged count (address_space)
        message = "damaged: a size stored in the file asks for more memory than the file could hold (USD: bad_alloc)"
    elif "Read out-of-bounds" in message:  # ... a count that fit the cap, checked only after the allocation
        said = _OUT_OF_BOUNDS.search(message)
        said = said[0] if said else "out of bounds"
        message = f"damaged: a size stored in the file points past its end (USD: {said})"
    return None, message or "cannot open as USD"


def _warning_text(diagnostic) -> str:
    text = _clean(str(getattr(diagnostic, "commentary", "") or ""))
    return text.replace(" -- ", ": ", 1) if text.startswith("/") else text


class _Redirect:
    """fd 2 redirected to a temporary file, shared by every block open at once (threads,
    nesting): the first block in redirects, the last one out restores. Each block, as it
    ends, takes what arrived since the last block took its share; usdmotion's own lines
    and terminal drawing (a progress bar) among it go on to the real stderr at once, the
    rest (what usd-core's C++ or the Python bindings printed) is the block's to report."""

    lock = threading.Lock()
    depth = 0
    file = None      # the temporary file behind fd 2
    saved_fd = -1    # the real stderr
    taken = 0        # bytes of the file already handed out

    @classmethod
    def enter(cls) -> None:
        with cls.lock:
            _flush_python_stderr()
            if cls.depth == 0:
                cls.file = tempfile.TemporaryFile()
                cls.saved_fd, cls.taken = os.dup(2), 0
                os.dup2(cls.file.fileno(), 2)
            cls.depth += 1

    @classmethod
    def leave(cls) -> list[str]:
        """The foreign lines captured since the last call; ours are passed on."""
        with cls.lock:
            _flush_python_stderr()
            os.lseek(cls.file.fileno(), cls.taken, os.SEEK_SET)
            raw = b""
            while chunk := os.read(cls.file.fileno(), 1 << 16):
                raw += chunk
            cls.taken += len(raw)
            ours, foreign = _sorted_lines(raw)
            if ours:
                os.write(cls.saved_fd, ours)
            cls.depth -= 1
            if cls.depth == 0:
                os.dup2(cls.saved_fd, 2)
                os.close(cls.saved_fd)
                cls.file.close()
                cls.file, cls.saved_fd = None, -1
            return foreign


def _flush_python_stderr() -> None:
    for stream in {id(s): s for s in (sys.stderr, sys.__stderr__) if s is not None}.values():
        with contextlib.suppress(Exception):
            stream.flush()


def _sorted_lines(raw: bytes) -> tuple[bytes, list[str]]:
    """``(ours, foreign)``: usdmotion's own lines and terminal drawing as raw bytes, the other
    non-blank lines as text without control characters."""
    ours, foreign = [], []
    for line in raw.splitlines(keepends=True):
        text = line.decode("utf-8", "replace")
        if text.startswith("usdmotion: ") or "\x1b" in text or text.rstrip("\n").count("\r"):
            ours.append(line)
        elif cleaned := _CONTROL.sub("", text).strip():
            foreign.append(cleaned)
    return b"".join(ours), foreign


@contextlib.contextmanager
def native_stderr() -> Iterator[list[str]]:
    """Capture what is written to file descriptor 2 during the block, by native code
    (usd-core's C++ writes there directly) or Python printing past the CLI (the bindings'
    ``TypeError: No to_python … converter`` lines).

    Yields a list that holds, after the block, those lines (control characters and blank
    lines removed). usdmotion's own lines (``usdmotion: warning: …``) and terminal drawing
    written meanwhile are passed on to the real stderr when the block ends. Safe to nest
    and to use from several threads at once (fd 2 is the process's: a line another thread
    writes meanwhile is reported by whichever block ends first).
    """
    lines: list[str] = []
    _Redirect.enter()
    try:
        yield lines
    finally:
        lines[:] = _Redirect.leave()


@contextlib.contextmanager
def usd_diagnostics(path: str | os.PathLike) -> Iterator[None]:
    """Trap USD diagnostics raised inside the block (reading ``path``).

    When the block succeeds, each distinct diagnostic becomes a warning. When it fails
    with an :class:`~usdmotion.errors.InputError`, the first diagnostic is folded into
    that error's one line instead (``…; USD: </prim>: reason``), so the user sees one line.

    Raises:
        UsdReadError: a ``Tf.ErrorException`` escaped the block (``path[:usda_line]: message``).
    """
    from pxr import Tf

    path = os.fspath(path)
    with native_stderr() as printed, Tf.DiagnosticTrap() as trap, capped_address_space(path):
        def trapped() -> list[str]:
            texts = [_warning_text(d) for d in list(trap.GetWarnings()) + list(trap.GetErrors())]
            trap.Clear()
            return list(dict.fromkeys(t for t in texts if t))

        try:
            yield
        except Tf.ErrorException as exc:
            trapped()
            line, message = usd_error_message(exc)
            raise UsdReadError(path, f"cannot read as USD: {message}", line) from None
        except UnicodeDecodeError as exc:
            # USD quotes the offending bytes in its error; a non-UTF-8 byte there makes the
            # Python binding fail to decode the message itself
            trapped()
            if not (isinstance(exc.object, bytes) and b"Error in" in exc.object):
                raise
            line, message = usd_error_message(exc.object.decode("utf-8", "replace"))
            raise UsdReadError(path, f"cannot read as USD: {message}", line) from None
        except InputError as exc:
            texts = trapped()
            if texts:
                exc.message = f"{exc.message}; USD: {texts[0]}"
                exc.args = (exc._format(),)
            raise
        except Exception:  # the reader tripped over what USD already complained about: say that
            texts = trapped()
            if texts:
                raise UsdReadError(path, f"not a usable UsdSkel stage; USD: {texts[0]}") from None
            raise
        except BaseException:
            trapped()
            raise
        texts = trapped()
    _reissue(path, texts + [_clean(line) for line in printed])


def _reissue(path: str, texts: list[str]) -> None:
    distinct = list(dict.fromkeys(t for t in texts if t))
    for text in distinct[:MAX_WARNINGS]:
        warnings.warn(f"{path}: USD: {text}", UsdMotionWarning, stacklevel=4)
    if len(distinct) > MAX_WARNINGS:
        warnings.warn(f"{path}: USD: {len(distinct) - MAX_WARNINGS} more warnings", UsdMotionWarning,
                      stacklevel=4)
