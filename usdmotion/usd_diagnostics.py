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
* :func:`native_stderr` catches what USD's C++ code prints straight to file descriptor 2,
  bypassing its own diagnostic system (a corrupted ``.usdc`` makes the crate reader print
  ``failed call to posix_madvise(…)``): :func:`usd_diagnostics` redirects fd 2 to a
  temporary file for the block and turns what was captured into its one warning, or drops
  it when the block raised (the error already says what is wrong).
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

from usdmotion.errors import InputError, UsdMotionWarning, UsdReadError

#: At most this many distinct USD warnings are shown per file (then a count).
MAX_WARNINGS = 5

_RECORD = re.compile(r"Error in '[^']*' at line \d+ in file [^:]* : '(.*?)'\s*(?=\n\s*Error in |\Z)", re.S)
_NAMESPACE = re.compile(r"pxrInternal_v\w*?__pxrReserved__::|\b\w+::")
_CONTROL = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|\x1b\][^\x07]*\x07|[\r\x00-\x08\x0b-\x1f]")
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
    return None, message or "cannot open as USD"


def _warning_text(diagnostic) -> str:
    text = _clean(str(getattr(diagnostic, "commentary", "") or ""))
    return text.replace(" -- ", ": ", 1) if text.startswith("/") else text


class _Redirect:
    """fd 2 redirected to a temporary file, shared by every block open at once (threads,
    nesting): the first block in redirects, the last one out restores; each block takes
    what arrived while it ran. Python's own ``sys.stderr`` keeps writing to the real
    stderr meanwhile (warnings, the CLI's lines), so only native writes are captured."""

    lock = threading.Lock()
    depth = 0
    file = None          # the temporary file behind fd 2
    saved_fd = -1        # the real stderr
    saved_stream = None  # sys.stderr before the block, when it wrote to fd 2

    @classmethod
    def enter(cls) -> int:
        with cls.lock:
            if cls.depth == 0:
                cls._redirect()
            cls.depth += 1
            return cls.file.seek(0, os.SEEK_END)

    @classmethod
    def leave(cls, start: int) -> str:
        with cls.lock:
            cls.file.seek(start)
            text = cls.file.read().decode("utf-8", "replace")
            cls.depth -= 1
            if cls.depth == 0:
                cls._restore()
            return text

    @classmethod
    def _redirect(cls) -> None:
        stream = sys.stderr
        with contextlib.suppress(Exception):
            stream.flush()
        cls.file = tempfile.TemporaryFile()
        cls.saved_fd = os.dup(2)
        os.dup2(cls.file.fileno(), 2)
        cls.saved_stream = None
        if _writes_to_fd2(stream):  # keep Python's writes on the real stderr
            cls.saved_stream = stream
            sys.stderr = open(cls.saved_fd, "w", buffering=1, closefd=False,  # noqa: SIM115
                              encoding=getattr(stream, "encoding", None) or "utf-8", errors="backslashreplace")

    @classmethod
    def _restore(cls) -> None:
        if cls.saved_stream is not None:
            with contextlib.suppress(Exception):
                sys.stderr.flush()
            sys.stderr = cls.saved_stream
            cls.saved_stream = None
        os.dup2(cls.saved_fd, 2)
        os.close(cls.saved_fd)
        cls.file.close()
        cls.file, cls.saved_fd = None, -1


def _writes_to_fd2(stream) -> bool:
    try:
        return stream.fileno() == 2
    except Exception:  # noqa: BLE001 - pytest's capsys, StringIO: not fd 2
        return False


@contextlib.contextmanager
def native_stderr() -> Iterator[list[str]]:
    """Capture what native code writes to file descriptor 2 during the block.

    Yields a list that holds, after the block, the captured lines (terminal control
    sequences and blank lines removed). Safe to nest and to use from several threads at
    once (fd 2 is the process's: a native write from another thread meanwhile is captured
    too, and reported by whichever block is open). ``sys.stderr`` is kept on the real
    stderr while fd 2 is redirected, so Python's own messages are never held back.
    """
    lines: list[str] = []
    start = _Redirect.enter()
    try:
        yield lines
    finally:
        text = _Redirect.leave(start)
        lines[:] = [line for line in (_CONTROL.sub("", raw).strip() for raw in text.splitlines()) if line]


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
    with native_stderr() as printed, Tf.DiagnosticTrap() as trap:
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
