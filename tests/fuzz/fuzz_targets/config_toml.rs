#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| dca_tests::fuzz::config_toml(data));
