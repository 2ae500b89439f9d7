//! A recorded IMU file, in simnet's CSV or a maker's layout: parsed into samples, or an error naming the line; on
//! success, the attitude comparison and the magnetometer's ellipsoid fit run on it, to a result or an error. Never a
//! panic, never a hang.
#![no_main]
use libfuzzer_sys::fuzz_target;
use simnet::analysis::attitude::{calibrate, compare};
use simnet::imu_csv::layout;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(rec) = simnet::imu_csv::parse(text, "fuzz.csv") {
        let _ = rec.at_steps(0.01, 100);
    }
    let _ = layout::read_reference(text, "fuzz.csv", &Default::default());
    if let Ok(r) = layout::read_any(text, "fuzz.csv", &Default::default()) {
        let _ = compare(&r.recording, r.rate_hz);
        if let Some(m) = &r.recording.mag {
            let _ = calibrate::fit(m);
        }
    }
});
