"""Locating the project's data folders: top-level ``schemas/`` (JSON Schemas) and ``render/``
(render presets).

In a source checkout (and an editable install) they are read where they live; a wheel
carries copies under ``usdmotion/_shipped/`` (symlinks in the source tree).
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def resource_path(folder: str, name: str) -> Path:
    """Path of ``name`` in the data folder ``folder`` (``"schemas"`` or ``"render"``)."""
    for base in (_PACKAGE.parent / folder, _PACKAGE / "_shipped" / folder):
        candidate = base / name
        if candidate.is_file():
            return candidate
    return _PACKAGE.parent / folder / name
