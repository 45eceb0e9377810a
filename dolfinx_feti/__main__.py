"""``python -m dolfinx_feti PROBLEM.toml``: the command ``dolfinx-feti`` (see :mod:`.cli`)."""

import sys

from .cli import main

sys.exit(main())
