"""``python -m gcs_tui.cli``: the ``gcs`` command."""

import sys

from gcs_tui.cli.commands import main

sys.exit(main())
