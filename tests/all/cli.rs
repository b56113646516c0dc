//! The `poa` binary as users and scripts call it.

use crate::common;

use std::process::{Command, Output};

use common::*;

fn poa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_poa"))
        .args(args)
        .env_remove("SLIC3R_FILAMENT_DIAMETER")
        .output()
        .expect("run poa")
}

fn assert_clean_failure(out: &Output, what: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{what}: should fail");
    assert_ne!(out.status.code(), Some(101), "{what}: panicked: {stderr}");
    assert!(!stderr.contains("panicked"), "{what}: {stderr}");
    let lines = stderr.trim().lines().count();
    assert!(
        (1..=2).contains(&lines),
        "{what}: message should be one or two lines: {stderr}"
    );
    assert!(stderr.starts_with("poa: "), "{what}: {stderr}");
}

#[test]
fn info_describes_a_prusaslicer_file() {
    let f = sample("rect_overhang_prusa_rel.gcode");
    let out = poa(&["info", f.to_str().unwrap()]);
    assert!(out.status.success());
    let s = String::from_utf8(out.stdout).unwrap();
    assert!(s.contains("PrusaSlicer 2.5"), "{s}");
    assert!(s.contains("layers      100"), "{s}");
    assert!(s.contains("external perimeter"), "{s}");
    assert!(s.contains("rect_overhang.stl"), "{s}");
}

#[test]
fn info_json_is_stable() {
    let f = sample("rect_overhang_prusa_abs.gcode");
    let out = poa(&["info", "--json", f.to_str().unwrap()]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["slicer"], "PrusaSlicer");
    assert_eq!(v["layers"], 100);
    assert_eq!(v["layer_source"], "markers");
    let modes: Vec<&str> = v["e_modes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    assert!(modes.contains(&"absolute"));
    let stated = v["stated_filament_mm"].as_f64().unwrap();
    let got = v["filament_mm"].as_f64().unwrap();
    assert!((stated - got).abs() / stated < 0.005);
    for key in [
        "roles",
        "objects",
        "diagnostics",
        "filament_g",
        "first_layer_z",
        "spiral_vase",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
}

#[test]
fn info_notes_inferred_layers() {
    let f = sample("rect_overhang_nocomments.gcode");
    let out = poa(&["info", f.to_str().unwrap()]);
    assert!(out.status.success());
    let s = String::from_utf8(out.stdout).unwrap();
    assert!(
        s.contains("no layer comments: layers inferred from Z"),
        "{s}"
    );
}

#[test]
fn bad_inputs_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, data: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, data).unwrap();
        p
    };
    // Readable, if odd: reported, exit 0.
    let empty = write("empty.gcode", b"");
    let out = poa(&["info", empty.to_str().unwrap()]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("layers      0"));

    let full = read(&sample("rect_overhang_prusa_rel.gcode"));
    let truncated = write("truncated.gcode", &full[..full.len() / 2 + 7]);
    let out = poa(&["info", truncated.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // Not G-code: one-line refusal.
    let mut junk = Vec::new();
    let mut x: u32 = 12345;
    for _ in 0..10_000 {
        x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
        junk.push((x >> 16) as u8);
    }
    let random = write("random.gcode", &junk);
    assert_clean_failure(&poa(&["info", random.to_str().unwrap()]), "random bytes");
    let bgcode = write("x.bgcode", b"GCDE\x01\x00\x00\x00\x01\x00\x01\x00");
    assert_clean_failure(&poa(&["info", bgcode.to_str().unwrap()]), "binary gcode");
    assert_clean_failure(&poa(&["info", dir.path().to_str().unwrap()]), "directory");
    let missing = dir.path().join("missing.gcode");
    assert_clean_failure(&poa(&["info", missing.to_str().unwrap()]), "missing file");
}

#[test]
fn analyze_json_lists_regions() {
    let f = sample("bridge_prusa_rel.gcode");
    let out = poa(&["analyze", "--json", f.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["summary"]["regions"], 1);
    assert_eq!(v["summary"]["bridges"], 1);
    let r = &v["regions"][0];
    assert_eq!(r["kind"], "bridge");
    assert_eq!(r["layer"], 51);
    assert!((r["z"].as_f64().unwrap() - 10.2).abs() < 1e-9);
    for key in [
        "id",
        "area_mm2",
        "max_distance_mm",
        "anchored_length_mm",
        "anchors",
        "object",
        "bbox",
        "extrusions",
        "over_air_length_mm",
        "over_air_filament_mm",
    ] {
        assert!(r.get(key).is_some(), "missing {key}");
    }
    assert!(v["settings"]["tolerance_mm"].as_f64().unwrap() > 0.2);
}

#[test]
fn analyze_human_output_and_settings() {
    let f = sample("rect_overhang_prusa_rel.gcode");
    let out = poa(&["analyze", f.to_str().unwrap()]);
    let s = String::from_utf8(out.stdout).unwrap();
    assert!(s.contains("1 region over air on 1 layer"), "{s}");
    assert!(s.contains("overhang"), "{s}");
    // A 10 mm tolerance swallows the overhang's first 10 mm; the rest is still reported.
    let out = poa(&[
        "analyze",
        "--json",
        "--tolerance",
        "10",
        f.to_str().unwrap(),
    ]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let a = v["regions"][0]["area_mm2"].as_f64().unwrap();
    assert!((a - 600.0).abs() < 10.0, "{a}");
    // Nonsense settings are refused with a message.
    assert_clean_failure(
        &poa(&["analyze", "--overhang-angle", "95", f.to_str().unwrap()]),
        "angle out of range",
    );
}

#[test]
fn preview_draws_a_layer_and_the_regions() {
    let dir = tempfile::tempdir().unwrap();
    let f = sample("bridge_prusa_rel.gcode");
    let svg = dir.path().join("l51.svg");
    let out = poa(&[
        "preview",
        f.to_str().unwrap(),
        "--layer",
        "51",
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"));
    assert!(text.contains("#1 bridge 791"), "region label");
    assert!(
        text.contains("bridge infill"),
        "legend lists the roles drawn"
    );
    assert!(text.contains("10 mm"), "scale bar");
    assert_eq!(text.matches("<svg").count(), 1);

    let folder = dir.path().join("regions");
    let out = poa(&[
        "preview",
        f.to_str().unwrap(),
        "--regions",
        "-o",
        folder.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let index = std::fs::read_to_string(folder.join("index.html")).unwrap();
    assert!(index.contains("layer-0051.svg"));
    assert!(index.contains(">bridge<"));
    assert!(folder.join("layer-0051.svg").is_file());

    let out = poa(&[
        "preview",
        f.to_str().unwrap(),
        "--layer",
        "500",
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert_clean_failure(&out, "no such layer");
    let out = poa(&["preview", f.to_str().unwrap(), "-o", svg.to_str().unwrap()]);
    assert!(!out.status.success(), "--layer or --regions is required");
}

#[test]
fn check_draws_a_layer_with_its_unsupported_points() {
    let dir = tempfile::tempdir().unwrap();
    let f = sample("rect_overhang_prusa_rel.gcode");
    let svg = dir.path().join("c.svg");
    let out = poa(&[
        "check",
        f.to_str().unwrap(),
        "--svg-layer",
        "51",
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("deposition check"));
    assert!(
        text.matches("#d7191c").count() > 100,
        "in-air points of the overhang drawn"
    );
    // --fail-in-air for scripts.
    let out = poa(&["check", f.to_str().unwrap(), "--fail-in-air", "5"]);
    assert_eq!(out.status.code(), Some(2));
}

/// `--help`, `poa config` and `poa profiles show` state each setting's values and default as
/// the settings table does: they are made from it.
#[test]
fn help_config_and_profiles_agree_with_the_settings_table() {
    use printonair::settings::{range_text, SPECS};
    let squash = |o: std::process::Output| -> String {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout)
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
    };
    let help = squash(poa(&["--help"]));
    let config = squash(poa(&[
        "config",
        sample("rect_overhang_prusa_rel.gcode").to_str().unwrap(),
    ]));
    let profile = squash(poa(&["profiles", "show", "petg"]));
    for s in SPECS {
        let stated = format!("{}; default {}", range_text(s), s.default);
        // Every key has a named flag.
        assert!(
            help.contains(&stated),
            "--help lacks `{stated}` for {}",
            s.key
        );
        assert!(
            config.contains(&stated),
            "poa config lacks `{stated}` for {}",
            s.key
        );
        if profile.contains(&format!("{}:", s.key)) {
            assert!(
                profile.contains(&stated),
                "profile lacks `{stated}` for {}",
                s.key
            );
        }
    }
    assert!(!help.contains("0..0.9"));
    // `auto` is a source; the value shown is the one that will be used for this file.
    assert!(
        config.contains("loop_speed 25 mm/s auto: the file's bridge_speed"),
        "{config}"
    );
    assert!(config.contains("tolerance 0.225 mm auto:"), "{config}");
}

#[test]
fn analyze_of_a_rewritten_file_says_so_and_reports_what_is_still_in_air() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("done.gcode");
    let src = sample("rect_overhang_prusa_abs.gcode");
    let o = poa(&[
        "process",
        src.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let text = String::from_utf8(poa(&["analyze", out.to_str().unwrap()]).stdout).unwrap();
    assert!(text.contains("already rewritten by poa"), "{text}");
    assert!(text.contains("still in air (deposition check)"), "{text}");
    assert!(!text.contains("over air"), "{text}");
    let json = poa(&["analyze", "--json", out.to_str().unwrap()]);
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    let in_air = v["rewritten_by_poa"]["in_air_mm"].as_f64().unwrap();
    assert!(in_air < 5.0, "{in_air}");
    // The slicer's file: no such note.
    let orig = poa(&["analyze", "--json", src.to_str().unwrap()]);
    let v: serde_json::Value = serde_json::from_slice(&orig.stdout).unwrap();
    assert!(v["rewritten_by_poa"].is_null());
}

/// The slowest feedrate (mm/min) poa's loops extrude at in `text`: `G1 F..` lines between
/// `;POA_BEGIN` and `;POA_END`, followed by an extruding move.
fn slowest_loop_feed(text: &str) -> f64 {
    let (mut inside, mut feed, mut slowest) = (false, f64::MAX, f64::MAX);
    for line in text.lines() {
        if line.starts_with(";POA_BEGIN") {
            inside = true;
        } else if line.starts_with(";POA_END") {
            inside = false;
        } else if inside && line.starts_with("G1") {
            let words: Vec<&str> = line.split(';').next().unwrap().split_whitespace().collect();
            if let Some(f) = words.iter().find_map(|w| w.strip_prefix('F')) {
                feed = f.parse().unwrap();
            }
            let extrudes = words.iter().any(|w| w.starts_with('E'))
                && words
                    .iter()
                    .any(|w| w.starts_with('X') || w.starts_with('Y'));
            if extrudes {
                slowest = slowest.min(feed);
            }
        }
    }
    slowest
}

#[test]
fn short_loops_slow_down_no_further_than_the_file_s_minimum_print_speed() {
    // The triangle's tip: loops shorter than half a second's print. The file says
    // `min_print_speed = 15`: poa's loops go no slower; `--min-loop-speed 5` lets them.
    let f = sample("tri_overhang_prusa_abs.gcode");
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| -> f64 {
        let out_path = dir.path().join("out.gcode");
        let mut args = vec![
            "process",
            f.to_str().unwrap(),
            "-o",
            out_path.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let out = poa(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        slowest_loop_feed(&std::fs::read_to_string(&out_path).unwrap())
    };
    assert!(std::fs::read_to_string(&f)
        .unwrap()
        .contains("; min_print_speed = 15\n"));
    assert_eq!(run(&[]), 900.0, "15 mm/s");
    assert_eq!(run(&["--min-loop-speed", "5"]), 300.0, "5 mm/s");
    assert_eq!(
        run(&["--set", "min_loop_time=0"]),
        1500.0,
        "no slowing: the bridge speed"
    );
}
