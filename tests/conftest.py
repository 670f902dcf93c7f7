"""Shared pytest configuration: make ``tests/_support.py`` importable from every test
directory (including ``tests/reproduction``)."""

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

from hypothesis import settings  # noqa: E402

# In CI the property-based tests draw a fixed sequence of examples (derandomize): a run's
# outcome depends only on the code. Locally they explore new examples each run.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
