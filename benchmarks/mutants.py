"""Mutation catalogue: plant each catalogued fault in a scratch copy of the package, run the suite,
write reports/mutation.md and reports/mutation.json (same as ``ldaspark mutants``).
Usage: python benchmarks/mutants.py [--quick] [--outdir reports] [--jobs 2] [--only ID,ID]"""
import sys

from ldaspark.lab.mutants.command import main

if __name__ == "__main__":
    sys.exit(main())
