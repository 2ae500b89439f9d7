#!/usr/bin/env bash
# Every fuzz target for SIMNET_FUZZ_SECONDS (default 45) each, SIMNET_FUZZ_JOBS (default: the cores) at a time, on
# stable Rust: cargo-fuzz with `--sanitizer none`, built with debug assertions and overflow checks (cargo-fuzz's
# default without -O). A crash fails the run and leaves
# its input in fuzz/artifacts/TARGET/; make it a regression test, fix it, and add it to fuzz/seeds/TARGET/.
# New inputs the fuzzer finds go to fuzz/corpus/TARGET/ (not committed); fuzz/seeds/TARGET/ is the seed corpus.
set -euo pipefail
cd "$(dirname "$0")"
if ! command -v cargo-fuzz >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked -q
fi
SECONDS_EACH=${SIMNET_FUZZ_SECONDS:-45}
cargo fuzz build --sanitizer none >/dev/null 2>&1 || cargo fuzz build --sanitizer none
# One target per core at a time: each still fuzzes for SECONDS_EACH on a core of its own.
JOBS=${SIMNET_FUZZ_JOBS:-$(nproc)}
fuzz_one() {
  local t=$1
  mkdir -p "corpus/$t"
  if ! cargo fuzz run --sanitizer none "$t" "corpus/$t" "seeds/$t" -- -max_total_time="$SECONDS_EACH" \
    > "corpus/$t.log" 2>&1; then
    tail -40 "corpus/$t.log" >&2
    echo "FAIL: fuzz target $t crashed (input in fuzz/artifacts/$t/)" >&2
    return 1
  fi
  echo "fuzz $t: $(grep -oE 'Done [0-9]+ runs in [0-9]+ second' "corpus/$t.log" | tail -1), no crash"
}
failed=0
running=0
for t in datagram topology imu_csv parts campaign; do
  fuzz_one "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$JOBS" ]; then
    wait -n || failed=1
    running=$((running - 1))
  fi
done
while [ "$running" -gt 0 ]; do
  wait -n || failed=1
  running=$((running - 1))
done
exit "$failed"
