//! A topology file as anyone could write it: parsed and validated into a scenario, or an error naming the key.
//! Never a panic; what validates writes itself out and reads back as the same scenario.
#![no_main]
use libfuzzer_sys::fuzz_target;
use simnet::Scenario;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(s) = Scenario::from_toml(text, "fuzz.toml") {
        let again = Scenario::from_toml(&s.to_toml(), "fuzz.toml").expect("a valid scenario's TOML validates");
        assert_eq!(again.to_toml(), s.to_toml());
    }
});
