"""``python -m ldaspark``: the command line (``ldaspark.cli``)."""
import sys

from .cli import main

sys.exit(main())
