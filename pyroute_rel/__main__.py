"""``python -m pyroute_rel``: the same as the ``pyroute-rel`` command."""

import sys

from pyroute_rel.cli.main import main

if __name__ == "__main__":
    sys.exit(main())
