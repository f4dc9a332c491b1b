"""Parsing the BVH motion rows into one ``(F, C)`` float array, vectorised.

Two paths, fastest first:

1. NumPy's C text reader (``np.loadtxt`` on the bytes, whitespace-separated, no comment
   character): any runs of spaces and tabs, ``\\r\\n`` line ends and blank lines; floats
   correctly rounded, like ``float()``. It reads the buffer in chunks (no per-line Python
   objects; the file's bytes shared, not copied, see :func:`_reader`) and needs no pyarrow: pyarrow's CSV reader, used here before, cost 0.03 s of
   import on every BVH read and more CPU time than this on large files
   (``benchmarks/startup.py``, ``benchmarks/parse_convert.py``).
2. Only when a file is broken (a row of another length, a token that is not a number,
   bytes that are not UTF-8): a per-line scan that names the first bad line and column
   (or, with ``lenient``, keeps the complete rows and says what it dropped). Whatever the
   first path accepts, this one reads to the same values (``float`` of the same tokens).
"""

from __future__ import annotations

import io
import re
import warnings
from dataclasses import dataclass

import numpy as np

from usdmotion.errors import BvhParseError, UsdMotionWarning

#: A digit: rows without one (blank, or only Unicode blanks such as U+2028, which loadtxt
#: reads as no data, with a warning) are left to the line scan.
_DIGIT = re.compile(rb"[0-9]")
_CR, _LF = re.compile(rb"\r"), re.compile(rb"\n")


@dataclass
class Rows:
    """Parsed motion rows: ``values (F, C)`` and what ``lenient`` dropped."""

    values: np.ndarray
    dropped: int = 0
    first_dropped_line: int | None = None


def _fast_parse(buf: bytes, n_channels: int) -> np.ndarray | None:
    """``(F, C)`` float64 via NumPy's text reader, or ``None`` if the bytes are not clean rows."""
    if n_channels == 0 or _DIGIT.search(buf) is None:
        return None
    try:
        values = np.loadtxt(_reader(buf), dtype=np.float64, comments=None, ndmin=2, encoding="utf-8")
    except ValueError:  # a row of another length, a non-number, invalid UTF-8 (UnicodeDecodeError)
        return None
    return values if values.size and values.shape[1] == n_channels else None


def _reader(buf: bytes | memoryview) -> io.BytesIO:
    """``buf`` as a binary file, without a copy of a long take's rows: ``BytesIO`` shares a
    ``bytes`` object until written to (it copies anything else, a memoryview included), so
    a view that ends a ``bytes`` object (the rows of a file's bytes) is read from its offset."""
    owner = buf.obj if isinstance(buf, memoryview) else buf
    if isinstance(owner, bytes) and owner is not buf:
        whole, view = np.frombuffer(owner, np.uint8), np.frombuffer(buf, np.uint8)
        start = view.ctypes.data - whole.ctypes.data
        if 0 <= start and start + view.size == whole.size:
            stream = io.BytesIO(owner)
            stream.seek(start)
            return stream
    return io.BytesIO(buf)


def _line_scan(buf: bytes, n_channels: int, first_line: int, path: str | None,
               lenient: bool) -> Rows:
    """Slow, exact scan: the first bad line/column, or (lenient) the complete rows."""
    rows: list[list[str]] = []
    dropped = 0
    first_dropped = None
    lines = buf.decode("utf-8").split("\n")
    last_content = max((k for k, line in enumerate(lines) if line.strip()), default=-1)
    for k, line in enumerate(lines):
        tokens = line.split()
        if not tokens:
            continue
        line_no = first_line + k
        if len(tokens) != n_channels:
            if lenient:
                dropped += 1
                first_dropped = first_dropped or line_no
                continue
            kind = "truncated motion row" if (k == last_content and len(tokens) < n_channels) else "motion row"
            raise BvhParseError(path, f"{kind} has {len(tokens)} values, the hierarchy declares "
                                      f"{n_channels} channels", line_no)
        try:
            rows.append([float(t) for t in tokens])
        except ValueError:
            col_tok = next(t for t in tokens if not _is_float(t))
            column = line.find(col_tok) + 1
            if lenient:
                dropped += 1
                first_dropped = first_dropped or line_no
                continue
            raise BvhParseError(path, f"{col_tok[:30]!r} is not a number", line_no, column) from None
    values = np.asarray(rows, dtype=np.float64).reshape(len(rows), n_channels)
    return Rows(values, dropped, first_dropped)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def parse_rows(buf: bytes | memoryview, n_channels: int, first_line: int, path: str | None,
               lenient: bool = False) -> Rows:
    """Parse motion rows ``buf`` (bytes after the ``Frame Time`` line).

    Args:
        buf: the motion rows, any line ends, blank lines allowed; a memoryview of the file's
            bytes is read as it is (no copy of a long take's rows) unless the rows are broken.
        n_channels: ``C``, values per row declared by the hierarchy.
        first_line: 1-based line number of the first byte of ``buf`` (for errors).
        lenient: drop rows with the wrong number of values (with a warning).

    Raises:
        BvhParseError: a row with the wrong number of values or a non-number.
    """
    if isinstance(buf, memoryview) and (n_channels == 0 or (_CR.search(buf) and not _LF.search(buf))):
        buf = bytes(buf)
    if isinstance(buf, bytes) and b"\r" in buf and b"\n" not in buf:  # classic-Mac line ends
        buf = buf.replace(b"\r", b"\n")
    if n_channels == 0:
        lines = [line for line in buf.split(b"\n") if line.strip()]
        if lines:
            k = next(i for i, line in enumerate(buf.split(b"\n")) if line.strip())
            if not lenient:
                raise BvhParseError(path, "motion row has values but the hierarchy declares no channels",
                                    first_line + k)
        return Rows(np.zeros((0, 0)))
    values = _fast_parse(buf, n_channels)
    if values is not None:
        return Rows(values)
    rows = _line_scan(bytes(buf), n_channels, first_line, path, lenient)
    if rows.dropped:
        warnings.warn(f"{path}:{rows.first_dropped_line}: dropped {rows.dropped} motion row(s) "
                      f"without exactly {n_channels} values (--lenient)", UsdMotionWarning, stacklevel=2)
    return rows


def line_of_row(buf: bytes, row: int, first_line: int) -> int:
    """1-based line number of non-blank row ``row`` of ``buf`` (error reporting only)."""
    seen = -1
    for k, line in enumerate(buf.split(b"\n")):
        if line.strip():
            seen += 1
            if seen == row:
                return first_line + k
    return first_line
