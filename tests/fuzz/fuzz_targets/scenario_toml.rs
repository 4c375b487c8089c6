#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| dca_tests::fuzz::scenario_toml(data));
