"""``python -m besman`` runs the command line."""

import sys

from besman.cli import main

sys.exit(main())
