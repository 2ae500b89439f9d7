#!/usr/bin/env bash
# ns-3's own numbers for the radio cross-checks: ns-3 3.44 with lr-wpan from its wheel, in a venv of its own
# (target/ns3/venv). Writes target/ns3/phy.json (the PHY's arithmetic, from Python) and target/ns3/star.json and
# star-ack.json (a star of senders around a coordinator, unacknowledged and with ACKs, a C++ program built against
# the wheel's headers and libraries) and prr.json (one sender's delivery ratio against distance, the same program);
# `cargo test --test integration -- --ignored ns3::` compares.
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

# The star: N senders r m around a coordinator, unslotted CSMA/CA, a 50-octet payload every 50 ms for
# 10 s; N = 1 … 20 at 5 m (all in range of each other), and two senders on either side of it at 20 m (40 m apart:
# they sense each other) and at 35 m (70 m apart: hidden from each other).
ns3="$("$venv/bin/python" -c 'import ns3; print(list(ns3.__path__)[0])')"
g++ -std=c++20 -O1 -I"$ns3/include" tests/ns3/star.cc -o target/ns3/star -L"$ns3/lib64" \
  -lns3.44-lr-wpan -lns3.44-spectrum -lns3.44-propagation -lns3.44-mobility -lns3.44-network -lns3.44-core \
  -Wl,-rpath,"$ns3/lib64"
# Each star twice: unacknowledged (star.json), and with ACKs and 3 retries (star-ack.json).
for ack in 0 1; do
  out=target/ns3/star.json
  [ "$ack" = 1 ] && out=target/ns3/star-ack.json
  {
    echo "["
    first=1
    for case in "1 5" "2 5" "3 5" "5 5" "8 5" "10 5" "15 5" "20 5" "2 20" "2 35"; do
      read -r n r <<< "$case"
      read -r n sent received < <(target/ns3/star --n="$n" --radius="$r" --ack="$ack" | tail -1)
      [ "$first" = 1 ] || echo ","
      first=0
      printf '  [%s, %s, %s, %s]' "$n" "$r" "$sent" "$received"
    done
    echo
    echo "]"
  } > "$out"
  echo "wrote $out: $(tr -d '\n ' < "$out")"
done
# The delivery ratio against distance: one sender at r m, unacknowledged, 1000 packets of 20 and of 100 octets at
# each distance, across the edge of the range (30–50 m).
{
  echo "["
  first=1
  for payload in 20 100; do
    for r in 30 36 38 39 40 41 42 45 47 50; do
      read -r n sent received < <(target/ns3/star --n=1 --radius="$r" --payload="$payload" --seconds=50 | tail -1)
      [ "$first" = 1 ] || echo ","
      first=0
      printf '  [%s, %s, %s, %s]' "$payload" "$r" "$sent" "$received"
    done
  done
  echo
  echo "]"
} > target/ns3/prr.json
echo "wrote target/ns3/prr.json: $(tr -d '\n ' < target/ns3/prr.json)"
# Its speed on the largest star (printed beside simnet's by the test; never asserted: the machine is shared).
start=$(date +%s%N)
target/ns3/star --n=20 --radius=5 >/dev/null
echo "{\"n\": 20, \"simulated_s\": 11, \"wall_s\": $(( ($(date +%s%N) - start) / 1000 ))e-6}" > target/ns3/star-speed.json
echo "wrote target/ns3/star-speed.json: $(cat target/ns3/star-speed.json)"
