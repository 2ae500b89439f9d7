#!/usr/bin/env bash
# report.html in a real browser: a run's page and a sweep's page, rendered by headless Chromium (Debian's
# `chromium`). The DOM Chromium builds holds the title, the tables and the inline plots; the screenshot is not a
# blank page (tests/browser/check_png.py).
#
# Without Chromium this skips with a message; with SIMNET_REQUIRE_BROWSER=1 (CI) a missing Chromium is a failure.
set -euo pipefail
cd "$(dirname "$0")/../.."

CHROMIUM=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$CHROMIUM" ]; then
  if [ "${SIMNET_REQUIRE_BROWSER:-0}" = 1 ]; then
    echo "FAIL: Chromium is required here (SIMNET_REQUIRE_BROWSER=1) but is not installed" >&2
    exit 1
  fi
  echo "SKIP: Chromium is not installed: report.html was not rendered"
  exit 0
fi
# The build the test suite made (`cargo test`): a dev build is quick enough for these short runs.
BIN=${SIMNET_BIN:-target/debug/simnet}
if [ -z "${SIMNET_BIN:-}" ]; then
  cargo build --locked -q
fi
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
"$BIN" -q -t ring3 --duration 5 --loss 0.2 --estimators all --rounds 2 --out "$WORK/run" >/dev/null
"$BIN" sweep -q -t ring3 --set link.loss.p=0:0.4:0.2 --seeds 3 --duration 3 --out "$WORK/sweep" >/dev/null

browse() {
  # A fresh profile each time; no sandbox (CI runs as root), no GPU.
  "$CHROMIUM" --headless --no-sandbox --disable-gpu --hide-scrollbars --user-data-dir="$WORK/profile" \
    --window-size=1280,2000 "$@" 2>/dev/null
}
failed=0
check() {
  local page=$1 title=$2; shift 2
  browse --dump-dom "file://$page" > "$WORK/dom.html"
  for want in "<title>$title" "$@"; do
    if ! grep -qF -- "$want" "$WORK/dom.html"; then
      echo "FAIL: $page: the rendered DOM has no \`$want\`" >&2
      failed=1
    fi
  done
  browse --screenshot="$WORK/shot.png" "file://$page" >/dev/null
  python3 tests/browser/check_png.py "$WORK/shot.png" 0.03 50 || failed=1
}
check "$WORK/run/report.html" "simnet · ring3 · seed 1" '<table id="nodes">' '<table id="estimators">' \
  '<table id="links">' '<svg' 'Provenance'
check "$WORK/sweep/report.html" "simnet sweep · ring3 against link.loss.p" '<table id="points">' \
  '<table id="made-by">' '<svg' '0.2'
if [ $failed = 1 ]; then
  exit 1
fi
echo "2 passed, 0 failed: a run's and a sweep's report.html laid out in Chromium"
