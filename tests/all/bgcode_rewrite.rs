//! Binary G-code through slicer mode: decoded, rewritten, written back as binary G-code with
//! the same blocks, thumbnails and encodings, valid checksums and updated statistics.

use crate::common;

use std::process::Command;

use common::*;
use printonair::bgcode::{self, BlockKind};

/// A binary G-code fixture made here, as PrusaSlicer 2.7+ writes one (its converter's rules,
/// Heatshrink and MeatPack), from a shipped PrusaSlicer text sample, with a thumbnail block
/// added after the printer metadata as PrusaSlicer places them.
fn specimen_bgcode() -> Vec<u8> {
    let text = read(&sample("rect_overhang_prusa_rel.gcode"));
    let mut file =
        bgcode::from_ascii(&text, &bgcode::BinarizeConfig::prusaslicer()).expect("converts");
    let at = file
        .blocks
        .iter()
        .position(|b| b.kind == BlockKind::PrinterMetadata)
        .map_or(0, |i| i + 1);
    // A 1 x 1 PNG (signature, IHDR, IDAT, IEND): its bytes must pass through untouched.
    let png: Vec<u8> = [
        &b"\x89PNG\r\n\x1a\n"[..],
        b"\0\0\0\rIHDR\0\0\0\x01\0\0\0\x01\x08\x06\0\0\0\x1f\x15\xc4\x89",
        b"\0\0\0\rIDATx\x9cc\xf8\x0f\x00\x00\x01\x01\x00\x05\x18\xd8N",
        b"\0\0\0\0IEND\xaeB`\x82",
    ]
    .concat();
    file.blocks.insert(
        at,
        bgcode::Block::new(
            BlockKind::Thumbnail,
            bgcode::Compression::None,
            bgcode::BlockParams::Thumbnail {
                format: bgcode::ThumbnailFormat::Png,
                width: 1,
                height: 1,
            },
            png,
        ),
    );
    bgcode::encode(&file)
}

/// The same text made binary by libbgcode itself (its Python wrapper, default settings).
fn libbgcode_fixture(dir: &std::path::Path) -> std::path::PathBuf {
    let out = dir.join("libbgcode.bgcode");
    let script = "import pybgcode, sys\n\
        i = pybgcode.open(sys.argv[1], 'r'); o = pybgcode.open(sys.argv[2], 'wb')\n\
        r = pybgcode.from_ascii_to_binary(i, o, pybgcode.get_config())\n\
        pybgcode.close(i); pybgcode.close(o)\n\
        print(pybgcode.translate_result(r))\n";
    let o = Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(sample("rect_overhang_prusa_rel.gcode"))
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(String::from_utf8_lossy(&o.stdout).trim(), "Success");
    out
}

#[test]
fn slicer_mode_rewrites_binary_gcode_in_place() {
    let dir = tempfile::tempdir().unwrap();
    // PrusaSlicer hands scripts a temporary name that does not end in .gcode.
    let f = dir.path().join("export.gcode.pp");
    let input = specimen_bgcode();
    std::fs::write(&f, &input).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .arg(&f)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let out = std::fs::read(&f).unwrap();
    assert!(bgcode::is_bgcode(&out), "still binary");
    let before = bgcode::decode(&input).unwrap();
    let after = bgcode::decode(&out).expect("valid blocks and checksums");
    // Same block structure around the G-code; thumbnails and printer metadata untouched.
    let kinds = |b: &bgcode::Bgcode| -> Vec<BlockKind> {
        b.blocks
            .iter()
            .filter(|x| x.kind != BlockKind::GCode)
            .map(|x| x.kind)
            .collect()
    };
    assert_eq!(kinds(&before), kinds(&after));
    for (a, b) in before.blocks.iter().zip(&after.blocks) {
        if matches!(a.kind, BlockKind::Thumbnail | BlockKind::PrinterMetadata) {
            assert_eq!(a.payload, b.payload, "{:?} unchanged", a.kind);
        }
    }
    let gcode_blocks = |b: &bgcode::Bgcode| -> Vec<(bgcode::Compression, bgcode::BlockParams)> {
        b.blocks
            .iter()
            .filter(|x| x.kind == BlockKind::GCode)
            .map(|x| (x.compression, x.params))
            .take(1)
            .collect()
    };
    assert_eq!(
        gcode_blocks(&before),
        gcode_blocks(&after),
        "same compression and encoding"
    );
    // The G-code has poa's loops and reads back with the same layers.
    let text = after.gcode_text();
    assert_eq!(
        String::from_utf8_lossy(&text).matches(";POA_BEGIN").count(),
        1
    );
    let (layers, _) = read_layers(&text, false);
    assert_eq!(layer_count(&layers), 100);
    // A second run changes nothing.
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .arg(&f)
        .output()
        .unwrap();
    assert!(o.status.success());
    assert_eq!(std::fs::read(&f).unwrap(), out);
}

#[test]
fn damaged_binary_gcode_is_refused_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("bad.bgcode");
    let mut data = specimen_bgcode();
    let n = data.len();
    data[n / 2] ^= 0x55;
    std::fs::write(&f, &data).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .arg(&f)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("damaged") && err.trim().lines().count() <= 2,
        "{err}"
    );
    assert_eq!(std::fs::read(&f).unwrap(), data);
}

#[test]
fn convert_binary_to_text_matches_the_reference() {
    let Some(shared) = shared("convert_binary_to_text_matches_the_reference") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.gcode");
    let src = shared.join("reference/bgcode-samples/mini_cube_ps2.8.1.bgcode");
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .args(["convert", src.to_str().unwrap(), out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let want = read(&shared.join("reference/bgcode-samples/mini_cube_ps2.8.1_ref.gcode"));
    assert!(std::fs::read(&out).unwrap() == want);
    // info and analyze read binary files too.
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .args(["info", "--json", src.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["slicer"], "PrusaSlicer");
    assert!(v["layers"].as_u64().unwrap() > 10);
}

/// libbgcode itself (through its Python wrapper, `pip install pybgcode-jneilliii`) reads what
/// poa wrote, checksums verified, and sees the same text poa meant.
#[test]
fn the_reference_library_reads_what_poa_writes() {
    if !have_pybgcode() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let made = libbgcode_fixture(dir.path());
    for (i, fixture) in [specimen_bgcode(), std::fs::read(&made).unwrap()]
        .into_iter()
        .enumerate()
    {
        reads_back(dir.path(), &format!("part{i}.bgcode"), &fixture);
    }
}

/// Slicer mode on a binary fixture, then libbgcode converts the result to text: it must
/// succeed (checksums and blocks valid) and give the text poa meant.
fn reads_back(dir: &std::path::Path, name: &str, fixture: &[u8]) {
    let f = dir.join(name);
    std::fs::write(&f, fixture).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .arg(&f)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = dir.join("ref.gcode");
    let script = "import pybgcode, sys\n\
        i = pybgcode.open(sys.argv[1], 'rb'); o = pybgcode.open(sys.argv[2], 'w')\n\
        r = pybgcode.from_binary_to_ascii(i, o, True)\n\
        pybgcode.close(i); pybgcode.close(o)\n\
        print(pybgcode.translate_result(r))\n";
    let o = Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(&f)
        .arg(&text)
        .output()
        .expect("python3");
    assert!(
        o.status.success(),
        "pybgcode is needed (pip install pybgcode-jneilliii): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(String::from_utf8_lossy(&o.stdout).trim(), "Success");
    let ours = bgcode::decode(&std::fs::read(&f).unwrap())
        .unwrap()
        .to_ascii();
    assert!(
        std::fs::read(&text).unwrap() == ours,
        "libbgcode and poa disagree on the text"
    );
    assert!(String::from_utf8_lossy(&ours).contains(";POA_BEGIN"));
}

/// Text -> binary: `poa convert` writes the same bytes as libbgcode's own converter (through
/// pybgcode, with its default settings) for PrusaSlicer text of 2.5, 2.6 and 2.8.
#[test]
fn convert_to_binary_matches_the_reference_converter() {
    if !have_pybgcode() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut inputs = vec![
        sample("circ_overhang_prusa_rel.gcode"),
        sample("bridge_prusa_abs.gcode"),
    ];
    if let Some(shared) =
        shared("convert_to_binary_matches_the_reference_converter (libbgcode's samples)")
    {
        let dir = shared.join("reference/bgcode-samples");
        for name in [
            "mini_cube_b_ref.gcode",
            "mini_cube_ps2.8.1_ref.gcode",
            "mini_cube_ps2.8.1.gcode",
        ] {
            inputs.push(dir.join(name));
        }
    }
    let script = "import pybgcode, sys\n\
        i = pybgcode.open(sys.argv[1], 'r'); o = pybgcode.open(sys.argv[2], 'wb')\n\
        r = pybgcode.from_ascii_to_binary(i, o, pybgcode.get_config())\n\
        pybgcode.close(i); pybgcode.close(o)\n\
        print(pybgcode.translate_result(r))\n";
    for input in inputs {
        let theirs = dir.path().join("theirs.bgcode");
        let o = Command::new("python3")
            .arg("-c")
            .arg(script)
            .arg(&input)
            .arg(&theirs)
            .output()
            .expect("python3");
        assert!(
            o.status.success(),
            "pybgcode: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(String::from_utf8_lossy(&o.stdout).trim(), "Success");
        let ours = dir.path().join("ours.bgcode");
        let o = Command::new(env!("CARGO_BIN_EXE_poa"))
            .args(["convert", "--preset", "libbgcode"])
            .arg(&input)
            .arg(&ours)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(
            std::fs::read(&ours).unwrap() == std::fs::read(&theirs).unwrap(),
            "{}: poa and libbgcode write different binaries",
            input.display()
        );
        // And back: the binary converts to the text libbgcode makes of it.
        let text = dir.path().join("back.gcode");
        let o = Command::new(env!("CARGO_BIN_EXE_poa"))
            .arg("convert")
            .arg(&ours)
            .arg(&text)
            .output()
            .unwrap();
        assert!(o.status.success());
        let decoded = bgcode::decode(&std::fs::read(&theirs).unwrap()).unwrap();
        assert!(std::fs::read(&text).unwrap() == decoded.to_ascii());
    }
}

/// Text that is not PrusaSlicer's cannot become binary G-code (the format needs its metadata);
/// the refusal says so and writes nothing.
#[test]
fn convert_refuses_text_without_prusaslicer_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.bgcode");
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .arg("convert")
        .arg(
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("sample-gcode/rect_overhang_cura.gcode"),
        )
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("PrusaSlicer"));
    assert!(!out.exists());
}

/// A line longer than the reader takes (1 MiB) is refused by `convert` as by every other
/// command: the binary file it made was one poa then refused to read back.
#[test]
fn convert_refuses_a_line_longer_than_the_reader_takes() {
    let dir = tempfile::tempdir().unwrap();
    let sample = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("sample-gcode/rect_overhang_prusa_rel.gcode");
    let text = std::fs::read_to_string(sample).unwrap();
    let f = dir.path().join("long.gcode");
    std::fs::write(&f, format!("{text}; {}\n", "x".repeat(2 << 20))).unwrap();
    let out = dir.path().join("out.bgcode");
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .arg("convert")
        .arg(&f)
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("longer than 1 MiB"), "{err}");
    assert!(!out.exists());
}

/// `poa convert` streams both ways: 150 MB of PrusaSlicer text becomes binary G-code and back
/// with the converter's peak memory under 100 MB (it read the whole file and built the whole
/// output: 924 MB for 260 MB of text), and the text it writes back converts to the same
/// binary. About 10 s in release; skipped in debug builds, where it takes minutes.
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "150 MB through poa convert: run in release"
)]
fn convert_runs_in_bounded_memory_both_ways() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("big.gcode");
    let mut w = std::io::BufWriter::new(std::fs::File::create(&text).unwrap());
    w.write_all(
        b"; generated by PrusaSlicer 2.7.0 on 2024-01-02 at 10:11:12 UTC\n\n\
          ; external perimeters extrusion width = 0.45mm\n\nM73 P0 R60\nG90\nM83\n",
    )
    .unwrap();
    // One layer of about 1 MB, repeated at rising heights.
    let mut layer = String::from(";TYPE:Perimeter\n;WIDTH:0.45\nG1 F1800\n");
    for i in 0..32_000 {
        layer.push_str(&format!(
            "G1 X{:.3} Y{:.3} E0.0{:04}\n",
            100.0 + (i % 97) as f64 * 0.5,
            80.0 + (i % 89) as f64 * 0.5,
            i % 9999
        ));
    }
    let mut written = 0;
    let mut z = 0;
    while written < 150 << 20 {
        z += 1;
        let head = format!(
            ";LAYER_CHANGE\n;Z:{:.2}\n;HEIGHT:0.2\nG1 Z{:.2} F720\n",
            z as f64 * 0.2,
            z as f64 * 0.2
        );
        w.write_all(head.as_bytes()).unwrap();
        w.write_all(layer.as_bytes()).unwrap();
        written += head.len() + layer.len();
    }
    w.write_all(
        b"M107\n; filament used [mm] = 123456.78\n; filament used [g] = 370.25\n\
          ; estimated printing time (normal mode) = 20h 1m 2s\n\n\
          ; prusaslicer_config = begin\n; layer_height = 0.2\n; nozzle_diameter = 0.4\n\
          ; printer_model = MK4\n; temperature = 215\n; prusaslicer_config = end\n",
    )
    .unwrap();
    drop(w);

    let (binary, back, again) = (
        dir.path().join("big.bgcode"),
        dir.path().join("back.gcode"),
        dir.path().join("again.bgcode"),
    );
    for (from, to) in [(&text, &binary), (&binary, &back), (&back, &again)] {
        let (o, peak) = peak_kib(&[&"convert", from, to], &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let Some(peak) = peak else { continue };
        eprintln!(
            "poa convert {} ({} MB): peak {peak} KB",
            from.file_name().unwrap().to_string_lossy(),
            std::fs::metadata(from).unwrap().len() >> 20
        );
        assert!(peak < 100_000, "{}: peak {peak} KB", from.display());
    }
    assert!(std::fs::metadata(&back).unwrap().len() > 150 << 20);
    assert!(std::fs::read(&binary).unwrap() == std::fs::read(&again).unwrap());
}
