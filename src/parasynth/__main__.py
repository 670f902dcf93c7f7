"""``python -m parasynth``: the command line, as the ``parasynth`` command."""
from .cli import entry

entry()
