"""Run the benchmark: python benchmarks/run.py [--smoke] [--out docs/results/performance] (same
as `nlos-cl bench`)."""
import sys

from nlos_cl.apps.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
