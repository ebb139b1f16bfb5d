"""``python -m ldaspark``: the command line (``ldaspark.cli``)."""
import sys

try:
    from .cli import main
except KeyboardInterrupt:          # Ctrl-C while the command line module loads: one line, 130
    print("ldaspark: interrupted", file=sys.stderr)
    sys.exit(130)

try:
    code = main()
except KeyboardInterrupt:          # Ctrl-C before main installed its handlers (its own imports)
    print("ldaspark: interrupted", file=sys.stderr)
    code = 130
sys.exit(code)
