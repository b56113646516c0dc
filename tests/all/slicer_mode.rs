//! `poa FILE` as slicers run it, `poa process`, and what happens when things go wrong.

use crate::common;

use std::process::{Command, Output};

use common::*;

fn poa() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_poa"));
    for (k, _) in std::env::vars() {
        if k.starts_with("SLIC3R_") {
            c.env_remove(k);
        }
    }
    c
}

fn run(args: &[&str]) -> Output {
    poa().args(args).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn copy_sample(dir: &std::path::Path, name: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::copy(sample(name), &p).unwrap();
    p
}

fn count(data: &[u8], needle: &str) -> usize {
    String::from_utf8_lossy(data).matches(needle).count()
}

#[test]
fn rewrites_in_place_and_a_second_run_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode");
    let o = run(&[f.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let once = std::fs::read(&f).unwrap();
    assert_eq!(count(&once, ";POA_BEGIN"), 1);
    assert!(String::from_utf8_lossy(&once)
        .lines()
        .nth(1)
        .unwrap()
        .starts_with("; poa print-on-air"));
    let o = run(&[f.to_str().unwrap()]);
    assert!(o.status.success());
    assert_eq!(std::fs::read(&f).unwrap(), once);
    // No temporary file is left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "{names:?}");
}

#[test]
fn options_come_before_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "bridge_prusa_rel.gcode");
    let o = run(&["--bridges", "poa", "--fan", "80", f.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let data = std::fs::read(&f).unwrap();
    assert_eq!(count(&data, ";POA_BEGIN"), 1);
    assert!(count(&data, "M106 S204") >= 1, "fan at 80 %");
    assert!(String::from_utf8_lossy(&data).contains("fan=80"));
}

#[test]
fn settings_from_the_slicer_environment() {
    // The slicer exports its settings; the file's own block says the same, the environment wins.
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode");
    let o = poa()
        .env("SLIC3R_BRIDGE_SPEED", "12")
        .arg(&f)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let data = std::fs::read_to_string(&f).unwrap();
    assert!(
        data.contains("loops at 12 mm/s"),
        "header records the loop speed"
    );
    assert!(data.contains("G1 F720\n"), "loops at the slicer's 12 mm/s");
}

#[test]
fn refused_files_are_left_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("junk.gcode");
    let bytes: Vec<u8> = (0..20_000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    std::fs::write(&junk, &bytes).unwrap();
    let o = run(&[junk.to_str().unwrap()]);
    assert!(!o.status.success());
    assert_ne!(o.status.code(), Some(101));
    let msg = stderr(&o);
    assert!(
        msg.starts_with("poa: ") && msg.trim().lines().count() <= 2,
        "{msg}"
    );
    assert_eq!(std::fs::read(&junk).unwrap(), bytes);

    let bg = dir.path().join("x.gcode.pp");
    std::fs::write(&bg, b"GCDE\x01\x00\x00\x00\x01\x00rest").unwrap();
    let o = run(&[bg.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("binary G-code"), "{}", stderr(&o));

    // A bad setting is refused before anything is written.
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode");
    let before = std::fs::read(&f).unwrap();
    let o = run(&["--overlap", "5", f.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("`overlap` must be a number from 0.05 to 0.9"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&f).unwrap(), before);
}

#[test]
fn a_failed_write_leaves_the_original_and_no_temp_file() {
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode");
    let before = std::fs::read(&f).unwrap();
    // The file-size limit makes every write past 64 KiB fail with EFBIG, like a full disk.
    let o = Command::new("bash")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 64; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_poa"))
        .arg(&f)
        .output()
        .unwrap();
    assert!(!o.status.success(), "the write should fail");
    let msg = stderr(&o);
    assert!(msg.starts_with("poa: cannot write"), "{msg}");
    assert!(msg.trim().lines().count() <= 2, "{msg}");
    assert_eq!(std::fs::read(&f).unwrap(), before);
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "temp file left: {names:?}");

    // An output folder that does not exist.
    let o = run(&[
        "process",
        f.to_str().unwrap(),
        "-o",
        "/nonexistent-poa/out.gcode",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("cannot write"), "{}", stderr(&o));
    // ... and says what to do.
    assert!(
        stderr(&o).contains("the folder does not exist: create it or write elsewhere"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&f).unwrap(), before);
}

#[test]
fn process_dry_run_report_and_object_filters() {
    let dir = tempfile::tempdir().unwrap();
    let f = sample("rect_overhang_prusa_abs.gcode");
    let report = dir.path().join("r.json");
    let o = run(&[
        "process",
        f.to_str().unwrap(),
        "--dry-run",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("1 rewritten"), "{out}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let r = &v["files"][0]["report"]["rewrites"][0];
    assert!(r["loops"].as_u64().unwrap() > 100);
    assert!(r["written_filament_mm"].as_f64().unwrap() > 0.0);
    assert!(r.get("time_added_s").is_some());

    let out_file = dir.path().join("o.gcode");
    let o = run(&[
        "process",
        f.to_str().unwrap(),
        "-o",
        out_file.to_str().unwrap(),
        "--skip-objects",
        "rect_*",
    ]);
    assert!(o.status.success());
    let data = std::fs::read(&out_file).unwrap();
    assert_eq!(count(&data, ";POA_BEGIN"), 0, "object skipped");
    let o = run(&[
        "process",
        f.to_str().unwrap(),
        "-o",
        out_file.to_str().unwrap(),
        "--objects",
        "rect_overhang.stl*",
    ]);
    assert!(o.status.success());
    assert_eq!(count(&std::fs::read(&out_file).unwrap(), ";POA_BEGIN"), 1);
}

#[test]
fn end_to_end_through_prusaslicer() {
    if !have_prusaslicer() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("part with space.gcode");
    let stl = part("tri_overhang");
    let config = repo().join("sample-gcode/config/prusaslicer-mk3s-pla.ini");
    // PrusaSlicer 2.5 drops the options of a quoted program path (measured): unquoted.
    let poa_cmd = format!("{} --fan 90", env!("CARGO_BIN_EXE_poa"));
    let o = Command::new("prusa-slicer")
        .arg("--load")
        .arg(&config)
        .arg("--export-gcode")
        .arg("-o")
        .arg(&out)
        .arg("--post-process")
        .arg(&poa_cmd)
        .arg(&stl)
        .output()
        .expect("prusa-slicer must be installed (apt-get install -y prusa-slicer)");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let data = std::fs::read(&out).unwrap();
    assert_eq!(count(&data, ";POA_BEGIN"), 1);
    assert!(count(&data, "M106 S230") >= 1, "fan at 90 %");
    // The rewritten file is still one the pipeline reads with the same layers.
    let (layers, _) = read_layers(&data, false);
    assert_eq!(layer_count(&layers), 75);
}

#[test]
fn a_folder_of_files_with_one_bad_file() {
    let dir = tempfile::tempdir().unwrap();
    let a = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode");
    let b = copy_sample(dir.path(), "rect_overhang_cura.gcode");
    let bad = dir.path().join("broken.gcode");
    std::fs::write(&bad, [0u8, 1, 2, 3, 255, 0, 0, 7].repeat(100)).unwrap();
    let out = dir.path().join("out");
    let o = run(&[
        "process",
        a.to_str().unwrap(),
        bad.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out-dir",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "one file failed");
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(table.lines().next().unwrap().starts_with("file"), "{table}");
    assert!(
        table.contains("PrusaSlicer") && table.contains("Cura"),
        "{table}"
    );
    assert!(table.contains("binary data"), "{table}");
    // stderr says the run failed, in one line, not only the table.
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.starts_with("poa: 1 of 3 files failed") && err.trim().lines().count() == 1,
        "{err}"
    );
    for name in ["rect_overhang_prusa_rel.gcode", "rect_overhang_cura.gcode"] {
        assert_eq!(
            count(&std::fs::read(out.join(name)).unwrap(), ";POA_BEGIN"),
            1,
            "{name}"
        );
    }
    assert!(!out.join("broken.gcode").exists());
}

#[test]
fn check_compare_agrees_with_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let f = sample("tri_overhang_prusa_rel.gcode");
    let out = dir.path().join("o.gcode");
    let report = dir.path().join("r.json");
    let o = run(&[
        "process",
        f.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let added = r["files"][0]["report"]["filament_added_mm"]
        .as_f64()
        .unwrap();
    let o = run(&[
        "check",
        "--json",
        "--compare",
        f.to_str().unwrap(),
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let compared = c["filament_added_mm"].as_f64().unwrap();
    assert!(
        (compared - added).abs() < 0.01,
        "check says {compared}, the report {added}"
    );
    let changed = c["changed"].as_array().unwrap();
    assert_eq!(changed.len(), 1, "only the rewritten layer differs");
    assert!(
        c["file"]["in_air_mm"].as_f64().unwrap() < c["original"]["in_air_mm"].as_f64().unwrap()
    );
}
