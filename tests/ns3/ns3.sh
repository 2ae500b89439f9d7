#!/usr/bin/env bash
# ns-3's own numbers for the radio cross-checks: ns-3 3.44 with lr-wpan from its wheel, in a venv of its own
# (target/ns3/venv), writes target/ns3/phy.json; `cargo test --test integration -- --ignored ns3::` compares.
set -euo pipefail
cd "$(dirname "$0")/../.."
venv=target/ns3/venv
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c "import ns" >/dev/null 2>&1; then
  "$venv/bin/pip" install -q ns3==3.44.post0
fi
# cppyy prints harmless static-initialiser notices from ns-3's headers; the script's own line says what it wrote.
"$venv/bin/python" tests/ns3/phy_reference.py target/ns3/phy.json 2> >(grep -v "Failed to materialize symbols" >&2)
