"""Parsing the BVH motion rows into one ``(F, C)`` float array, vectorised.

Three paths, fastest first:

1. pyarrow's CSV reader (C++, multi-threaded, correctly rounded floats) on the raw
   bytes, single spaces between values: the layout nearly every exporter writes.
2. The same after a vectorised NumPy pass that collapses runs of spaces/tabs and strips
   leading/trailing whitespace and ``\\r`` on every line.
3. Only when a file is broken: a per-line scan that names the first bad line and
   column (or, with ``lenient``, keeps the complete rows and says what it dropped).
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass

import numpy as np

from usdmotion.errors import BvhParseError, UsdMotionWarning


@dataclass
class Rows:
    """Parsed motion rows: ``values (F, C)`` and what ``lenient`` dropped."""

    values: np.ndarray
    dropped: int = 0
    first_dropped_line: int | None = None


def _arrow_parse(buf, n_channels: int, expected_rows: int | None = None) -> np.ndarray | None:
    """``(F, C)`` float64 via pyarrow, or ``None`` if the bytes are not clean rows.

    ``buf`` (bytes or a memoryview of them, not copied) is read in blocks by pyarrow's
    streaming CSV reader, each block copied into one preallocated array of
    ``expected_rows`` rows (the header's ``Frames:``; grown if the file has more), so the
    peak is the array plus a block, not the whole parsed table beside its copy.
    """
    import pyarrow as pa
    import pyarrow.csv as pcsv

    if n_channels == 0 or not len(buf) or bytes(buf[:4096]).isspace() and bytes(buf).isspace():
        return None
    read = pcsv.ReadOptions(autogenerate_column_names=True, block_size=1 << 22)
    parse = pcsv.ParseOptions(delimiter=" ", quote_char=False, escape_char=False,
                              double_quote=False, ignore_empty_lines=True)
    convert = pcsv.ConvertOptions(
        column_types={f"f{k}": pa.float64() for k in range(n_channels)},
        null_values=[], strings_can_be_null=False, quoted_strings_can_be_null=False,
    )
    # a row takes at least two bytes per value: a Frames: claim beyond that is not allocated
    capacity = max(min(int(expected_rows or 0), len(buf) // (2 * n_channels) + 1), 1)
    out = np.empty((capacity, n_channels), dtype=np.float64)
    rows = 0
    try:
        reader = pcsv.open_csv(pa.BufferReader(pa.py_buffer(buf)), read_options=read, parse_options=parse,
                               convert_options=convert)
        if len(reader.schema) != n_channels:
            return None
        for batch in reader:
            n = batch.num_rows
            if rows + n > capacity:  # more rows than Frames: says (the caller reports it)
                capacity = max(2 * capacity, rows + n)
                out = np.resize(out, (capacity, n_channels))
            for k, column in enumerate(batch.columns):
                out[rows:rows + n, k] = _float64_values(column)
            rows += n
    except (pa.ArrowInvalid, pa.ArrowTypeError, pa.ArrowNotImplementedError):
        return None
    return out if rows == capacity else out[:rows].copy()


def _float64_values(chunk) -> np.ndarray:
    """The values of a null-free float64 pyarrow array, read from its data buffer:
    ``Array.to_numpy`` would import pandas (0.16 s of start-up) for nothing."""
    return np.frombuffer(chunk.buffers()[1], dtype=np.float64, count=len(chunk), offset=chunk.offset * 8)


def normalize_whitespace(buf: bytes) -> bytes:
    """Collapse whitespace runs to one space and strip every line (vectorised).

    Removes ``\\r``, tabs and other blanks at line starts and ends; keeps ``\\n``.
    """
    b = np.frombuffer(buf, dtype=np.uint8)
    if b.size == 0:
        return buf
    newline = b == 10
    blank = (b == 32) | (b == 9) | (b == 13) | (b == 11) | (b == 12)
    content = ~(blank | newline)
    # a blank is kept iff it is the last of its run, followed by content, and the line
    # already had content before it
    next_is_content = np.zeros_like(content)
    next_is_content[:-1] = content[1:]
    index = np.arange(b.size)
    last_newline = np.maximum.accumulate(np.where(newline, index, -1))
    content_count = np.cumsum(content)
    count_at_line_start = np.where(last_newline >= 0, content_count[np.maximum(last_newline, 0)], 0)
    has_content_before = (content_count - content) > count_at_line_start
    keep = content | newline | (blank & next_is_content & has_content_before)
    out = b[keep].copy()
    out[out == 9] = 32
    out[(out == 11) | (out == 12) | (out == 13)] = 32
    return out.tobytes()


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
               lenient: bool = False, expected_rows: int | None = None) -> Rows:
    """Parse motion rows ``buf`` (bytes after the ``Frame Time`` line).

    Args:
        buf: the motion rows, any line ends, blank lines allowed (a memoryview is read without copying).
        n_channels: ``C``, values per row declared by the hierarchy.
        first_line: 1-based line number of the first byte of ``buf`` (for errors).
        lenient: drop rows with the wrong number of values (with a warning).
        expected_rows: the row count the header declares (the array is allocated once for it).

    Raises:
        BvhParseError: a row with the wrong number of values or a non-number.
    """
    if n_channels == 0:
        buf = bytes(buf)
        lines = [line for line in buf.split(b"\n") if line.strip()]
        if lines:
            k = next(i for i, line in enumerate(buf.split(b"\n")) if line.strip())
            if not lenient:
                raise BvhParseError(path, "motion row has values but the hierarchy declares no channels",
                                    first_line + k)
        return Rows(np.zeros((0, 0)))
    values = _arrow_parse(buf, n_channels, expected_rows)  # the buffer as is (no copy): nearly every file
    if values is None:
        buf = bytes(buf)
        if b"\r" in buf and b"\n" not in buf:  # classic-Mac line ends
            buf = buf.replace(b"\r", b"\n")
        values = _arrow_parse(normalize_whitespace(buf), n_channels, expected_rows)
    if values is not None:
        return Rows(values)
    rows = _line_scan(buf, n_channels, first_line, path, lenient)
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
