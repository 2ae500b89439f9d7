#!/usr/bin/env bash
# report.html in a real browser, headless Chromium (Debian's `chromium`): the page of a short run of every built-in
# topology (every estimator), of ring3 with a crash, a link down and a partition, and of a sweep. For each page the
# DOM Chromium builds holds the title, the tables and the inline plots; laid out in a 1280-pixel-wide frame
# (tests/browser/measure.html) no label of a plot renders smaller than 8 px and no two labels are drawn over each
# other; a screenshot of a run's, a faulted run's and a sweep's page is not a blank page (tests/browser/check_png.py).
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
HERE=$PWD

browse() {
  # A fresh profile each time; no sandbox (CI runs as root), no GPU.
  "$CHROMIUM" --headless --no-sandbox --disable-gpu --hide-scrollbars --user-data-dir="$WORK/profile" \
    --window-size=1280,2000 "$@" 2>/dev/null
}
failed=0
pages=0
check() {
  local page=$1 title=$2; shift 2
  pages=$((pages + 1))
  # The page as laid out: its DOM, and its plots' text sizes and overlapping labels, measured by the browser.
  browse --allow-file-access-from-files --virtual-time-budget=10000 --dump-dom \
    "file://$HERE/tests/browser/measure.html?page=file://$page" > "$WORK/measure.html"
  python3 - "$WORK/measure.html" "$page" "<title>$title" "$@" <<'PY' || failed=1
import html, json, re, sys
dom, page, wants = open(sys.argv[1]).read(), sys.argv[2], sys.argv[3:]
m = re.search(r'<pre id="result">(.*?)</pre>', dom, re.S)
r = json.loads(html.unescape(m.group(1))) if m and m.group(1).startswith("{") else None
if r is None or "error" in r:
    sys.exit(f"FAIL: {page}: the plots could not be measured ({r and r.get('error')})")
problems = [f"the rendered DOM has no `{w}`" for w in wants if w not in r["dom"]]
if r["svgs"] == 0 or r["texts"] == 0:
    problems.append("no plot with text")
if r["min_text_px"] is not None and r["min_text_px"] < 8:
    problems.append(f"the label {r['smallest']!r} renders {r['min_text_px']:.1f} px high (< 8 px)")
for a, b in r["overlaps"]:
    problems.append(f"labels {a!r} and {b!r} are drawn over each other")
for p in problems:
    print(f"FAIL: {page}: {p}", file=sys.stderr)
sys.exit(1 if problems else 0)
PY
  # A screenshot of the first page of each kind (a run, faults, a sweep): not a blank page.
  if [ "${SHOOT:-1}" = 1 ]; then
    browse --screenshot="$WORK/shot.png" "file://$page" >/dev/null
    python3 tests/browser/check_png.py "$WORK/shot.png" 0.03 50 || failed=1
  fi
}

# Every built-in, with every estimator it can run: its page and its plots.
for t in $("$BIN" topologies | awk '{print $1}'); do
  "$BIN" -q -t "$t" --duration 4 --estimators all --out "$WORK/$t" >/dev/null
  SHOOT=$([ "$t" = ring3 ] && echo 1 || echo 0) check "$WORK/$t/report.html" "simnet · $t · seed 1" \
    '<table id="nodes">' '<table id="estimators">' '<svg' 'Provenance'
done
# Faults shaded on the plots and named in their legends.
sed -n '/^\[\[fault\]\]/,$p' docs/src/topologies.md | sed '/^\[\[attack\]\]/,$d;/^```/,$d' > "$WORK/faults.toml"
cat topologies/ring3.toml "$WORK/faults.toml" > "$WORK/ring3-faults.toml"
"$BIN" -q -t "$WORK/ring3-faults.toml" --loss 0.2 --out "$WORK/faults" >/dev/null
check "$WORK/faults/report.html" "simnet · ring3 · seed 1" '<table id="links">' 'node 2 crashed, 10–15 s' \
  'link 0–1 down, 5–6 s' 'partition of node 1, 20–22 s'
"$BIN" sweep -q -t ring3 --set link.loss.p=0:0.4:0.2 --seeds 3 --duration 3 --estimators all \
  --out "$WORK/sweep" >/dev/null
check "$WORK/sweep/report.html" "simnet sweep · ring3 against link.loss.p" '<table id="points">' \
  '<table id="made-by">' '<svg' '0.2'
if [ $failed = 1 ]; then
  exit 1
fi
echo "$pages passed, 0 failed: the report.html of every built-in, of a run with faults and of a sweep laid out in Chromium"
