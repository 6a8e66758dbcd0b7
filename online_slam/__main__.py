"""``python -m online_slam`` runs the command line."""

import sys

from online_slam.cli.main import main

sys.exit(main())
