"""The exceptions and warnings of mechanism descriptions."""

from __future__ import annotations


class DescriptionError(ValueError):
    """A malformed mechanism description. The message names the key path, e.g.
    ``legs[2] (L3).actuated: ...``."""


class DescriptionWarning(UserWarning):
    """A described mechanism that can be built but whose analysis reveals a problem:
    under-actuation, or task coordinates inconsistent with what the legs allow."""
