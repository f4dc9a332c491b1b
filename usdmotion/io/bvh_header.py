"""BVH ``HIERARCHY`` and ``MOTION`` header parsing (iterative, line/column aware).

Produces plain arrays; nothing here knows about rotations. The grammar accepted::

    HIERARCHY
    ROOT name {                      # name may contain spaces and ':'
        OFFSET x y z                 # exactly three numbers on the line
        CHANNELS n name_1 ... name_n # any of X/Y/Z position/rotation, any order
        JOINT name { ... }           # up to MAX_JOINT_DEPTH (1,000) levels, no recursion
        End Site { [OFFSET x y z] }  # the OFFSET may be missing (zero)
    }
    MOTION
    Frames: N
    Frame Time: dt                   # also "Frame time", "FrameTime", "=" or no colon

Keywords are case-insensitive; braces may share a line with other tokens.
"""

from __future__ import annotations

import collections
import math
import re
from dataclasses import dataclass, field

import numpy as np

from usdmotion.constants import MAX_ABS_VALUE, MAX_FPS, MAX_JOINT_DEPTH, MAX_JOINTS, MIN_FPS
from usdmotion.errors import BvhParseError
from usdmotion.motion import CHANNEL_NAMES

_TOKEN = re.compile(r"[{}]|[^\s{}]+")
_CHANNEL_LOOKUP = {c.lower(): c for c in CHANNEL_NAMES}
_FRAMES = re.compile(r"^\s*frames\s*[:=]?\s*(\S*)\s*$", re.IGNORECASE)
_FRAME_TIME = re.compile(r"^\s*frame\s*time\s*[:=]?\s*(\S*)\s*$", re.IGNORECASE)


@dataclass
class Token:
    text: str
    line: int
    column: int


@dataclass
class BvhHeader:
    """The hierarchy and motion header of a BVH file, as plain arrays."""

    joint_names: list[str] = field(default_factory=list)
    parents: list[int] = field(default_factory=list)
    offsets: list[tuple[float, float, float]] = field(default_factory=list)
    channels: list[tuple[str, ...]] = field(default_factory=list)
    end_sites: list[bool] = field(default_factory=list)
    name_tokens: list[Token] = field(default_factory=list)
    n_frames: int = 0
    frame_time: float = 0.0
    frame_time_text: str = ""
    frames_line: int = 0
    data_line: int = 0  # 1-based line number where the motion rows start


class _Cursor:
    """Token stream over the hierarchy lines with one-token lookahead, tokenized lazily
    one line at a time (a refused file costs only the lines read before its error).

    ``end_line`` is the line of ``MOTION`` (or the last line), reported when the
    hierarchy runs out of tokens.
    """

    def __init__(self, text: str, end: int, path: str | None, end_line: int, at_motion: bool):
        self._lines = enumerate(text[:end].split("\n"), start=1)
        self._buffer: collections.deque[Token] = collections.deque()  # the rest of the current line
        self.last: Token | None = None
        self.path = path
        self.end_line = end_line
        self.at_motion = at_motion

    def peek(self) -> Token | None:
        while not self._buffer:
            line_no, line = next(self._lines, (None, None))
            if line is None:
                return None
            self._buffer.extend(Token(m.group(0), line_no, m.start() + 1) for m in _TOKEN.finditer(line))
        return self._buffer[0]

    def next(self, expected: str) -> Token:
        tok = self.peek()
        if tok is None:
            last = self.last or Token("", 1, 1)
            raise BvhParseError(self.path, f"file ends inside the hierarchy, expected {expected}", last.line)
        self.last = self._buffer.popleft()
        return tok

    def rest_of_line(self, line: int) -> list[Token]:
        """Tokens not yet read on ``line`` (the current line)."""
        return [t for t in self._buffer if t.line == line]

    def error(self, tok: Token, message: str) -> BvhParseError:
        return BvhParseError(self.path, message, tok.line, tok.column)


def _parse_float(cur: _Cursor, tok: Token, what: str) -> float:
    try:
        value = float(tok.text)
    except ValueError:
        raise cur.error(tok, f"{what}: {tok.text!r} is not a number") from None
    if not math.isfinite(value):
        raise cur.error(tok, f"{what}: {tok.text!r} is not a finite number")
    if abs(value) > MAX_ABS_VALUE:
        raise cur.error(tok, f"{what}: {tok.text} is beyond ±{MAX_ABS_VALUE:g}")
    return value


def _read_offset(cur: _Cursor, keyword: Token) -> tuple[float, float, float]:
    values = []
    for k in range(3):
        tok = cur.next("an OFFSET value")
        if tok.line != keyword.line or tok.text in "{}":
            raise cur.error(tok if tok.line == keyword.line else keyword,
                            f"OFFSET has {k} values, expected 3")
        values.append(_parse_float(cur, tok, "OFFSET"))
    extra = cur.peek()
    if extra is not None and extra.line == keyword.line and extra.text not in "{}":
        count = 3 + sum(1 for t in cur.rest_of_line(keyword.line) if t.text not in "{}")
        raise cur.error(extra, f"OFFSET has {count} values, expected 3")
    return values[0], values[1], values[2]


def _read_channels(cur: _Cursor, keyword: Token) -> tuple[str, ...]:
    count_tok = cur.next("the number of CHANNELS")
    try:
        count = int(count_tok.text)
    except ValueError:
        raise cur.error(count_tok, f"CHANNELS count {count_tok.text!r} is not an integer") from None
    if not 0 <= count <= 6:
        raise cur.error(count_tok, f"CHANNELS count {count} is outside 0..6")
    names = []
    for k in range(count):
        tok = cur.peek()
        name = None if tok is None else _CHANNEL_LOOKUP.get(tok.text.lower())
        if name is None:
            where = tok if tok is not None else count_tok
            raise cur.error(where, f"CHANNELS says {count} but lists {k} channel names"
                            + ("" if tok is None else f" (then {tok.text!r})"))
        cur.next("")
        if name in names:
            raise cur.error(tok, f"channel {name} is listed twice")
        names.append(name)
    extra = cur.peek()
    if extra is not None and extra.line == keyword.line and extra.text.lower() in _CHANNEL_LOOKUP:
        raise cur.error(extra, f"CHANNELS says {count} but lists more channel names")
    return tuple(names)


def _read_name(cur: _Cursor, keyword: Token) -> tuple[str, Token]:
    parts = []
    first = None
    while (tok := cur.peek()) is not None and tok.line == keyword.line and tok.text not in "{}":
        parts.append(tok.text)
        first = first or tok
        cur.next("")
    if not parts:
        raise cur.error(keyword, f"{keyword.text} has no name")
    return " ".join(parts), first


def _parse_hierarchy(cur: _Cursor, header: BvhHeader) -> None:
    """Fill ``header`` from the tokens between HIERARCHY and MOTION (explicit stack)."""
    first = cur.next("HIERARCHY")
    if first.text.upper() != "HIERARCHY":
        raise cur.error(first, f"expected HIERARCHY, found {first.text!r} (is this a BVH file?)")
    root_kw = cur.next("ROOT")
    if root_kw.text.upper() != "ROOT":
        raise cur.error(root_kw, f"expected ROOT, found {root_kw.text!r}")
    stack: list[int] = []  # open joint blocks (index into header lists)
    seen_offset: list[bool] = []
    pending = ("ROOT", root_kw, -1)
    while True:
        if pending is not None:
            kind, kw, parent = pending
            pending = None
            if kind == "End":
                name = header.joint_names[parent] + "_End"
                name_tok = kw
            else:
                name, name_tok = _read_name(cur, kw)
            brace = cur.next("'{'")
            if brace.text != "{":
                raise cur.error(brace, f"expected '{{' after {kw.text} {name}, found {brace.text!r}")
            if len(header.joint_names) >= MAX_JOINTS:
                raise cur.error(kw, f"more than {MAX_JOINTS} joints; at most {MAX_JOINTS} are supported "
                                    "(far more than any real rig)")
            if len(stack) > MAX_JOINT_DEPTH:
                raise cur.error(kw, f"{name} is {len(stack)} levels deep; at most {MAX_JOINT_DEPTH} are "
                                    "supported (far more than any real rig)")
            header.joint_names.append(name)
            header.parents.append(parent)
            header.offsets.append((0.0, 0.0, 0.0))
            header.channels.append(())
            header.end_sites.append(kind == "End")
            header.name_tokens.append(name_tok)
            stack.append(len(header.joint_names) - 1)
            seen_offset.append(False)
        if cur.peek() is None:
            if cur.at_motion:
                raise BvhParseError(cur.path, f"MOTION before the hierarchy is closed: {len(stack)} '}}' missing",
                                    cur.end_line)
            raise BvhParseError(cur.path, f"file ends inside the hierarchy ({len(stack)} '}}' missing)",
                                cur.end_line)
        tok = cur.next("'}'")
        word = tok.text.upper()
        current = stack[-1]
        is_end = header.end_sites[current]
        if word == "OFFSET":
            if seen_offset[-1]:
                raise cur.error(tok, f"second OFFSET in {header.joint_names[current]}")
            header.offsets[current] = _read_offset(cur, tok)
            seen_offset[-1] = True
        elif word == "CHANNELS" and not is_end:
            if header.channels[current]:
                raise cur.error(tok, f"second CHANNELS in {header.joint_names[current]}")
            header.channels[current] = _read_channels(cur, tok)
        elif word == "JOINT" and not is_end:
            pending = ("JOINT", tok, current)
        elif word == "END" and not is_end:
            site = cur.next("Site")
            if site.text.upper() != "SITE":
                raise cur.error(site, f"expected 'End Site', found 'End {site.text}'")
            pending = ("End", tok, current)
        elif tok.text == "}":
            if not seen_offset[-1] and not is_end:
                raise cur.error(tok, f"{header.joint_names[current]} has no OFFSET")
            stack.pop()
            seen_offset.pop()
            if not stack:
                return
        elif word == "MOTION":
            raise cur.error(tok, f"MOTION inside the hierarchy: {len(stack)} '}}' missing")
        elif word == "ROOT":
            raise cur.error(tok, "ROOT inside another joint (missing '}')")
        else:
            inside = "End Site" if is_end else header.joint_names[current]
            raise cur.error(tok, f"unexpected {tok.text!r} in {inside}")


def parse_header(text: str, path: str | None) -> BvhHeader:
    """Parse everything before the motion rows. ``text`` uses ``\\n`` line ends."""
    header = BvhHeader()
    motion_at = re.search(r"^[ \t]*MOTION[ \t]*$", text, re.IGNORECASE | re.MULTILINE)
    hierarchy_end = motion_at.start() if motion_at else len(text)
    last_content_line = len(text[:hierarchy_end].rstrip().split("\n"))
    end_line = text.count("\n", 0, hierarchy_end) + 1 if motion_at else last_content_line
    cur = _Cursor(text, hierarchy_end, path, end_line, motion_at is not None)
    if cur.peek() is None:
        raise BvhParseError(path, "no HIERARCHY section (empty or blank file?)", 1)
    _parse_hierarchy(cur, header)
    extra = cur.peek()
    if extra is not None:
        if extra.text.upper() == "ROOT":
            raise cur.error(extra, "a second ROOT hierarchy; only one skeleton per file is supported")
        raise cur.error(extra, f"unexpected {extra.text!r} after the hierarchy (unbalanced braces?)")
    if motion_at is None:
        raise BvhParseError(path, "no MOTION section after the hierarchy", last_content_line)
    _parse_motion_header(text, motion_at.end(), header, path)
    return header


def _parse_motion_header(text: str, start: int, header: BvhHeader, path: str | None) -> None:
    """Read ``Frames:`` and ``Frame Time:`` (any order, blank lines allowed) after MOTION."""
    line_no = text.count("\n", 0, start) + 1  # the MOTION line
    nl = text.find("\n", start)
    pos = len(text) if nl < 0 else nl + 1
    found: dict[str, tuple[str, int]] = {}
    while len(found) < 2:
        what = "Frames:" if "frames" not in found else "Frame Time:"
        if pos >= len(text):
            raise BvhParseError(path, f"file ends before '{what}' in the MOTION header", line_no)
        nl = text.find("\n", pos)
        end = len(text) if nl < 0 else nl
        line = text[pos:end]
        pos = end + 1
        line_no += 1
        if not line.strip():
            continue
        if (m := _FRAME_TIME.match(line)) and "frame_time" not in found:
            found["frame_time"] = (m.group(1), line_no)
        elif (m := _FRAMES.match(line)) and "frames" not in found:
            found["frames"] = (m.group(1), line_no)
        else:
            raise BvhParseError(path, f"expected '{what}', found {line.strip()[:40]!r}", line_no, 1)
    frames_text, frames_line = found["frames"]
    try:
        n_frames = int(frames_text)
    except ValueError:
        raise BvhParseError(path, f"Frames: {frames_text!r} is not an integer", frames_line) from None
    if n_frames < 0:
        raise BvhParseError(path, f"Frames: {n_frames} is negative", frames_line)
    time_text, time_line = found["frame_time"]
    try:
        frame_time = float(time_text)
    except ValueError:
        raise BvhParseError(path, f"Frame Time: {time_text!r} is not a number", time_line) from None
    if not (math.isfinite(frame_time) and frame_time > 0):
        raise BvhParseError(path, f"Frame Time: {time_text} must be a positive number of seconds", time_line)
    if not 1.0 / MAX_FPS <= frame_time <= 1.0 / MIN_FPS:
        raise BvhParseError(path, f"Frame Time: {time_text} s is outside {1 / MAX_FPS:g}..{1 / MIN_FPS:g} s "
                                  "(one frame a microsecond to one an hour)", time_line)
    header.n_frames = n_frames
    header.frame_time = frame_time
    header.frame_time_text = time_text
    header.frames_line = frames_line
    header.data_line = line_no + 1


def header_arrays(header: BvhHeader) -> tuple[np.ndarray, np.ndarray]:
    """``(parents (J,) int32, offsets (J, 3) float64)`` of a parsed header."""
    return np.asarray(header.parents, dtype=np.int32), np.asarray(header.offsets, dtype=np.float64)


_NTSC_BASES = (24, 30, 48, 60, 120, 240)
_STANDARD_RATES = (tuple(float(r) for r in range(1, 1001))
                   + tuple(k * 1000.0 / 1001.0 for k in _NTSC_BASES)
                   + (23.976, 29.97, 47.952, 59.94, 119.88, 239.76))


def frame_rate(frame_time_text: str) -> float:
    """Frames per second for a ``Frame Time`` as written.

    Exporters round the frame time (``.0083333`` for 120 fps). If a standard rate
    (integer, or NTSC ``k·1000/1001`` and its decimal forms 23.976, 29.97, ...) has a
    frame time that, rounded to the decimals written, gives exactly the text, that rate
    is returned; otherwise ``1 / frame_time``. Texts too short to pin the rate to 0.2 %
    are taken literally.
    """
    frame_time = float(frame_time_text)
    mantissa = frame_time_text.strip().lower().split("e")[0]
    if "e" in frame_time_text.lower() or "." not in mantissa:
        return 1.0 / frame_time
    decimals = len(mantissa.split(".")[1])
    if 0.5 * 10.0**-decimals > 2e-3 * frame_time:  # the text does not pin the rate to 0.2 %
        return 1.0 / frame_time
    raw = 1.0 / frame_time
    near = [rate for rate in _STANDARD_RATES if abs(rate - raw) <= 0.01 * raw]  # within 1 %, nearest first:
    for rate in sorted(near, key=lambda r: abs(r - raw)):                    # sorting only those (start-up)
        if round(1.0 / rate, decimals) == round(frame_time, decimals):
            return rate
    return raw


def frame_time_text(fps: float) -> str:
    """The ``Frame Time`` to write for ``fps``: the shortest text with 6 to 9 decimals (as
    exporters write it: ``0.008333``, ``0.008342``) that :func:`frame_rate` reads back as
    exactly ``fps``, so a file's frame time survives a round trip as read; else ``%.10g``."""
    for decimals in range(6, 10):
        text = f"{1.0 / fps:.{decimals}f}"
        if float(text) > 0 and frame_rate(text) == fps:
            return text
    return f"{1.0 / fps:.10g}"
