"""``python -m whexar.cli``: the ``whexar`` command without its console script."""

import sys

from whexar.cli import main

sys.exit(main())
