"""What a run costs from Python against the same run of the `simnet` binary, measured in the same process.

    python python/benches/run_cost.py [path/to/simnet]    # default: target/release/simnet

For each case: the median wall time of `simnet --json` (a process, its output parsed) and of `simnet.run` (the tables
read into DataFrames, and not), and their ratios. Medians of 5, after one warm-up of each.
"""

import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import simnet

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "target" / "release" / "simnet"
CASES = [
    ("ring3", {"loss": 0.2}, ["--loss", "0.2"]),
    ("ring3", {"loss": 0.2, "estimators": "all"}, ["--loss", "0.2", "--estimators", "all"]),
    ("rgg50", {"loss": 0.1, "duration": 10}, ["--loss", "0.1", "--duration", "10"]),
]


def median_time(f, n=5):
    f()
    times = []
    for _ in range(n):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main():
    if not BIN.is_file():
        sys.exit(f"{BIN}: no simnet binary (cargo build --release, or give its path)")
    print(f"{'case':<34} {'CLI s':>8} {'Python s':>9} {'+tables s':>10} {'Python/CLI':>11} {'+tables/CLI':>12}")
    for topo, opts, args in CASES:
        cli = median_time(lambda: json.loads(subprocess.run([str(BIN), "-q", "-t", topo, *args, "--json"],
                                                            capture_output=True, check=True).stdout))
        py = median_time(lambda: simnet.run(topo, **opts).summary)

        def with_tables():
            r = simnet.run(topo, **opts)
            return r.trace, r.links, r.measurements, r.estimators

        tables = median_time(with_tables)
        name = f"{topo} {' '.join(args)}"
        print(f"{name:<34} {cli:>8.3f} {py:>9.3f} {tables:>10.3f} {py / cli:>11.2f} {tables / cli:>12.2f}")


if __name__ == "__main__":
    main()
