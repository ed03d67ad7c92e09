"""``python -m hapticframe``."""

import sys

from hapticframe.cli import main

sys.exit(main())
