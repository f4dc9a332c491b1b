"""The studio's HTTP error: an answer other than 200 with a one-line message (the app and
every panel raise it; the app turns it into ``{"error": message}`` with its status)."""

from __future__ import annotations


class StudioError(Exception):
    """An answer other than 200: ``status`` and a one-line message."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status
