"""Edit pipelines: a JSON list of operations (``schemas/edit-pipeline.schema.json``).

``load_pipeline(path)`` validates the file with jsonschema and returns the operations;
``run_pipeline(motion, operations, base)`` applies them in order. Every problem is an
:class:`~usdmotion.errors.InputError` naming the file and the offending entry
(``edits.json: operation 3 (speed): ...``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

from usdmotion.errors import InputError
from usdmotion.io import read_motion
from usdmotion.motion import Motion
from usdmotion.ops.edit._common import EditError, frames_of
from usdmotion.resources import resource_path
from usdmotion.schemas import parse_text

SCHEMA_PATH = resource_path("schemas", "edit-pipeline.schema.json")


@lru_cache(maxsize=1)
def pipeline_schema() -> dict:
    """The JSON Schema of pipeline files."""
    try:
        return json.loads(SCHEMA_PATH.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(SCHEMA_PATH, f"cannot read the pipeline schema: {exc.strerror or exc}") from None


def load_pipeline(path: str | os.PathLike) -> list[dict]:
    """Read and validate a pipeline file; returns its list of operations."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise InputError(path, "not a UTF-8 text file") from None
    return validate_pipeline(parse_text(text, path), path)  # bad JSON, NaN, absurd nesting: one line


def validate_pipeline(document, path: str | os.PathLike | None = None) -> list[dict]:
    """``document`` (a parsed pipeline) checked against the schema; ``InputError`` naming
    ``path`` and the offending operation otherwise."""
    import jsonschema

    validator = jsonschema.Draft202012Validator(pipeline_schema())
    error = jsonschema.exceptions.best_match(validator.iter_errors(document))
    if error is not None:
        where = list(error.absolute_path)
        raise InputError(path, f"{_entry(document, where)}{_describe(error)}")
    return document


def _entry(document, where: list) -> str:
    if not where or not isinstance(where[0], int):
        return ""
    op = document[where[0]].get("op", "?") if isinstance(document[where[0]], dict) else "?"
    inner = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in where[1:])
    return f"operation {where[0]} ({op}){': ' + inner.lstrip('.') if inner else ''}: "


def _describe(error) -> str:
    message = error.message
    if error.validator == "oneOf" and error.validator_value and all("required" in s for s in error.validator_value):
        options = " or ".join(repr(s["required"][0]) for s in error.validator_value)
        message = f"needs exactly one of {options}"
    elif error.validator == "additionalProperties":
        message = message.replace("Additional properties are not allowed", "unknown option(s)")
    return message.splitlines()[0][:300]


def run_pipeline(motion: Motion, operations: list[dict], base: Path, path: Path | None = None,
                 read: Callable[[Path], Motion] | None = None,
                 on_step: Callable[[int, dict, Motion], None] | None = None) -> Motion:
    """Apply validated ``operations`` in order. ``base``: folder for relative ``with`` paths."""
    for i, op in enumerate(operations):
        try:
            motion = _apply(motion, dict(op), base, read)
        except EditError as exc:
            raise InputError(path, f"operation {i} ({op.get('op')}): {exc}") from None
        if on_step is not None:
            on_step(i, op, motion)
    return motion


def _time(value, motion: Motion, what: str):
    frames = frames_of(value, motion.fps, what)
    return None if frames is None else frames


def _frame(value, motion: Motion, what: str):
    if value is None or isinstance(value, int):
        return value
    text = str(value).strip().lower()
    negative = text.startswith("-")
    frames = frames_of(text.lstrip("-"), motion.fps, what)
    return -int(round(frames)) if negative else int(round(frames))


def _pairs(keys, motion: Motion, what: str):
    return None if keys is None else [(_time(f, motion, what), v) for f, v in keys]


def _apply(motion: Motion, op: dict, base: Path, read) -> Motion:
    from usdmotion.ops import edit as E

    kind = op.pop("op")
    if kind == "equalize":
        return E.equalize(motion, **op)
    if kind == "reorient":
        return E.reorient(motion, rotate=op.get("rotate"), heading_deg=op.get("heading"),
                          position=op.get("position"), translate=op.get("translate"))
    if kind == "displace":
        keys = [{**k, "frame": _time(k["frame"], motion, "key frame")} for k in op["keys"]]
        return E.displace(motion, keys, falloff=_time(op.get("falloff"), motion, "falloff"),
                          frame=op.get("frame", "local"))
    if kind == "layer":
        return E.layer(motion, op["joint"], op["channel"], _pairs(op["keys"], motion, "key frame"),
                       falloff=_time(op.get("falloff"), motion, "falloff"), frame=op.get("frame", "local"))
    if kind == "blend":
        other_path = Path(op.pop("with"))
        other_path = other_path if other_path.is_absolute() else base / other_path
        other = read(other_path) if read is not None else _read(other_path)
        for name in ("transition", "at"):
            if name in op:
                op[name] = _time(op[name], motion, name)
        if "offset" in op:
            op["offset"] = _frame(op["offset"], motion, "offset")
        op["keys"] = _pairs(op.get("keys"), motion, "key frame")
        return E.blend(motion, other, **op)
    if kind == "speed":
        return E.speed(motion, factor=op.get("factor"), keys=_pairs(op.get("keys"), motion, "key frame"),
                       joint=op.get("joint"), subtree=op.get("subtree", False), interp=op.get("interp", "cubic"))
    if kind == "resample":
        return E.resample(motion, op["fps"], interp=op.get("interp", "cubic"))
    if kind == "cycle":
        stop = op.get("stop")
        return E.cycle(motion, start=_frame(op.get("start"), motion, "start"),
                       stop=stop if stop == "auto" else _frame(stop, motion, "stop"),
                       transition=_time(op.get("transition"), motion, "transition"), loops=op.get("loops", 2),
                       offset=op.get("offset", "rigid"), method=op.get("method", "slerp"))
    if kind == "trim":
        return E.trim(motion, _frame(op.get("start"), motion, "start"), _frame(op.get("stop"), motion, "stop"))
    raise EditError(f"unknown operation {kind!r}")  # unreachable after validation


def _read(path: Path) -> Motion:
    if not path.is_file():
        raise EditError(f"blend: no such file {path}")
    return read_motion(path)
