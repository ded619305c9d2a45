"""``python -m urdfpost``: the command line, as the ``urdfpost`` script runs it."""

from __future__ import annotations

import sys

from urdfpost.cli import main

if __name__ == "__main__":
    sys.exit(main())
