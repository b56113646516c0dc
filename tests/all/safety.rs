//! Issue 13, one test per case: no path loses or corrupts a file, no input blows up memory or
//! time, every refusal is one or two lines a user can act on.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

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

fn run(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    poa().args(args).output().unwrap()
}

fn err(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// A refusal: non-zero, no panic, `poa: ` and at most two lines.
fn refused(o: &Output, what: &str) -> String {
    let e = err(o);
    assert!(
        matches!(o.status.code(), Some(1) | Some(2)),
        "{what}: status {:?}: {e}",
        o.status
    );
    assert!(
        e.starts_with("poa: ") && e.trim().lines().count() <= 2,
        "{what}: {e}"
    );
    e
}

fn copy_sample(dir: &Path, name: &str, as_name: &str) -> PathBuf {
    let p = dir.join(as_name);
    std::fs::copy(sample(name), &p).unwrap();
    p
}

/// Names in `dir` that are poa's temporary files.
fn temps(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.contains(".poa-tmp-"))
        .collect()
}

const MAX_KIB: u64 = 64 * 1024;

// ---------------------------------------------------------------------------------------------
// Data loss

/// Case 1: `-o OUT` where OUT is a hard link to an already-processed IN truncated IN to 0.
#[test]
fn hard_link_output_of_a_processed_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in.gcode");
    assert!(run(&[&input]).status.success());
    let processed = std::fs::read(&input).unwrap();
    let out = dir.path().join("out.gcode");
    std::fs::hard_link(&input, &out).unwrap();
    let o = run(&[&"process", &input, &"-o", &out]);
    refused(&o, "hard link");
    assert_eq!(std::fs::read(&input).unwrap(), processed);
    // A symlink to the input is the input too, and so is a second name in --out-dir.
    let link = dir.path().join("link.gcode");
    std::os::unix::fs::symlink(&input, &link).unwrap();
    refused(&run(&[&"process", &input, &"-o", &link]), "symlink");
    assert_eq!(std::fs::read(&input).unwrap(), processed);
}

/// Case 2: two inputs with one output name raced on one temporary file.
#[test]
fn two_inputs_with_one_output_name_are_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["a", "b"] {
        std::fs::create_dir(dir.path().join(sub)).unwrap();
    }
    let a = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "a/x.gcode");
    let b = copy_sample(dir.path(), "circ_overhang_prusa_rel.gcode", "b/x.gcode");
    let out = dir.path().join("out");
    let e = refused(&run(&[&"process", &a, &b, &"--out-dir", &out]), "same name");
    assert!(e.contains("would both be written"), "{e}");
    assert!(!out.join("x.gcode").exists(), "nothing written");
    // Distinct names are processed in parallel, each into its own file.
    let c = copy_sample(dir.path(), "circ_overhang_prusa_rel.gcode", "b/y.gcode");
    let o = run(&[&"process", &a, &c, &"--out-dir", &out]);
    assert!(o.status.success(), "{}", err(&o));
    for (f, n) in [(&a, "x.gcode"), (&c, "y.gcode")] {
        let got = std::fs::read(out.join(n)).unwrap();
        let want = std::fs::read(f).unwrap();
        assert!(
            got.len() > want.len() && got.starts_with(&want[..100]),
            "{n}"
        );
    }
    assert!(temps(&out).is_empty());
}

/// Case 3: every output path that could name the input.
#[test]
fn no_output_overwrites_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in.gcode");
    let before = std::fs::read(&f).unwrap();
    let other = dir.path().join("other.gcode");
    let hard = dir.path().join("hard.gcode");
    std::fs::hard_link(&f, &hard).unwrap();
    let cases: Vec<(&str, Vec<&dyn AsRef<std::ffi::OsStr>>)> = vec![
        (
            "--report IN",
            vec![&"process", &f, &"-o", &other, &"--report", &f],
        ),
        (
            "--report hard link",
            vec![&"process", &f, &"-o", &other, &"--report", &hard],
        ),
        (
            "check svg",
            vec![&"check", &f, &"--svg-layer", &"3", &"-o", &f],
        ),
        ("preview", vec![&"preview", &f, &"--layer", &"3", &"-o", &f]),
        ("ab", vec![&"ab", &f, &"-o", &f, &"--offset", &"60,0"]),
        (
            "ab hard link",
            vec![&"ab", &f, &"-o", &hard, &"--offset", &"60,0"],
        ),
        ("convert", vec![&"convert", &f, &f]),
    ];
    for (what, args) in cases {
        let e = refused(&run(&args), what);
        assert!(e.contains("input"), "{what}: {e}");
        assert_eq!(std::fs::read(&f).unwrap(), before, "{what}");
        assert!(!other.exists(), "{what}: nothing written");
    }
    assert!(temps(dir.path()).is_empty());
}

/// Case 3, second half: the report is written atomically, so a full disk keeps the old one.
#[test]
fn a_report_that_cannot_be_written_keeps_the_old_one() {
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in.gcode");
    let report = dir.path().join("r.json");
    std::fs::write(&report, "{\"old\": true}\n").unwrap();
    // The file-size limit (1 KiB) fails every write past it with EFBIG, like a full disk.
    let o = Command::new("bash")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 1; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_poa"))
        .args(["process", "--dry-run", "--report"])
        .arg(&report)
        .arg(&f)
        .output()
        .unwrap();
    let e = refused(&o, "full disk");
    assert!(e.contains("cannot write"), "{e}");
    assert_eq!(
        std::fs::read_to_string(&report).unwrap(),
        "{\"old\": true}\n"
    );
    assert!(temps(dir.path()).is_empty());
}

/// Case 4: outputs that are not regular files are written through, never replaced; slicer
/// mode refuses an input that is not a regular file.
#[test]
fn devices_and_fifos_are_written_through_never_replaced() {
    let f = sample("rect_overhang_prusa_rel.gcode");
    let null = Path::new("/dev/null");
    let o = run(&[&"process", &f, &"-o", &null]);
    assert!(o.status.success(), "{}", err(&o));
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata(null)
        .unwrap()
        .file_type()
        .is_char_device());
    let e = refused(&run(&[&null]), "slicer mode on /dev/null");
    assert!(e.contains("device"), "{e}");
    assert!(std::fs::metadata(null)
        .unwrap()
        .file_type()
        .is_char_device());

    // A FIFO as output: the reader gets the whole rewrite, the FIFO stays a FIFO.
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("out.fifo");
    let ok = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(ok.success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(&fifo).unwrap())
    };
    let o = run(&[&"process", &f, &"-o", &fifo]);
    assert!(o.status.success(), "{}", err(&o));
    let got = reader.join().unwrap();
    assert!(String::from_utf8_lossy(&got).contains(";POA_BEGIN"));
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    assert!(temps(dir.path()).is_empty());
}

/// An output that is a symbolic link stays one: the file it points to is written, also when
/// that file does not exist yet (a link to nothing was replaced by a regular file), through a
/// relative link and a chain of two.
#[test]
fn an_output_link_stays_a_link_even_to_a_file_not_there_yet() {
    let f = sample("rect_overhang_prusa_rel.gcode");
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("real");
    std::fs::create_dir(&sub).unwrap();
    let link = dir.path().join("out.gcode");
    let hop = dir.path().join("hop.gcode");
    std::os::unix::fs::symlink("hop.gcode", &link).unwrap();
    std::os::unix::fs::symlink("real/target.gcode", &hop).unwrap();
    let o = run(&[&"process", &f, &"-o", &link]);
    assert!(o.status.success(), "{}", err(&o));
    for l in [&link, &hop] {
        assert!(std::fs::symlink_metadata(l)
            .unwrap()
            .file_type()
            .is_symlink());
    }
    let written = std::fs::read(sub.join("target.gcode")).unwrap();
    assert!(String::from_utf8_lossy(&written).contains(";POA_BEGIN"));
    assert!(temps(dir.path()).is_empty() && temps(&sub).is_empty());
}

/// Slicer mode keeps the file's owner, group and mode: run as root on a user's file, the
/// rewrite was left owned by root. (Without root the owner cannot be given away, and this
/// checks the mode only.)
#[test]
fn the_rewritten_file_keeps_its_owner_and_mode() {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in.gcode");
    std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o640)).unwrap();
    // SAFETY: geteuid has no preconditions.
    let root = unsafe { libc::geteuid() } == 0;
    if root {
        std::os::unix::fs::chown(&f, Some(1234), Some(1234)).unwrap();
    } else {
        println!("note: not root; the owner is not given away, only the mode is checked");
    }
    let before = std::fs::metadata(&f).unwrap();
    let o = run(&[&f]);
    assert!(o.status.success(), "{}", err(&o));
    let after = std::fs::metadata(&f).unwrap();
    assert_ne!(before.ino(), after.ino(), "replaced by rename");
    assert_eq!(after.mode() & 0o777, 0o640);
    assert_eq!((after.uid(), after.gid()), (before.uid(), before.gid()));
}

/// Case 5: slicer mode inserted its header into any text file (an STL, then rejected by
/// PrusaSlicer).
#[test]
fn files_that_are_not_gcode_are_refused_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let stl = std::fs::read(part("rect_overhang")).unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("model.stl", stl),
        (
            "model.obj",
            b"# made by hand\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec(),
        ),
        (
            "project.3mf",
            b"PK\x03\x04\x14\x00\x00\x00\x08\x00rest of a zip".to_vec(),
        ),
        (
            "notes.txt",
            "Shopping list\n- milk\n- Gouda\n".repeat(50).into_bytes(),
        ),
        (
            "only comments.gcode",
            b"; nothing but comments\n; here\n".to_vec(),
        ),
    ];
    for (name, data) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, &data).unwrap();
        let e = refused(&run(&[&p]), name);
        assert!(e.contains("not G-code"), "{name}: {e}");
        assert_eq!(std::fs::read(&p).unwrap(), data, "{name} byte-identical");
    }
    assert!(temps(dir.path()).is_empty());
}

// ---------------------------------------------------------------------------------------------
// Memory and time

/// A block header with Deflate data that claims to decode to `claim` bytes.
fn deflate_block(claim: u32, data: &[u8], out: &mut Vec<u8>) {
    use std::io::Write;
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::new(6));
    z.write_all(data).unwrap();
    let packed = z.finish().unwrap();
    let start = out.len();
    out.extend_from_slice(&1u16.to_le_bytes()); // G-code block
    out.extend_from_slice(&1u16.to_le_bytes()); // Deflate
    out.extend_from_slice(&claim.to_le_bytes());
    out.extend_from_slice(&(packed.len() as u32).to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes()); // plain text encoding
    out.extend_from_slice(&packed);
    let crc = crc32fast::hash(&out[start..]);
    out.extend_from_slice(&crc.to_le_bytes());
}

#[test]
fn binary_gcode_blocks_claiming_gigabytes_are_refused_fast() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("bomb.bgcode");
    let mut data = b"GCDE\x01\x00\x00\x00\x01\x00".to_vec();
    for _ in 0..4 {
        deflate_block(1 << 30, &vec![b'G'; 1 << 16], &mut data);
    }
    std::fs::write(&f, &data).unwrap();
    for args in [vec!["info"], vec![]] {
        let mut a: Vec<&dyn AsRef<std::ffi::OsStr>> = args.iter().map(|s| s as _).collect();
        a.push(&f);
        let t = Instant::now();
        let (o, peak) = peak_kib(&a, &[]);
        let e = refused(&o, "bomb");
        assert!(e.contains("damaged") || e.contains("decodes to"), "{e}");
        assert!(t.elapsed() < Duration::from_secs(10));
        assert!(peak.is_none_or(|p| p < MAX_KIB), "{peak:?} KiB");
        assert_eq!(std::fs::read(&f).unwrap(), data);
    }
}

/// A legitimate binary file is decoded block by block: the rewrite of a 40 x larger G-code
/// than the sample stays within the bound.
#[test]
fn binary_gcode_is_rewritten_in_bounded_memory() {
    let one = read(&sample("rect_overhang_prusa_rel.gcode"));
    let mut text = one.clone();
    // The same part again and again on top of itself: more layers, same metadata.
    let body_start = String::from_utf8_lossy(&one).find(";LAYER_CHANGE").unwrap();
    for _ in 0..39 {
        text.extend_from_slice(&one[body_start..]);
    }
    let file =
        printonair::bgcode::from_ascii(&text, &printonair::bgcode::BinarizeConfig::prusaslicer())
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("big.bgcode");
    std::fs::write(&f, printonair::bgcode::encode(&file)).unwrap();
    let (o, peak) = peak_kib(&[&f], &[]);
    assert!(o.status.success(), "{}", err(&o));
    eprintln!(
        "{} MB of G-code as {} MB of binary G-code: peak {peak:?} KiB",
        text.len() >> 20,
        std::fs::metadata(&f).unwrap().len() >> 20
    );
    assert!(peak.is_none_or(|p| p < MAX_KIB), "{peak:?} KiB");
    let back = printonair::bgcode::decode(&std::fs::read(&f).unwrap()).unwrap();
    assert!(String::from_utf8_lossy(&back.gcode_text()).contains(";POA_BEGIN"));
}

#[test]
fn endless_and_blocking_inputs_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let zero = dir.path().join("z.gcode");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let fifo = dir.path().join("f.gcode");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    for (what, p) in [("/dev/zero", &zero), ("fifo", &fifo)] {
        for args in [vec![], vec!["info"], vec!["analyze"]] {
            let t = Instant::now();
            let mut child = poa()
                .args(&args)
                .arg(p)
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap();
            let status = loop {
                if let Some(s) = child.try_wait().unwrap() {
                    break s;
                }
                if t.elapsed() > Duration::from_secs(10) {
                    let _ = child.kill();
                    panic!("{what} {args:?}: still running after 10 s");
                }
                std::thread::sleep(Duration::from_millis(10));
            };
            assert_eq!(status.code(), Some(1), "{what} {args:?}");
        }
    }
    // A pipe on standard input says what to do instead of "Illegal seek".
    let o = poa()
        .arg("info")
        .arg("/dev/stdin")
        .stdin(Stdio::piped())
        .output()
        .unwrap();
    let e = refused(&o, "stdin pipe");
    assert!(e.contains("pipe") && e.contains("save the G-code"), "{e}");
}

#[test]
fn absurd_slicer_settings_are_refused_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let text = read(&sample("rect_overhang_prusa_rel.gcode"));
    let mut bad = text.clone();
    bad.extend_from_slice(b"; external_perimeter_extrusion_width = 1e13\n");
    let file_case = dir.path().join("width.gcode");
    std::fs::write(&file_case, &bad).unwrap();
    let f = dir.path().join("env.gcode");
    std::fs::write(&f, &text).unwrap();
    type Case<'a> = (&'a Path, &'a [(&'a str, &'a str)], &'a str);
    let cases: [Case; 4] = [
        (&file_case, &[], "external_perimeter_extrusion_width"),
        (
            &f,
            &[("SLIC3R_EXTERNAL_PERIMETER_EXTRUSION_WIDTH", "1e300%")],
            "SLIC3R_EXTERNAL_PERIMETER_EXTRUSION_WIDTH",
        ),
        (
            &f,
            &[("SLIC3R_RETRACT_LENGTH", "1e300")],
            "SLIC3R_RETRACT_LENGTH",
        ),
        (
            &f,
            &[("SLIC3R_TRAVEL_SPEED_Z", "1e-9")],
            "SLIC3R_TRAVEL_SPEED_Z",
        ),
    ];
    for (path, envs, name) in cases {
        let before = std::fs::read(path).unwrap();
        let t = Instant::now();
        let (o, peak) = peak_kib(&[&path], envs);
        let e = refused(&o, name);
        assert!(e.contains(name), "{name}: {e}");
        assert!(t.elapsed() < Duration::from_secs(10));
        assert!(peak.is_none_or(|p| p < MAX_KIB), "{peak:?} KiB");
        assert_eq!(std::fs::read(path).unwrap(), before);
    }
    assert!(temps(dir.path()).is_empty());
}

#[test]
fn a_gigabyte_line_or_nul_padding_is_refused_in_bounded_memory() {
    let dir = tempfile::tempdir().unwrap();
    let text = read(&sample("rect_overhang_prusa_rel.gcode"));
    // 1 GiB of NUL after the G-code (a sparse file: no disk is used).
    let padded = dir.path().join("padded.gcode");
    std::fs::write(&padded, &text).unwrap();
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&padded)
        .unwrap();
    file.set_len(text.len() as u64 + (1 << 30)).unwrap();
    drop(file);
    // A 40 MB comment line in the middle of the layers.
    let at = String::from_utf8_lossy(&text)
        .find(";LAYER_CHANGE")
        .unwrap();
    let mut long = text[..at].to_vec();
    long.extend_from_slice(b"; ");
    long.extend(std::iter::repeat_n(b'x', 40 << 20));
    long.push(b'\n');
    long.extend_from_slice(&text[at..]);
    let long_file = dir.path().join("long.gcode");
    std::fs::write(&long_file, &long).unwrap();
    for p in [&padded, &long_file] {
        for args in [vec![], vec!["analyze"]] {
            let mut a: Vec<&dyn AsRef<std::ffi::OsStr>> = args.iter().map(|s| s as _).collect();
            a.push(p);
            let t = Instant::now();
            let (o, peak) = peak_kib(&a, &[]);
            let e = refused(&o, "long line");
            assert!(e.contains("longer than"), "{e}");
            assert!(t.elapsed() < Duration::from_secs(10));
            assert!(peak.is_none_or(|p| p < MAX_KIB), "{peak:?} KiB");
        }
    }
    assert_eq!(std::fs::read(&long_file).unwrap(), long);
    assert!(temps(dir.path()).is_empty());
}

#[test]
fn a_file_of_one_move_layers_each_over_air_stops_within_seconds() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("layers.gcode");
    let mut s = String::from("; generated by PrusaSlicer 2.5.0\nM83\nG90\n");
    for i in 0..200_000 {
        let z = 0.2 * (i + 1) as f64;
        let x = if i % 2 == 0 { 0 } else { 3 };
        s.push_str(&format!(
            ";LAYER_CHANGE\n;Z:{z:.1}\nG1 Z{z:.1}\nG1 X{x} Y0\nG1 X{} Y0 E0.2\nG1 X{} Y5 E0.2\nG1 X{x} Y5 E0.2\nG1 X{x} Y0 E0.2\n",
            x + 5,
            x + 5
        ));
    }
    std::fs::write(&f, &s).unwrap();
    for args in [vec![], vec!["analyze"]] {
        let mut a: Vec<&dyn AsRef<std::ffi::OsStr>> = args.iter().map(|s| s as _).collect();
        a.push(&f);
        let t = Instant::now();
        let (o, peak) = peak_kib(&a, &[]);
        let e = refused(&o, "dense regions");
        assert!(e.contains("not a sliced part"), "{e}");
        assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
        assert!(peak.is_none_or(|p| p < MAX_KIB), "{peak:?} KiB");
    }
    assert_eq!(std::fs::read_to_string(&f).unwrap(), s);
}

// ---------------------------------------------------------------------------------------------
// Robustness

/// A second run must not delete a live run's temporary file; a dead run's file goes, even when
/// the file it was for is already processed.
#[test]
fn temporary_files_of_live_runs_are_kept_and_of_dead_runs_removed() {
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in.gcode");
    assert!(run(&[&f]).status.success());
    let mut gone = Command::new("true").spawn().unwrap();
    let dead = gone.id();
    gone.wait().unwrap();
    let live = std::process::id();
    let dead_tmp = dir.path().join(format!(".in.gcode.poa-tmp-{dead}-00ff"));
    let live_tmp = dir.path().join(format!(".in.gcode.poa-tmp-{live}-00aa"));
    let old_style = dir.path().join(format!(".in.gcode.poa-tmp-{dead}.2"));
    for t in [&dead_tmp, &live_tmp, &old_style] {
        std::fs::write(t, b"partial").unwrap();
    }
    let o = run(&[&f]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(
        !dead_tmp.exists() && !old_style.exists(),
        "dead runs' files removed"
    );
    assert!(live_tmp.exists(), "a live run's file kept");
}

/// Killed at any moment, rename window included: the file is the original or the complete
/// rewrite, never anything else, and the next run leaves no temporary file.
#[test]
fn killed_at_any_moment_the_file_is_the_original_or_the_rewrite() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("p.gcode");
    let mut data = read(&sample("rect_overhang_prusa_rel.gcode"));
    let once = data.clone();
    for _ in 0..3 {
        data.extend_from_slice(&once);
    }
    std::fs::write(&f, &data).unwrap();
    assert!(run(&[&f]).status.success());
    let rewritten = std::fs::read(&f).unwrap();
    let mut seen = [0usize; 2];
    for step in 0..40u64 {
        std::fs::write(&f, &data).unwrap();
        let mut child = poa().arg(&f).spawn().unwrap();
        std::thread::sleep(Duration::from_micros(step * step * 150));
        let _ = child.kill();
        let _ = child.wait();
        let now = std::fs::read(&f).unwrap();
        if now == data {
            seen[0] += 1;
        } else {
            assert!(
                now == rewritten,
                "step {step}: neither original nor rewrite"
            );
            seen[1] += 1;
        }
    }
    eprintln!(
        "kills: {} left the original, {} the rewrite",
        seen[0], seen[1]
    );
    assert!(run(&[&f]).status.success());
    assert!(temps(dir.path()).is_empty(), "{:?}", temps(dir.path()));
}

#[test]
fn a_header_pushed_down_by_prepended_lines_still_counts() {
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in.gcode");
    assert!(run(&[&f]).status.success());
    let mut text = "; a line a tool added\n".repeat(70).into_bytes();
    text.extend_from_slice(&std::fs::read(&f).unwrap());
    // Far past the head, too.
    let mut far = "; padding padding padding padding padding\n"
        .repeat(3000)
        .into_bytes();
    far.extend_from_slice(&text);
    for (name, data) in [("near.gcode", text), ("far.gcode", far)] {
        let p = dir.path().join(name);
        std::fs::write(&p, &data).unwrap();
        let o = run(&[&p]);
        assert!(o.status.success(), "{}", err(&o));
        assert_eq!(std::fs::read(&p).unwrap(), data, "{name}: processed twice");
    }
}

#[test]
fn long_file_names_work() {
    let dir = tempfile::tempdir().unwrap();
    let name = format!("{}.gcode", "n".repeat(248));
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", &name);
    let o = run(&[&f]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(String::from_utf8_lossy(&std::fs::read(&f).unwrap()).contains(";POA_BEGIN"));
    assert!(temps(dir.path()).is_empty());
}

#[test]
fn binary_output_under_a_text_name_is_said_and_regions_need_a_folder() {
    let dir = tempfile::tempdir().unwrap();
    let text = read(&sample("rect_overhang_prusa_rel.gcode"));
    let file =
        printonair::bgcode::from_ascii(&text, &printonair::bgcode::BinarizeConfig::prusaslicer())
            .unwrap();
    let bin = dir.path().join("in.bgcode");
    std::fs::write(&bin, printonair::bgcode::encode(&file)).unwrap();
    let out = dir.path().join("x.gcode");
    let o = run(&[&"process", &bin, &"-o", &out]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(err(&o).contains("binary G-code"), "{}", err(&o));

    let svg = dir.path().join("r.svg");
    let e = refused(
        &run(&[
            &"preview",
            &sample("rect_overhang_prusa_rel.gcode"),
            &"--regions",
            &"-o",
            &svg,
        ]),
        "regions into r.svg",
    );
    assert!(e.contains("folder"), "{e}");
    assert!(!svg.exists());
}

// ---------------------------------------------------------------------------------------------
// Messages

#[test]
fn messages_say_each_cause_once_and_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.gcode");
    let e = refused(&run(&[&"info", &missing]), "missing");
    assert_eq!(e.matches("No such file").count(), 1, "{e}");

    // A typo in a command name.
    let e = refused(&run(&[&"anlyze", &"x.gcode"]), "typo");
    assert!(e.contains("did you mean `poa analyze`"), "{e}");
    // clap's own errors keep the prefix and fit in two lines.
    refused(&run(&[&"process"]), "no input");
    refused(&run(&[&"--no-such-flag", &"x.gcode"]), "unknown flag");
    refused(&run(&[&"check", &"--overlap-min"]), "missing value");

    // --objects that matches nothing names the file's objects; the file is left alone.
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in.gcode");
    let before = std::fs::read(&f).unwrap();
    let e = refused(&run(&[&"--objects", &"nope*", &f]), "objects");
    assert!(
        e.contains("nope*") && e.contains("rect_overhang.stl"),
        "{e}"
    );
    assert_eq!(std::fs::read(&f).unwrap(), before);

    // --fail-in-air says why it failed.
    let o = run(&[&"check", &f, &"--fail-in-air", &"0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(err(&o).contains("in air"), "{}", err(&o));
}

/// `--dwell` pauses are time the print takes: in the report, the footer and the progress lines.
#[test]
fn dwell_pauses_are_counted_in_the_time() {
    let dir = tempfile::tempdir().unwrap();
    let f = sample("rect_overhang_prusa_rel.gcode");
    let time = |dwell: &str| -> (f64, u64) {
        let r = dir.path().join(format!("r{dwell}.json"));
        let o = run(&[
            &"process",
            &f,
            &"--dry-run",
            &"--dwell",
            &dwell,
            &"--report",
            &r,
        ]);
        assert!(o.status.success(), "{}", err(&o));
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&r).unwrap()).unwrap();
        let rep = &v["files"][0]["report"];
        (
            rep["time_added_s"].as_f64().unwrap(),
            rep["loops"].as_u64().unwrap(),
        )
    };
    let (t0, loops) = time("0");
    let (t2, _) = time("2");
    let pauses = 2.0 * (loops - 1) as f64;
    assert!(
        (t2 - t0 - pauses).abs() < 1.0,
        "{t0} s -> {t2} s with {loops} loops"
    );
    // The footer of the rewritten file says the same.
    let out = dir.path().join("o.gcode");
    assert!(run(&[&"process", &f, &"-o", &out, &"--dwell", &"2"])
        .status
        .success());
    let text = String::from_utf8(std::fs::read(&out).unwrap()).unwrap();
    let stated = |t: &str| -> f64 {
        let line = t
            .lines()
            .find(|l| l.starts_with("; estimated printing time (normal mode)"))
            .unwrap();
        printonair::estimate::parse_dhms(line.split('=').nth(1).unwrap().trim()).unwrap()
    };
    let original = stated(&String::from_utf8(read(&f)).unwrap());
    assert!((stated(&text) - original - t2).abs() < 2.0);
}

/// On a terminal, slicer mode prints its one summary line (slicers capture stdout).
#[test]
fn slicer_mode_prints_a_summary_on_a_terminal() {
    if Command::new("script").arg("--version").output().is_err() {
        note("slicer_mode_prints_a_summary_on_a_terminal skipped: no `script`");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let f = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in.gcode");
    let o = Command::new("script")
        .arg("-qec")
        .arg(format!("{} {}", env!("CARGO_BIN_EXE_poa"), f.display()))
        .arg("/dev/null")
        .output()
        .unwrap();
    assert!(o.status.success());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("1 region found, 1 rewritten"), "{out}");
    // Without a terminal (as a slicer runs it): nothing on stdout.
    let f2 = copy_sample(dir.path(), "rect_overhang_prusa_rel.gcode", "in2.gcode");
    let o = run(&[&f2]);
    assert!(o.status.success() && o.stdout.is_empty());
}

/// Statistics a file states out of any range (a damaged footer) are left as they are, not
/// added to: no `inf`, no 300-digit numbers, no day counts past the end of time.
#[test]
fn damaged_footer_statistics_are_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let text = String::from_utf8(read(&sample("rect_overhang_prusa_rel.gcode"))).unwrap();
    let bad: String = text
        .lines()
        .map(|l| {
            if l.starts_with("; estimated printing time (normal mode)") {
                "; estimated printing time (normal mode) = 999999999999999999999d 1h".to_string()
            } else if l.starts_with("; filament used [mm]") {
                "; filament used [mm] = 1e308".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n";
    let f = dir.path().join("in.gcode");
    std::fs::write(&f, &bad).unwrap();
    let o = run(&[&f]);
    assert!(o.status.success(), "{}", err(&o));
    let out = std::fs::read_to_string(&f).unwrap();
    assert!(out.contains("; filament used [mm] = 1e308\n"));
    assert!(out.contains("= 999999999999999999999d 1h\n"));
    assert!(!out.contains("= inf") && !out.contains("NaN"));
    assert!(out.contains(";POA_BEGIN"));
}
