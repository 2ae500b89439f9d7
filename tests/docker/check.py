#!/usr/bin/env python3
"""Assertions of tests/docker/faults.sh on the parts and the merged summary of a multi-host run."""
import csv
import glob
import json
import math
import os
import sys


def fail(msg):
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def parts(d):
    out = {}
    for p in glob.glob(os.path.join(d, "node-*.json")):
        s = json.load(open(p))
        out[s["part"]["node"]] = s
    return out


def networked_rows(d, node):
    with open(os.path.join(d, f"trace-{node}.csv")) as f:
        return [r for r in csv.DictReader(f) if r["estimator"] == "networked"]


def fault(d, target, downtime, rate):
    ps = parts(d)
    if sorted(ps) != [0, 1, 2]:
        fail(f"expected parts of nodes 0, 1, 2, got {sorted(ps)}")
    steps = max(p["part"]["steps_done"] for p in ps.values())
    for i, p in ps.items():
        n = p["nodes"][0]
        if n["networked"]["diverged"]:
            fail(f"node {i}: networked covariance diverged")
        if i != target and (p["part"]["steps_done"] != steps or p["interrupted"]):
            fail(f"survivor {i} stopped stepping: {p['part']['steps_done']} of {steps} steps")
    print(f"  survivors stepped all {steps} steps; no networked filter diverged")
    for i, p in ps.items():
        if i == target:
            continue
        rows = networked_rows(d, i)
        run = best = 0
        for r in rows:
            got = {int(x) for x in r["received"].split(";") if x}
            run = run + 1 if target not in got else 0
            best = max(best, run)
        missing = dict((src, c) for src, c in p["part"]["rx"])[target]["missing_steps"]
        tol = max(1.0, 0.15 * downtime)
        print(f"  node {i}: {missing} steps without node {target} ({missing / rate:.2f} s; longest gap {best / rate:.2f} s) "
              f"vs {downtime:.2f} s away (± {tol:.2f} s)")
        if abs(missing / rate - downtime) > tol:
            fail(f"node {i} recorded {missing / rate:.2f} s of loss from node {target}, which was away {downtime:.2f} s")
    window = int(2 * rate)
    def tail_mean(node):
        rows = networked_rows(d, node)[-window:]
        return sum(float(r["trace_p_post"]) for r in rows) / len(rows)
    steady = sum(tail_mean(i) for i in ps if i != target) / 2
    back = tail_mean(target)
    print(f"  node {target}: trace P over the last 2 s {back:.4e} vs survivors' {steady:.4e} ({100 * (back / steady - 1):+.1f} %)")
    if abs(back / steady - 1) > 0.10:
        fail(f"node {target}'s trace P did not return within 10 % of the steady state")
    print("ok")


def loss(d, p):
    m = json.load(open(os.path.join(d, "merged.json")))
    sent = sum(l["sent"] for l in m["links"])
    # Late datagrams crossed the link too (the realtime clock decides lateness, not the loss model).
    delivered = sum(l["delivered"] + l["late"] for l in m["links"])
    frac = delivered / sent
    sigma = math.sqrt(p * (1 - p) / sent)
    print(f"  arrived {delivered}/{sent} = {frac:.4f}; expected {1 - p} ± {3 * sigma:.4f} (3σ)")
    if abs(frac - (1 - p)) > 3 * sigma:
        fail("arrived fraction outside 3σ")
    for n in m["nodes"]:
        if n["networked"]["diverged"]:
            fail(f"node {n['id']} diverged")
    print("ok")


if __name__ == "__main__":
    if sys.argv[1] == "fault":
        fault(sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]))
    elif sys.argv[1] == "loss":
        loss(sys.argv[2], float(sys.argv[3]))
    else:
        fail(f"unknown check {sys.argv[1]}")
