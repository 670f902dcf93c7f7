"""The error of an invalid study, below every other module of the study layer."""

from __future__ import annotations

__all__ = ["StudyError"]


class StudyError(ValueError):
    """An invalid study: the message names the key path and what is allowed."""
