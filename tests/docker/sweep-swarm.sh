#!/usr/bin/env bash
# A campaign sharded over Docker Swarm: the stack `simnet sweep --emit stack` prints, deployed with 3 replicas on a
# one-node swarm (initialised here if the engine is not in one, and left afterwards), runs each shard as one task;
# the tasks complete, the last one writes the tables into the results volume, and `sweep merge` of that volume
# gives the runs.csv and points.csv of the same sweep run locally, byte for byte.
#
# Without Docker this skips with a message; with SIMNET_REQUIRE_DOCKER=1 (CI) a missing Docker is a failure. The
# engine is left as it was: the stack, its volume, the image and a swarm made here are removed.
set -euo pipefail
cd "$(dirname "$0")/../.."

if ! docker info >/dev/null 2>&1; then
  if [ "${SIMNET_REQUIRE_DOCKER:-0}" = 1 ]; then
    echo "FAIL: Docker is required here (SIMNET_REQUIRE_DOCKER=1) but \`docker info\` fails" >&2
    exit 1
  fi
  echo "SKIP: Docker is not available: the Swarm campaign test did not run"
  exit 0
fi

BIN=target/x86_64-unknown-linux-gnu/release/simnet
echo "== static binary and image"
RUSTFLAGS='-C target-feature=+crt-static' cargo build --release --locked --target x86_64-unknown-linux-gnu -q
IMAGE="simnetsweep:$$"
STACK="simnetsweep$$"
WORK=$(mktemp -d)
MADE_SWARM=0
# `swarm init` makes the docker_gwbridge network and `swarm leave` keeps it: it goes too if it was not there before.
HAD_GWBRIDGE=0
docker network inspect docker_gwbridge >/dev/null 2>&1 && HAD_GWBRIDGE=1
cleanup() {
  docker stack rm "$STACK" >/dev/null 2>&1 || true
  # The volume can go once the stack's containers have.
  for _ in $(seq 1 120); do
    docker volume rm "${STACK}_results" >/dev/null 2>&1 && break
    docker volume inspect "${STACK}_results" >/dev/null 2>&1 || break
    sleep 0.5
  done
  docker image rm -f "$IMAGE" >/dev/null 2>&1 || true
  if [ "$MADE_SWARM" = 1 ]; then
    docker swarm leave --force >/dev/null 2>&1 || true
    if [ "$HAD_GWBRIDGE" = 0 ]; then
      docker network rm docker_gwbridge >/dev/null 2>&1 || true
    fi
  fi
  rm -rf "$WORK"
}
trap cleanup EXIT
docker build -q -t "$IMAGE" . >"$WORK/build.log" 2>&1 || { cat "$WORK/build.log" >&2; echo "FAIL: docker build" >&2; exit 1; }

if [ "$(docker info -f '{{.Swarm.LocalNodeState}}')" != active ]; then
  echo "== docker swarm init (left again at the end)"
  docker swarm init --advertise-addr 127.0.0.1 >/dev/null
  MADE_SWARM=1
fi

ARGS=(-t ring3 --set link.loss.p=0,0.2 --set consensus.self=0.6,0.7 --seeds 3 --duration 2
  --estimators sequeira,independent,kcf)
echo "== the sweep locally"
"$BIN" sweep -q "${ARGS[@]}" --out "$WORK/local" >/dev/null

echo "== the same sweep as a stack of 3 shards"
"$BIN" sweep "${ARGS[@]}" --emit stack --image "$IMAGE" --replicas 3 > "$WORK/sweep.yml"
grep -q 'SIMNET_SHARD: "{{.Task.Slot}}/3"' "$WORK/sweep.yml"
docker stack deploy --resolve-image never -c "$WORK/sweep.yml" "$STACK" >"$WORK/deploy.log" 2>&1 ||
  { cat "$WORK/deploy.log" >&2; echo "FAIL: docker stack deploy" >&2; exit 1; }
# Wait for the event counted: every task complete (or one failed).
done_tasks=0
for _ in $(seq 1 600); do
  states=$(docker service ps "${STACK}_sweep" --format '{{.DesiredState}} {{.CurrentState}}' 2>/dev/null || true)
  done_tasks=$(grep -c '^Shutdown Complete' <<<"$states" || true)
  if grep -qE 'Failed|Rejected' <<<"$states"; then
    docker service ps --no-trunc "${STACK}_sweep" >&2
    docker service logs "${STACK}_sweep" >&2 || true
    echo "FAIL: a task of the sweep failed" >&2
    exit 1
  fi
  [ "$done_tasks" -ge 3 ] && break
  sleep 0.5
done
if [ "$done_tasks" -lt 3 ]; then
  docker service ps "${STACK}_sweep" >&2
  echo "FAIL: $done_tasks of 3 tasks completed" >&2
  exit 1
fi

echo "== the results volume, merged"
docker run --rm -v "${STACK}_results:/results" -v "$WORK:/work" "$IMAGE" sweep merge /results --out /work/swarm -q >/dev/null
for f in runs.csv points.csv; do
  if ! cmp -s "$WORK/local/$f" "$WORK/swarm/$f"; then
    diff "$WORK/local/$f" "$WORK/swarm/$f" | head -20 >&2
    echo "FAIL: $f of the swarm differs from the local sweep's" >&2
    exit 1
  fi
done
python3 - "$WORK/swarm/manifest.json" <<'EOF'
import json, sys
m = json.load(open(sys.argv[1]))
shards = sorted(s["shard"] for s in m["made_by"])
assert shards == ["1/3", "2/3", "3/3", "merge"], shards
assert m["runs"] == 12, m["runs"]
EOF
echo "1 passed, 0 failed: 3 tasks, 12 runs, runs.csv and points.csv equal to the local sweep's"
