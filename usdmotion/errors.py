"""Typed errors raised at the library boundary.

Every error a user can provoke with bad input is a :class:`UsdMotionError`; the CLI
prints ``str(error)`` as one line and exits with code 2.
"""

from __future__ import annotations

from pathlib import Path


class UsdMotionError(Exception):
    """Base class of every error caused by input, options or the environment."""


class InputError(UsdMotionError):
    """A file could not be used: ``path[:line[:column]]: message``.

    ``line`` and ``column`` are 1-based, ``None`` where unknown.
    """

    def __init__(self, path: str | Path | None, message: str, line: int | None = None,
                 column: int | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        self.column = column
        self.message = message
        super().__init__(self._format())

    def _format(self) -> str:
        where = self.path or "<input>"
        if self.line is not None:
            where += f":{self.line}"
            if self.column is not None:
                where += f":{self.column}"
        return f"{where}: {self.message}"


class BvhParseError(InputError):
    """A BVH file is malformed; names the file, line and (where known) column."""


class UsdReadError(InputError):
    """A USD file could not be read as a skeleton animation."""


class TopologyError(UsdMotionError, ValueError):
    """A joint hierarchy is invalid (parents after children, cycles, several roots...)."""


class OutputError(UsdMotionError):
    """An output file could not be written (unwritable path, unknown extension...)."""


class UsdMotionWarning(UserWarning):
    """A recoverable problem in the input (e.g. ``--lenient`` dropped rows)."""


#: What the CLI reports as bad input (exit 2): the library's own errors and the standard ones a
#: reader or an option check raises. Anything else is a bug (``internal error``, exit 1).
INPUT_ERRORS = (UsdMotionError, ValueError, KeyError, OSError, MemoryError)


def error_message(exc: BaseException) -> str:
    """The one line ``usdmotion`` reports for ``exc`` after ``usdmotion: error:``: its message's
    first line (a ``KeyError``'s key without quotes; the type's name for an empty message), or
    ``internal error (Type: line)`` for an exception that is not one of :data:`INPUT_ERRORS`.

    The CLI (:func:`usdmotion.cli.main`) and the Studio (library rows, takes that fail, jobs) both
    print this line, so a file gives the same line in both."""
    text = str(exc.args[0] if isinstance(exc, KeyError) and exc.args else exc)
    line = text.splitlines()[0] if text.strip() else type(exc).__name__
    if not isinstance(exc, INPUT_ERRORS):
        return f"internal error ({type(exc).__name__}: {line if str(exc) else ''})"
    return line


def error_line(exc: BaseException) -> str:
    """``usdmotion: error: `` and :func:`error_message`: the whole line the CLI prints."""
    return f"usdmotion: error: {error_message(exc)}"
