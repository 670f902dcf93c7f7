"""``python -m parasynth``: the command line, as the ``parasynth`` command."""
import sys

from .cli import main

sys.exit(main())
