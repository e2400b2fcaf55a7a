"""``python -m besman`` runs the command line."""

import sys

from besman import main

sys.exit(main())
