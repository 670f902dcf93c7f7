"""``python -m parasynth.cli``: the command line."""
from . import entry

entry()
