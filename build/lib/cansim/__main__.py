"""``python -m cansim``: the ``cansim`` command line (:mod:`cansim.tools.cli`)."""

from __future__ import annotations

import sys

from cansim.tools.cli import main

if __name__ == "__main__":
    sys.exit(main())
