"""``python -m parcover_env.cli``: the parcover command line."""

import sys

from parcover_env.cli.main import main

sys.exit(main())
