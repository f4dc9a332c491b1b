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
