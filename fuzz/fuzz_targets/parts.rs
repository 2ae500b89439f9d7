//! What `simnet collect` reads from a node's part: `estimates-ID.csv`, `trace-ID.csv` and `node-ID.json` (merged
//! with itself). An error naming the file and line, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use simnet::report::parts;

fuzz_target!(|data: &[u8]| {
    let _ = parts::read_estimates(data, 0, "estimates-0.csv");
    let _ = parts::read_trace(data, "trace-0.csv");
    if let Ok(s) = serde_json::from_slice::<simnet::Summary>(data) {
        let estimates = Default::default();
        let _ = parts::merge(&[s.clone(), s], &estimates);
    }
});
