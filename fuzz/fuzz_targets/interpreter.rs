//! The modal interpreter on arbitrary lines: no panic, finite positions.
#![no_main]

use libfuzzer_sys::fuzz_target;
use printonair::gcode::parse_line;
use printonair::machine::{Action, Machine};

fuzz_target!(|data: &[u8]| {
    let mut m = Machine::new();
    for (i, line) in data.split(|&b| b == b'\n').enumerate() {
        if let Action::Move(mv) = m.step(&parse_line(line), i as u64 + 1) {
            assert!(mv.to.iter().all(|v| v.is_finite()));
            let _ = mv.points(0.01);
        }
    }
});
