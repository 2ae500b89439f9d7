//! A recorded IMU file: parsed into samples, or an error naming the line. Never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(rec) = simnet::imu_csv::parse(text, "fuzz.csv") {
        let _ = rec.at_steps(0.01, 100);
    }
});
