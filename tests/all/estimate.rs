//! The print-time estimate against PrusaSlicer's own, on files it sliced.

use crate::common;

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
        let Some(data) = common::slice("tri_overhang", args) else {
            return;
        };
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

fn poa() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_poa"))
}

fn progress_lines(text: &str) -> Vec<(f64, f64)> {
    text.lines()
        .filter_map(|l| l.strip_prefix("M73 P"))
        .filter_map(|rest| {
            let (p, r) = rest.split_once(" R")?;
            Some((p.parse().ok()?, r.split_whitespace().next()?.parse().ok()?))
        })
        .collect()
}

/// What `--report` says a rewrite added is what `check --compare` measures between the files,
/// and the progress lines count down the new total.
#[test]
fn report_compare_and_progress_lines_agree() {
    for name in ["rect_overhang", "circ_overhang", "tri_overhang"] {
        let dir = tempfile::tempdir().unwrap();
        let original = common::sample(&format!("{name}_prusa_rel.gcode"));
        let file = dir.path().join("part.gcode");
        let report = dir.path().join("report.json");
        let o = poa()
            .arg("process")
            .arg(&original)
            .arg("-o")
            .arg(&file)
            .arg("--report")
            .arg(&report)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let r: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
        let o = poa()
            .args(["check", "--json", "--compare"])
            .arg(&original)
            .arg(&file)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let files = &r["files"][0]["report"];
        let (rt, ct) = (
            files["time_added_s"].as_f64().unwrap(),
            c["time_added_s"].as_f64().unwrap(),
        );
        let (rf, cf) = (
            files["filament_added_mm"].as_f64().unwrap(),
            c["filament_added_mm"].as_f64().unwrap(),
        );
        eprintln!("{name}: time {rt:.1} / {ct:.1} s, filament {rf:.2} / {cf:.2} mm");
        assert!(
            rt > 0.0 && (rt - ct).abs() <= 0.05 * ct.abs() + 1.0,
            "{name}: {rt} vs {ct}"
        );
        assert!((rf - cf).abs() < 0.05, "{name}: {rf} vs {cf}");

        // Progress lines: same count, counting down the new total.
        let before = std::fs::read_to_string(&original).unwrap();
        let after = std::fs::read_to_string(&file).unwrap();
        let (p0, p1) = (progress_lines(&before), progress_lines(&after));
        assert_eq!(p0.len(), p1.len());
        let total = after
            .lines()
            .find_map(|l| l.strip_prefix("; estimated printing time (normal mode) = "))
            .and_then(parse_dhms)
            .unwrap();
        assert_eq!(p1[0], (0.0, (total / 60.0).floor()), "{name}");
        assert!(
            p1.windows(2).all(|w| w[1].0 >= w[0].0 && w[1].1 <= w[0].1),
            "{name}"
        );
        assert_eq!(p1.last(), Some(&(100.0, 0.0)));

        // --keep-progress leaves them as the slicer wrote them; nothing else differs.
        // (Slicer mode, in place, like PrusaSlicer runs it.)
        let kept = dir.path().join("kept.gcode");
        std::fs::copy(&original, &kept).unwrap();
        let o = poa().arg("--keep-progress").arg(&kept).output().unwrap();
        assert!(o.status.success());
        let kept = std::fs::read_to_string(&kept).unwrap();
        assert_eq!(progress_lines(&kept), p0);
        let strip = |t: &str| -> Vec<String> {
            t.lines()
                .filter(|l| !l.starts_with("M73"))
                .map(String::from)
                .collect()
        };
        assert_eq!(strip(&kept), strip(&after));
    }
}
