"""One progress-callback type for long operations.

An operation that takes a ``progress`` argument calls ``progress(current, total, message)``
as its work advances: ``current`` units done of ``total`` (``None`` where the total is not
known), ``message`` a few words on what it is doing ("retargeting", "rendering walk.mp4").
The CLI's progress bar (:func:`usdmotion.cli._progress.progress`), the Studio's jobs and
the batch runner all implement this one type, so an operation reports progress once for
every front end. :func:`no_progress` is the default that reports nothing.
"""

from __future__ import annotations

from typing import Protocol


class Progress(Protocol):
    """``progress(current, total, message)``: ``current`` of ``total`` units done (``None``: unknown)."""

    def __call__(self, current: float, total: float | None, message: str) -> None: ...


def no_progress(current: float, total: float | None, message: str) -> None:
    """The progress callback that reports nothing."""
