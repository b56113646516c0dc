//! The whole rewrite of a file: no panic on any input, and what it writes reads back.
#![no_main]

use libfuzzer_sys::fuzz_target;
use printonair::emit::{process, ObjectFilter, ProcessOptions};
use printonair::layers::SlicerConfig;
use printonair::poa::PoaSettings;

fuzz_target!(|data: &[u8]| {
    let config = SlicerConfig::parse(data);
    let opts = ProcessOptions {
        detect: printonair::report::detect_options(&config),
        settings: PoaSettings::default(),
        objects: ObjectFilter::default(),
        header: "; poa print-on-air fuzz".into(),
    };
    let mut out = Vec::new();
    let _ = process(data, config, &opts, &mut out);
});
