"""Acclaim skeleton files (``.asf``, CMU mocap): ``parse_asf`` → :class:`AsfSkeleton`.

Only the skeleton; the motion (``.amc``) is read by :mod:`usdmotion.io.amc`.

Conventions (Acclaim ASF as written by Vicon BodyBuilder for the CMU database):

* ``direction`` is a unit vector and ``length`` a length in the *global* rest frame; a
  bone starts where its parent ends (the root has no length).
* ``axis ax ay az ORDER`` is the orientation ``C`` of the bone's local frame in the world,
  the rotations applied in the order named (``XYZ`` → ``C = Rz(az) @ Ry(ay) @ Rx(ax)``).
  An AMC value set ``M`` (its ``dof`` axes applied in the order listed) rotates the bone
  about that frame, so the bone's rotation relative to its parent, in world-aligned
  axes, is ``C @ M @ C⁻¹``.
* ``:units length L`` means one file unit is ``1/L`` inch (CMU: 0.45); ``angle deg|rad``
  is the unit of ``axis``, ``orientation`` and (unless the AMC says otherwise) AMC angles.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdmotion.errors import InputError

ROTATION_DOFS = ("rx", "ry", "rz")
_SECTIONS = (":version", ":name", ":units", ":documentation", ":root", ":bonedata", ":hierarchy")


class AsfParseError(InputError):
    """An ASF file is malformed; names the file and line."""


@dataclass(frozen=True)
class AsfSkeleton:
    """An Acclaim skeleton as arrays, bones in depth-first order (root first).

    Attributes:
        names: ``B`` bone names, ``names[0] == "root"``, parents before children.
        parents: ``(B,)`` parent bone index, ``-1`` for the root.
        directions: ``(B, 3)`` direction of each bone in the world rest frame, as written (a unit
            vector to the file's precision; root: 0).
        lengths: ``(B,)`` bone lengths, file units (root: 0).
        axes: ``(B, 3)`` the ``axis`` angles in radians (root: ``orientation``).
        axis_orders: per bone, the order the ``axis`` rotations are applied in (``"XYZ"``).
        dofs: per bone, its AMC channel names in file order (``("rx", "ry", "rz")``; the
            root's come from ``:root order``, e.g. ``("tx", "ty", "tz", "rx", "ry", "rz")``).
        root_position: ``(3,)`` the root ``position``, file units.
        length_unit: the ``:units length`` value (1 file unit = 1/length_unit inch).
        angles_in_degrees: ``:units angle`` is ``deg``.
        path: the file read, for messages.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    directions: np.ndarray
    lengths: np.ndarray
    axes: np.ndarray
    axis_orders: tuple[str, ...]
    dofs: tuple[tuple[str, ...], ...]
    root_position: np.ndarray
    length_unit: float
    angles_in_degrees: bool
    path: str | None = None

    @property
    def meters_per_unit(self) -> float:
        """Metres per file unit (``0.0254 / length_unit``)."""
        return 0.0254 / self.length_unit


def _floats(tokens: list[str], count: int, what: str, path, line: int) -> np.ndarray:
    if len(tokens) != count:
        raise AsfParseError(path, f"{what} has {len(tokens)} values, expected {count}", line)
    try:
        values = np.array([float(t) for t in tokens])
    except ValueError:
        bad = next(t for t in tokens if not _is_float(t))
        raise AsfParseError(path, f"{what}: {bad!r} is not a number", line) from None
    if not np.all(np.isfinite(values)):
        raise AsfParseError(path, f"{what} is not finite", line)
    return values


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _order(token: str, path, line: int) -> str:
    order = token.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise AsfParseError(path, f"axis order {token!r} is not a permutation of XYZ", line)
    return order


def _sections(lines: list[str], path) -> dict[str, list[tuple[int, list[str]]]]:
    """Split the file into ``{":section": [(line_number, tokens), ...]}``."""
    sections: dict[str, list[tuple[int, list[str]]]] = {}
    current = None
    for number, raw in enumerate(lines, start=1):
        text = raw.split("#", 1)[0].strip()
        if not text:
            continue
        tokens = text.split()
        if tokens[0].startswith(":"):
            key = tokens[0].lower()
            if key not in _SECTIONS:
                raise AsfParseError(path, f"unknown section {tokens[0]!r} (expected one of {', '.join(_SECTIONS)})",
                                    number)
            if key in sections:
                raise AsfParseError(path, f"section {tokens[0]} appears twice", number)
            current = key
            sections[key] = [(number, tokens[1:])] if len(tokens) > 1 else []
            continue
        if current is None:
            raise AsfParseError(path, f"{tokens[0]!r} before the first section (an ASF starts with :version or :name)",
                                number)
        sections[current].append((number, tokens))
    return sections


def _units(entries, path) -> tuple[float, bool]:
    length, degrees = 1.0, True
    for line, tokens in entries:
        key = tokens[0].lower()
        if key == "length":
            length = float(_floats(tokens[1:], 1, "units length", path, line)[0])
            if length <= 0:
                raise AsfParseError(path, "units length must be positive", line)
        elif key == "angle":
            if len(tokens) != 2 or tokens[1].lower() not in ("deg", "rad"):
                raise AsfParseError(path, "units angle must be 'deg' or 'rad'", line)
            degrees = tokens[1].lower() == "deg"
    return length, degrees


def _root(entries, path, end_line: int) -> tuple[tuple[str, ...], str, np.ndarray, np.ndarray]:
    order, axis, position, orientation = None, "XYZ", np.zeros(3), np.zeros(3)
    for line, tokens in entries:
        key = tokens[0].lower()
        if key == "order":
            order = tuple(t.lower() for t in tokens[1:])
            bad = [t for t in order if t not in ("tx", "ty", "tz") + ROTATION_DOFS]
            if bad or len(set(order)) != len(order):
                raise AsfParseError(path, f"root order {' '.join(tokens[1:])!r} must list TX TY TZ RX RY RZ "
                                    "at most once each", line)
        elif key == "axis":
            if len(tokens) != 2:
                raise AsfParseError(path, "root axis needs one order (e.g. XYZ)", line)
            axis = _order(tokens[1], path, line)
        elif key == "position":
            position = _floats(tokens[1:], 3, "root position", path, line)
        elif key == "orientation":
            orientation = _floats(tokens[1:], 3, "root orientation", path, line)
        else:
            raise AsfParseError(path, f"unknown root field {tokens[0]!r}", line)
    if order is None:
        raise AsfParseError(path, ":root has no 'order' line", end_line)
    return order, axis, position, orientation


def _bones(entries, path, degrees: bool) -> dict[str, dict]:
    bones: dict[str, dict] = {}
    bone = None
    in_limits = False
    for line, tokens in entries:
        key = tokens[0].lower()
        if key == "begin":
            if bone is not None:
                raise AsfParseError(path, "'begin' inside a bone (missing 'end')", line)
            bone, in_limits = {"line": line}, False
            continue
        if bone is None:
            raise AsfParseError(path, f"{tokens[0]!r} outside a begin … end bone block", line)
        if key == "end":
            for need in ("name", "direction", "length"):
                if need not in bone:
                    raise AsfParseError(path, f"bone has no '{need}'", bone["line"])
            if bone["name"] in bones:
                raise AsfParseError(path, f"bone {bone['name']!r} is defined twice", bone["line"])
            bones[bone["name"]] = bone
            bone = None
            continue
        if key == "limits" or (in_limits and tokens[0].startswith("(")):
            in_limits = True
            continue  # joint limits are not used
        in_limits = False
        if key == "id":
            continue
        if key == "name":
            if len(tokens) != 2:
                raise AsfParseError(path, "bone name must be one word", line)
            if tokens[1].lower() == "root":
                raise AsfParseError(path, "a bone cannot be called 'root'", line)
            bone["name"] = tokens[1]
        elif key == "direction":
            direction = _floats(tokens[1:], 3, "direction", path, line)
            if not np.any(direction):
                raise AsfParseError(path, "direction is the zero vector", line)
            bone["direction"] = direction  # as written (6 decimals in CMU files), not renormalised
        elif key == "length":
            bone["length"] = float(_floats(tokens[1:], 1, "length", path, line)[0])
            if bone["length"] < 0:
                raise AsfParseError(path, "length is negative", line)
        elif key == "axis":
            if len(tokens) != 5:
                raise AsfParseError(path, f"axis has {len(tokens) - 1} values, expected 3 angles and an order", line)
            angles = _floats(tokens[1:4], 3, "axis", path, line)
            bone["axis"] = np.deg2rad(angles) if degrees else angles
            bone["order"] = _order(tokens[4], path, line)
        elif key == "dof":
            dofs = tuple(t.lower() for t in tokens[1:])
            bad = [t for t in dofs if t not in ROTATION_DOFS]
            if bad:
                raise AsfParseError(path, f"dof {bad[0]!r} is not supported (bones may rotate about rx ry rz only)",
                                    line)
            if len(set(dofs)) != len(dofs):
                raise AsfParseError(path, "dof lists an axis twice", line)
            bone["dofs"] = dofs
        elif key in ("bodymass", "cofmass"):
            continue
        else:
            raise AsfParseError(path, f"unknown bone field {tokens[0]!r}", line)
    if bone is not None:
        raise AsfParseError(path, "bone block has no 'end'", bone["line"])
    return bones


def _hierarchy(entries, path, known: set[str]) -> dict[str, tuple[str, list[str], int]]:
    """``{child: (parent, ..., line)}`` from the ``begin … end`` hierarchy block."""
    parent_of: dict[str, tuple[str, int]] = {}
    for line, tokens in entries:
        key = tokens[0].lower()
        if key in ("begin", "end"):
            continue
        for name in tokens:
            if name != "root" and name not in known:
                raise AsfParseError(path, f"hierarchy names bone {name!r}, which :bonedata does not define", line)
        for child in tokens[1:]:
            if child == "root":
                raise AsfParseError(path, "root cannot be a child", line)
            if child in parent_of:
                raise AsfParseError(path, f"bone {child!r} has two parents", line)
            parent_of[child] = (tokens[0], line)
    return parent_of


def parse_asf(text: str, path: str | os.PathLike | None = None) -> AsfSkeleton:
    """Parse ASF ``text`` into an :class:`AsfSkeleton` (raises :class:`AsfParseError`)."""
    path = None if path is None else str(path)
    lines = text.splitlines()
    sections = _sections(lines, path)
    last = max(len(lines), 1)
    for need in (":root", ":bonedata", ":hierarchy"):
        if need not in sections:
            raise AsfParseError(path, f"no {need} section (is this an Acclaim .asf file?)", last)
    length_unit, degrees = _units(sections.get(":units", []), path)
    root_order, root_axis, root_position, orientation = _root(sections[":root"], path, last)
    bones = _bones(sections[":bonedata"], path, degrees)
    parent_of = _hierarchy(sections[":hierarchy"], path, set(bones))
    children: dict[str, list[str]] = {"root": []}
    for name in bones:
        children[name] = []
    for child, (parent, _) in parent_of.items():
        children[parent].append(child)
    order: list[str] = []
    parents: list[int] = []
    stack = [("root", -1)]
    while stack:  # topology only: depth-first, children in the order the hierarchy lists them
        name, parent = stack.pop()
        if len(order) > len(bones):
            break
        order.append(name)
        parents.append(parent)
        index = len(order) - 1
        stack.extend((child, index) for child in reversed(children[name]))
    missing = [name for name in bones if name not in set(order)]
    if missing or len(order) != len(bones) + 1:
        name = missing[0] if missing else order[-1]
        line = parent_of[name][1] if name in parent_of else bones[name]["line"]
        reason = "is not reachable from root in :hierarchy" if name not in parent_of else "is part of a cycle"
        raise AsfParseError(path, f"bone {name!r} {reason}", line)
    n = len(order)
    directions = np.zeros((n, 3))
    lengths = np.zeros(n)
    axes = np.zeros((n, 3))
    axes[0] = np.deg2rad(orientation) if degrees else orientation
    axis_orders = [root_axis]
    dofs: list[tuple[str, ...]] = [root_order]
    for i, name in enumerate(order[1:], start=1):
        bone = bones[name]
        directions[i] = bone["direction"]
        lengths[i] = bone["length"]
        axes[i] = bone.get("axis", np.zeros(3))
        axis_orders.append(bone.get("order", "XYZ"))
        dofs.append(bone.get("dofs", ()))
    return AsfSkeleton(names=tuple(order), parents=np.array(parents, np.int64), directions=directions,
                       lengths=lengths, axes=axes, axis_orders=tuple(axis_orders), dofs=tuple(dofs),
                       root_position=root_position, length_unit=length_unit, angles_in_degrees=degrees, path=path)


def read_asf(path: str | os.PathLike) -> AsfSkeleton:
    """Read and parse an ASF file (raises :class:`AsfParseError`)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise AsfParseError(path, f"cannot read: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")  # Vicon writes Windows paths in comments
    if "\x00" in text:
        raise AsfParseError(path, "binary data, not an ASF text file", text[: text.index("\x00")].count("\n") + 1)
    return parse_asf(text, path)
