"""What a run costs from Python against the same run of the `simnet` binary, measured in the same process.

    python python/benches/run_cost.py [path/to/simnet]    # default: target/release/simnet

For each case, the median wall time of: `simnet --json` (a process, its output parsed); `simnet --json --out DIR`
(the tables written too); `simnet.run(tables=False)` ("bare": no per-step rows, like `--json`); `simnet.run` (the
tables made, the summary read); `simnet.run` with its tables read into DataFrames; and the ratio of each Python call
to the like CLI run. Medians of 5, after one
warm-up of each.
"""

import json
import statistics
import subprocess
import sys
import tempfile
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
    out = tempfile.mkdtemp(prefix="simnet-bench-")
    print(f"{'case':<34} {'CLI s':>7} {'bare s':>7} {'bare/CLI':>9} {'CLI+out s':>10} {'Python s':>9} {'+frames s':>10}"
          f" {'Python/CLI+out':>15} {'+frames/CLI+out':>16}")
    for topo, opts, args in CASES:
        def cli_run(*more):
            return json.loads(subprocess.run([str(BIN), "-q", "-t", topo, *args, "--json", *more],
                                             capture_output=True, check=True).stdout)

        cli = median_time(cli_run)
        cli_out = median_time(lambda: cli_run("--out", out))
        py = median_time(lambda: simnet.run(topo, **opts).summary)
        bare = median_time(lambda: simnet.run(topo, tables=False, **opts).summary)

        def with_tables():
            r = simnet.run(topo, **opts)
            return r.trace, r.links, r.measurements, r.estimators

        tables = median_time(with_tables)
        name = f"{topo} {' '.join(args)}"
        print(f"{name:<34} {cli:>7.3f} {bare:>7.3f} {bare / cli:>9.2f} {cli_out:>10.3f} {py:>9.3f} {tables:>10.3f}"
              f" {py / cli_out:>15.2f} {tables / cli_out:>16.2f}")


if __name__ == "__main__":
    main()
