//! The print-time estimate against PrusaSlicer's own, on files it sliced.

mod common;

use printonair::estimate::{estimate_text, parse_dhms};
use printonair::layers::SlicerConfig;

/// PrusaSlicer's normal-mode estimate from a file's statistics footer.
fn slicer_estimate(text: &str) -> Option<f64> {
    text.lines()
        .rev()
        .find_map(|l| l.strip_prefix("; estimated printing time (normal mode) = "))
        .and_then(parse_dhms)
}

#[test]
fn estimate_is_within_five_percent_of_prusaslicer() {
    let mut checked = 0;
    for path in common::samples() {
        let data = std::fs::read(&path).unwrap();
        let text = String::from_utf8_lossy(&data);
        let Some(expected) = slicer_estimate(&text) else {
            continue;
        };
        let config = SlicerConfig::parse(&data);
        let t = estimate_text(&data, &config);
        let err = (t - expected) / expected;
        eprintln!(
            "{}: poa {:.0} s, PrusaSlicer {:.0} s, {:+.2} %",
            path.display(),
            t,
            expected,
            100.0 * err
        );
        assert!(err.abs() < 0.05, "{}: {t} vs {expected}", path.display());
        checked += 1;
    }
    assert!(checked >= 8, "only {checked} samples carry an estimate");
}

/// Other firmwares and limit settings: the estimate follows the rules of each.
#[test]
fn estimate_follows_other_flavors_and_limit_settings() {
    let variants: &[&[&str]] = &[
        &["--gcode-flavor", "marlin"],
        &["--gcode-flavor", "repetier"],
        &["--gcode-flavor", "reprapfirmware"],
        &["--machine-limits-usage", "time_estimate_only"],
        &["--machine-limits-usage", "ignore"],
        &["--gcode-flavor", "reprap"],
    ];
    for args in variants {
        let data = common::slice("tri_overhang", args);
        let text = String::from_utf8_lossy(&data);
        let expected = slicer_estimate(&text).expect("PrusaSlicer writes its estimate");
        let t = estimate_text(&data, &SlicerConfig::parse(&data));
        let err = (t - expected) / expected;
        eprintln!(
            "{args:?}: poa {t:.0} s, PrusaSlicer {expected:.0} s, {:+.2} %",
            100.0 * err
        );
        assert!(err.abs() < 0.05, "{args:?}: {t} vs {expected}");
    }
}
