#!/usr/bin/env bash
# --format parquet (cargo feature `parquet`): a sweep's runs and points and a run's tables written as Parquet, read
# back with pyarrow in a fresh virtual environment, equal the CSVs beside them (tests/parquet/check.py).
set -euo pipefail
cd "$(dirname "$0")/../.."

# SIMNET_BIN: a binary built with the parquet feature already (CI's, built once with every feature).
BIN=${SIMNET_BIN:-target/debug/simnet}
if [ -z "${SIMNET_BIN:-}" ]; then
  cargo build --locked --features parquet -q
fi
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
VENV=target/ci-venv
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
fi
"$VENV/bin/pip" install -q --disable-pip-version-check pyarrow pandas

"$BIN" sweep -q -t ring3 --set link.loss.p=0,0.2 --set consensus.self=0.6,0.7 --seeds 3 --duration 2 \
  --estimators all --rounds 2 --format parquet --out "$WORK/sweep" >/dev/null
"$BIN" -q -t rgg50 --duration 2 --loss 0.1 --estimators icf,centralized --format parquet --out "$WORK/run" >/dev/null
"$VENV/bin/python" tests/parquet/check.py "$WORK/sweep" "$WORK/run"
echo "Parquet: every file equal to its CSV"
