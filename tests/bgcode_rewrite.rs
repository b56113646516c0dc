//! Binary G-code through slicer mode: decoded, rewritten, written back as binary G-code with
//! the same blocks, thumbnails and encodings, valid checksums and updated statistics.

mod common;

use std::process::Command;

use common::*;
use printonair::bgcode::{self, BlockKind};

/// A real PrusaSlicer 2.8 .bgcode (its metadata and thumbnails) carrying a specimen's G-code.
fn specimen_bgcode() -> Vec<u8> {
    let real = read(&shared().join("reference/bgcode-samples/mini_cube_ps2.8.1.bgcode"));
    let decoded = bgcode::decode(&real).unwrap();
    let text = read(&sample("rect_overhang_prusa_rel.gcode"));
    bgcode::encode(&bgcode::with_gcode(&decoded, &text))
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
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.gcode");
    let src = shared().join("reference/bgcode-samples/mini_cube_ps2.8.1.bgcode");
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .args(["convert", src.to_str().unwrap(), out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let want = read(&shared().join("reference/bgcode-samples/mini_cube_ps2.8.1_ref.gcode"));
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
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("part.bgcode");
    std::fs::write(&f, specimen_bgcode()).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_poa"))
        .arg(&f)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = dir.path().join("ref.gcode");
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
}

/// Text -> binary: `poa convert` writes the same bytes as libbgcode's own converter (through
/// pybgcode, with its default settings) for PrusaSlicer text of 2.5, 2.6 and 2.8.
#[test]
fn convert_to_binary_matches_the_reference_converter() {
    let dir = tempfile::tempdir().unwrap();
    let shared = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/reference/bgcode-samples");
    let inputs = [
        shared.join("mini_cube_b_ref.gcode"),
        shared.join("mini_cube_ps2.8.1_ref.gcode"),
        shared.join("mini_cube_ps2.8.1.gcode"),
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("sample-gcode/circ_overhang_prusa_rel.gcode"),
    ];
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
