#![no_main]
//! libFuzzer on `cloth_fuzz::Target::Snapshot`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    cloth_fuzz::libfuzzer_once();
    cloth_fuzz::Target::Snapshot.run(data);
});
