"""``python -m pendsweep.bench [NAME ...] [--quick] [-o results/bench.json]``."""

import argparse
import json
from pathlib import Path

from .registry import BENCHMARKS, run_benchmarks

parser = argparse.ArgumentParser(prog="python -m pendsweep.bench", description=__doc__)
parser.add_argument("names", nargs="*", help=f"benchmarks to run (default all): {', '.join(BENCHMARKS)}")
parser.add_argument("--quick", action="store_true", help="small sizes, for smoke tests")
parser.add_argument("-o", "--output", type=Path, default=Path("results/bench.json"))
args = parser.parse_args()
report = run_benchmarks(args.names, args.output, args.quick)
for name in args.names or BENCHMARKS:
    print(f"== {name}")
    print(json.dumps(report[name], indent=2, sort_keys=True))
print(f"written to {args.output}")
