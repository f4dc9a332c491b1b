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
"""

from __future__ import annotations

import contextlib
import os
import re
import warnings
from collections.abc import Iterator

from usdmotion.errors import InputError, UsdMotionWarning, UsdReadError

#: At most this many distinct USD warnings are shown per file (then a count).
MAX_WARNINGS = 5

_RECORD = re.compile(r"Error in '[^']*' at line \d+ in file [^:]* : '(.*?)'\s*(?=\n\s*Error in |\Z)", re.S)
_NAMESPACE = re.compile(r"pxrInternal_v\w*?__pxrReserved__::|\b\w+::")
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
    with Tf.DiagnosticTrap() as trap:
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
        _reissue(path, trapped())


def _reissue(path: str, texts: list[str]) -> None:
    distinct = list(dict.fromkeys(t for t in texts if t))
    for text in distinct[:MAX_WARNINGS]:
        warnings.warn(f"{path}: USD: {text}", UsdMotionWarning, stacklevel=4)
    if len(distinct) > MAX_WARNINGS:
        warnings.warn(f"{path}: USD: {len(distinct) - MAX_WARNINGS} more warnings", UsdMotionWarning,
                      stacklevel=4)
