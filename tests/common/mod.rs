//! Shared helpers for the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use printonair::layers::{Layer, LayerKind, LayerReader, ReaderOptions, SlicerConfig};

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn samples() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join("sample-gcode"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "gcode"))
        .collect();
    v.sort();
    assert!(v.len() >= 10, "sample-gcode/ should hold the samples");
    v
}

pub fn sample(name: &str) -> PathBuf {
    repo().join("sample-gcode").join(name)
}

/// Reads a file the way the CLI does (config from the file itself, no environment).
pub fn read_layers(data: &[u8], keep_raw: bool) -> (Vec<Layer>, LayerReader<&[u8]>) {
    let config = SlicerConfig::parse(data);
    let mut r = LayerReader::new(data, ReaderOptions { keep_raw, config });
    let layers = r.by_ref().map(|l| l.unwrap()).collect();
    (layers, r)
}

pub fn layer_count(layers: &[Layer]) -> usize {
    layers.iter().filter(|l| l.kind == LayerKind::Layer).count()
}

/// Removes every comment and the blank lines that leaves: the retrofit case.
pub fn strip_comments(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len());
    for line in data.split(|&b| b == b'\n') {
        let code = match line.iter().position(|&b| b == b';') {
            Some(i) => &line[..i],
            None => line,
        };
        let code = code.strip_suffix(b"\r").unwrap_or(code);
        let trimmed = code.trim_ascii_end();
        if !trimmed.is_empty() {
            out.extend_from_slice(trimmed);
            out.push(b'\n');
        }
    }
    out
}

pub fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The shared reference folder beside the checkout.
pub fn shared() -> PathBuf {
    let p = repo().join("..").join("shared");
    assert!(
        p.is_dir(),
        "tests need ../shared beside the checkout ({})",
        p.display()
    );
    p
}

/// Slices a specimen with PrusaSlicer's CLI and the samples' config plus `args`.
pub fn slice(specimen: &str, args: &[&str]) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.gcode");
    let stl = shared().join("specimens").join(format!("{specimen}.stl"));
    let config = repo().join("sample-gcode/config/prusaslicer-mk3s-pla.ini");
    let status = std::process::Command::new("prusa-slicer")
        .arg("--load")
        .arg(&config)
        .args(args)
        .arg("--export-gcode")
        .arg("-o")
        .arg(&out)
        .arg(&stl)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .expect("prusa-slicer must be installed for this test (apt-get install -y prusa-slicer)");
    assert!(
        status.success(),
        "prusa-slicer failed on {specimen} {args:?}"
    );
    read(&out)
}
