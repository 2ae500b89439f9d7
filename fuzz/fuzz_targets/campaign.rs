//! What a campaign reads that anyone could have written: `plan.json`, `runs/KEY.json` checked against the plan, the
//! `--set KEY=VALUES` grammar of a sweep and of a run, and `--shard I/N`. An error naming what is wrong, never a panic,
//! an abort or an allocation by a crafted size.
#![no_main]
use libfuzzer_sys::fuzz_target;
use simnet::campaign::{parse_shard, Axis, PlanFile, RunRecord};

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    match mode % 3 {
        // A plan, then a record checked against each of its first runs.
        0 => {
            let (plan, record) = text.split_once('\u{0}').unwrap_or((text, ""));
            if let Ok(p) = PlanFile::parse(plan) {
                let runs = p.runs();
                for i in 0..p.points.len().min(4) {
                    let _ = p.describe(i);
                }
                if let Ok(r) = serde_json::from_str::<RunRecord>(record) {
                    for run in runs.iter().take(4) {
                        let _ = r.clone().file_under(run, &p);
                    }
                }
            }
        }
        // A sweep's axis, and a small one's points over a built-in.
        1 => {
            let _ = simnet::scenario::parse_set(text);
            let _ = parse_shard(text);
            if let Ok(a) = Axis::parse(text) {
                if a.values.len() <= 4 {
                    if let Ok(base) = simnet::Scenario::resolve("ring3") {
                        let _ = simnet::campaign::Plan::new(base, vec![a], 1);
                    }
                }
            }
        }
        // `--set` on a run: every key path and value the grammar reads, set on a built-in.
        _ => {
            if let Ok((k, v)) = simnet::scenario::parse_set(text) {
                if let Ok(base) = simnet::Scenario::resolve("line4") {
                    let _ = base.set(&k, v);
                }
            }
        }
    }
});
