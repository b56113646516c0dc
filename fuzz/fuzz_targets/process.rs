//! The whole rewrite of a file and its progress pass: no panic on any input, and the
//! progress pass keeps every line.
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
    let Ok(report) = process(data, config, &opts, &mut out) else {
        return;
    };
    // The progress pass changes numbers only: every line stays, in order.
    let mut fixed = Vec::new();
    let totals = printonair::progress::Totals::default();
    printonair::progress::update(&out[..], &mut fixed, &report.progress, totals)
        .expect("in-memory progress pass");
    let lines = |b: &[u8]| b.iter().filter(|&&c| c == b'\n').count();
    assert_eq!(lines(&out), lines(&fixed));
});
