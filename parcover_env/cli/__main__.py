"""``python -m parcover_env.cli``: the ``parcover`` command without the console script."""

import sys

from parcover_env.cli.main import main

if __name__ == "__main__":
    sys.exit(main())
