//! Golden outputs: the rewrite of every sample, of two generated plates and of `poa ab` cases
//! must stay byte for byte what it was when `tests/all/golden.txt` was written (length and
//! CRC-32 of each output). Restructuring must not change a byte; a deliberate change of the
//! output regenerates the file with `POA_BLESS=1 cargo test --release golden` and says why in
//! its commit.

use crate::common;

use std::path::Path;
use std::process::Command;

use common::*;

fn fingerprint(bytes: &[u8]) -> String {
    format!("{} {:08x}", bytes.len(), crc32fast::hash(bytes))
}

/// Runs poa with `args` (the output path last) and fingerprints the output, or the refusal.
fn outcome(args: &[&dyn AsRef<std::ffi::OsStr>], out: &Path) -> String {
    let _ = std::fs::remove_file(out);
    let mut c = Command::new(env!("CARGO_BIN_EXE_poa"));
    for (k, _) in std::env::vars() {
        if k.starts_with("SLIC3R_") {
            c.env_remove(k);
        }
    }
    let o = c.args(args).output().unwrap();
    if o.status.success() {
        fingerprint(&std::fs::read(out).unwrap())
    } else {
        format!("refused {:?}", o.status.code())
    }
}

/// A plate of `n` copies of a PrusaSlicer sample, each layer printed once per copy, shifted by
/// `dx` mm in X: the part as a slicer's "duplicate" would place it.
fn plate(name: &str, n: usize, dx: f64) -> Vec<u8> {
    let text = String::from_utf8(read(&sample(name))).unwrap();
    let (body, tail) = text.split_at(text.find("\n; filament used [mm]").unwrap());
    let mut parts = body.split(";LAYER_CHANGE\n");
    let mut out = parts.next().unwrap().to_string();
    let coord = regex::Regex::new(r"X(-?\d*\.?\d+)").unwrap();
    for layer in parts {
        out.push_str(";LAYER_CHANGE\n");
        out.push_str(layer);
        for k in 1..n {
            for line in layer.split_inclusive('\n') {
                if line.starts_with("G1") || line.starts_with("G0") {
                    let shifted = coord.replace_all(line, |c: &regex::Captures| {
                        let x: f64 = c[1].parse().unwrap();
                        format!("X{:.3}", x + dx * k as f64)
                    });
                    out.push_str(&shifted);
                } else if !line.starts_with(";Z:") && !line.starts_with(";HEIGHT:") {
                    out.push_str(line);
                }
            }
        }
    }
    out.push_str(tail);
    out.into_bytes()
}

#[test]
fn rewrites_are_byte_for_byte_the_golden_ones() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.gcode");
    let mut got = Vec::new();
    for s in samples() {
        let name = s.file_name().unwrap().to_string_lossy().to_string();
        got.push(format!(
            "process {name} {}",
            outcome(&[&"process", &s, &"-o", &out], &out)
        ));
        if name.starts_with("bridge") {
            let r = outcome(&[&"process", &"--bridges", &"poa", &s, &"-o", &out], &out);
            got.push(format!("process --bridges poa {name} {r}"));
        }
    }
    for (name, n, dx) in [
        ("rect_overhang_prusa_rel.gcode", 3, 60.0),
        ("circ_overhang_prusa_abs.gcode", 4, 30.0),
    ] {
        let p = dir.path().join(format!("plate-{name}"));
        std::fs::write(&p, plate(name, n, dx)).unwrap();
        got.push(format!(
            "plate {n}x {name} {}",
            outcome(&[&"process", &p, &"-o", &out], &out)
        ));
    }
    for (name, extra) in [
        ("rect_overhang_prusa_rel.gcode", vec!["--offset", "60,0"]),
        ("tri_overhang_prusa_abs.gcode", vec!["--offset=-60,0"]),
        (
            "rect_overhang_cura.gcode",
            vec!["--offset", "80,0", "--bed", "0,0,300,300"],
        ),
        (
            "klipper_objects.gcode",
            vec!["--offset", "0,30", "--bed", "0,0,250,210"],
        ),
    ] {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"ab"];
        let s = sample(name);
        args.push(&s);
        args.push(&"-o");
        args.push(&out);
        for e in &extra {
            args.push(e);
        }
        got.push(format!(
            "ab {name} {} {}",
            extra.join(" "),
            outcome(&args, &out)
        ));
    }
    let golden = repo().join("tests/all/golden.txt");
    let text = got.join("\n") + "\n";
    if std::env::var_os("POA_BLESS").is_some() {
        std::fs::write(&golden, &text).unwrap();
        return;
    }
    let want =
        std::fs::read_to_string(&golden).expect("tests/all/golden.txt (POA_BLESS=1 writes it)");
    let diff: Vec<String> = want
        .lines()
        .zip(text.lines())
        .filter(|(a, b)| a != b)
        .map(|(a, b)| format!("  was {a}\n  now {b}"))
        .collect();
    assert!(
        diff.is_empty() && want.lines().count() == text.lines().count(),
        "outputs changed:\n{}",
        diff.join("\n")
    );
}

/// The move-map seam: the identity map gives every sample (and a generated plate) back byte
/// for byte, arcs, comments and line endings included.
#[test]
fn the_identity_move_map_gives_every_sample_back_unchanged() {
    use printonair::movemap::{apply, Identity};
    use printonair::writer::Cartesian;
    let mut inputs: Vec<(String, Vec<u8>)> = samples()
        .iter()
        .map(|s| (s.display().to_string(), read(s)))
        .collect();
    inputs.push((
        "plate".into(),
        plate("rect_overhang_prusa_abs.gcode", 3, 60.0),
    ));
    for (name, text) in inputs {
        let mut out = Vec::with_capacity(text.len());
        let stats = apply(&text[..], &mut Identity, &Cartesian, &mut out).unwrap();
        assert!(stats.moves > 10, "{name}: {stats:?}");
        assert_eq!(stats.rewritten, 0, "{name}");
        assert!(out == text, "{name}: identity map changed the file");
    }
}
