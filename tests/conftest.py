"""Shared pytest configuration: make ``tests/_support.py`` importable from every test
directory (including ``tests/reproduction``)."""

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
