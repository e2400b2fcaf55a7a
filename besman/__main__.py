"""``python -m besman`` runs the command line."""

import sys

from besman import main

if __name__ == "__main__":
    sys.exit(main())
