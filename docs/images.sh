#!/usr/bin/env bash
# The book's run plots, made again by the commands the book shows and rendered to PNG by headless Chromium:
# `bash docs/images.sh` after a change to a plot (SIMNET_BIN: a built simnet; default: a release build).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${SIMNET_BIN:-target/release/simnet}
if [ -z "${SIMNET_BIN:-}" ]; then
  cargo build --release --locked -q
fi
CHROMIUM=$(command -v chromium || command -v chromium-browser) || {
  echo "docs/images.sh needs Chromium (apt-get install chromium)" >&2
  exit 2
}
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
"$BIN" -q -t ring3 --loss 0.2 --out "$W/ring3" >/dev/null
"$BIN" -q -t rgg50 --loss 0.1 --estimators all --rounds 3 --out "$W/rgg50" >/dev/null
"$BIN" -q -t attitude3 --out "$W/attitude3" >/dev/null
render() {
  "$CHROMIUM" --headless --no-sandbox --disable-gpu --hide-scrollbars --screenshot="$PWD/docs/src/images/$2" \
    --window-size="$3" "file://$W/$1" >/dev/null 2>&1
  echo "docs/src/images/$2 from $1"
}
render ring3/error.svg ring3-error.png 1000,640
render ring3/trace_p.svg ring3-trace-p.png 1000,640
render rgg50/estimators.svg rgg50-estimators.png 1250,640
render attitude3/error.svg attitude3-error.png 1000,640
