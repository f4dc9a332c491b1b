"""Reading and validating the JSON/YAML documents users write (limits, synthesis, segments).

The JSON Schemas live in the top-level ``schemas/<name>.schema.json`` (shipped inside the
wheel too; see :mod:`usdmotion.resources`). Every problem becomes
one :class:`~usdmotion.errors.InputError` line naming the file and the JSON path of the
offending value, e.g. ``limits.json: /joints/LeftLeg/x: [10, 5] ...``.
"""

from __future__ import annotations

import json
import math
import os
from functools import lru_cache
from pathlib import Path
from typing import Any

from usdmotion.errors import InputError
from usdmotion.resources import resource_path

SCHEMA_NAMES = ("limits", "synthesis", "body-segments", "segments", "edit-pipeline", "jointmap", "rigprofile",
                "contacts")


@lru_cache(maxsize=None)
def schema(name: str) -> dict:
    """The JSON Schema called ``name`` (one of :data:`SCHEMA_NAMES`)."""
    if name not in SCHEMA_NAMES:
        raise ValueError(f"unknown schema {name!r}")
    return json.loads(resource_path("schemas", f"{name}.schema.json").read_text("utf-8"))


def _json_path(parts) -> str:
    return "/" + "/".join(str(p) for p in parts) if parts else "/"


def _reject_constant(token: str):
    raise ValueError(f"{token} is not a number JSON allows")


#: Deepest nesting of arrays/objects accepted in a user document (ours need 4).
MAX_NESTING = 64


def parse_text(text: str, path: str | os.PathLike | None, kind: str = "json") -> Any:
    """Parse JSON or YAML text; syntax errors become one-line ``InputError``s with the line.

    Documents nested deeper than :data:`MAX_NESTING` are refused (before Python's
    recursion limit could turn them into an internal error).
    """
    try:
        document = _parse(text, path, kind)
    except RecursionError:
        document = None
        depth = MAX_NESTING + 1
    else:
        depth = nesting_depth(document)
    if depth > MAX_NESTING:
        raise InputError(path, f"nested more than {MAX_NESTING} levels deep; not a usdmotion document")
    return document


def json_or_none(text: str | bytes) -> Any:
    """``text`` parsed as JSON, ``None`` where it is not a document :func:`parse_text` takes
    (bad syntax or encoding, NaN/Infinity, nesting deeper than :data:`MAX_NESTING`): for the
    readers that skip a file they cannot use rather than refuse it."""
    try:
        return parse_text(text, None)
    except (InputError, UnicodeDecodeError):
        return None


def nesting_depth(document: Any) -> int:
    """Deepest nesting of lists/dicts in ``document`` (a scalar is 0), without recursion."""
    deepest, stack = 0, [(document, 0)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, dict):
            value = list(value.values())
        if isinstance(value, list):
            deepest = max(deepest, depth + 1)
            if depth + 1 > MAX_NESTING:
                break
            stack.extend((item, depth + 1) for item in value)
    return deepest


def _parse(text: str, path: str | os.PathLike | None, kind: str) -> Any:
    if kind == "yaml":
        import yaml

        try:
            return yaml.safe_load(text)
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            line = mark.line + 1 if mark is not None else None
            problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
            raise InputError(path, f"not valid YAML: {problem}", line) from None
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not valid JSON: {exc.msg}", exc.lineno, exc.colno) from None
    except ValueError as exc:
        raise InputError(path, f"not valid JSON: {exc}") from None


def _non_finite(value: Any, parts: tuple = ()) -> tuple | None:
    """JSON path of the first NaN/inf number in ``value`` (YAML's ``.nan``), else None."""
    if isinstance(value, float) and not math.isfinite(value):
        return parts
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return None
    for key, item in items:
        found = _non_finite(item, parts + (key,))
        if found is not None:
            return found
    return None


def validate(document: Any, name: str, path: str | os.PathLike | None) -> Any:
    """Validate ``document`` against schema ``name``; return it or raise ``InputError``."""
    import jsonschema

    bad = _non_finite(document)
    if bad is not None:
        raise InputError(path, f"{_json_path(bad)}: {document_value(document, bad)!r} is not a finite number")
    validator = jsonschema.Draft202012Validator(schema(name))
    errors = sorted(validator.iter_errors(document), key=lambda e: (len(e.absolute_path), list(map(str, e.path))))
    if errors:
        error = jsonschema.exceptions.best_match(errors)
        message = error.message.splitlines()[0]
        if len(message) > 160:
            message = message[:157] + "..."
        raise InputError(path, f"{_json_path(list(error.absolute_path))}: {message}")
    return document


def document_value(document: Any, parts) -> Any:
    """The value at a JSON path (tuple of keys) of ``document``."""
    for key in parts:
        document = document[key]
    return document


def load_document(path: str | os.PathLike, name: str) -> Any:
    """Read a ``.json``, ``.yaml`` or ``.yml`` file and validate it against schema ``name``."""
    path = Path(path)
    kind = "yaml" if path.suffix.lower() in (".yaml", ".yml") else "json"
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    return validate(parse_text(text, path, kind), name, path)
