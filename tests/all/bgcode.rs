//! Binary G-code: decoding to libbgcode's reference text, byte-exact round trips, errors on
//! corrupt input, and every compression x encoding pair on a small synthetic file.
//! Samples come from prusa3d/libbgcode's test data in ../shared/reference/bgcode-samples/ (third
//! party, not in this repository): the tests that read them skip with a note when it is absent.
//! The synthetic files and the fixtures poa makes (tests/all/bgcode_rewrite.rs) need nothing.

use printonair::bgcode::{
    decode, encode, is_bgcode, with_gcode, Bgcode, BgcodeError, Block, BlockKind, BlockParams,
    ChecksumType, Compression, GcodeEncoding, MetadataEncoding, ThumbnailFormat,
    MAX_GCODE_BLOCK_TEXT,
};
use proptest::prelude::*;
use std::path::PathBuf;

const SAMPLES: [&str; 2] = ["mini_cube_b", "mini_cube_ps2.8.1"];

fn sample_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/reference/bgcode-samples")
}

/// Whether libbgcode's samples are there; prints which test skips when not.
fn have_samples(test: &str) -> bool {
    crate::common::shared(test).is_some() && sample_dir().is_dir()
}

fn read(name: &str) -> Vec<u8> {
    let path = sample_dir().join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

fn first_difference(a: &[u8], b: &[u8]) -> String {
    let at = a
        .iter()
        .zip(b)
        .position(|(x, y)| x != y)
        .unwrap_or(a.len().min(b.len()));
    let line = a[..at].iter().filter(|&&c| c == b'\n').count() + 1;
    let ctx = |s: &[u8]| {
        String::from_utf8_lossy(&s[at.saturating_sub(60)..(at + 60).min(s.len())]).into_owned()
    };
    format!(
        "lengths {} vs {}, first difference at byte {at} (line {line}):\n{:?}\nvs\n{:?}",
        a.len(),
        b.len(),
        ctx(a),
        ctx(b)
    )
}

#[test]
fn decodes_to_the_reference_text() {
    if !have_samples("decodes_to_the_reference_text") {
        return;
    }
    for name in SAMPLES {
        let b = decode(&read(&format!("{name}.bgcode"))).expect(name);
        let ascii = b.to_ascii();
        let reference = read(&format!("{name}_ref.gcode"));
        assert!(
            ascii == reference,
            "{name}: {}",
            first_difference(&ascii, &reference)
        );
    }
}

#[test]
fn samples_are_recognised() {
    if !have_samples("samples_are_recognised") {
        return;
    }
    for name in SAMPLES {
        assert!(is_bgcode(&read(&format!("{name}.bgcode"))));
        assert!(!is_bgcode(&read(&format!("{name}_ref.gcode"))));
    }
}

#[test]
fn encode_round_trips_byte_for_byte() {
    if !have_samples("encode_round_trips_byte_for_byte") {
        return;
    }
    for name in SAMPLES {
        let original = read(&format!("{name}.bgcode"));
        let b = decode(&original).unwrap();
        assert!(encode(&b) == original, "{name}");
    }
}

/// Heatshrink and MeatPack are re-implemented to match libbgcode's output, so G-code blocks
/// encoded afresh (not copied from the file) equal PrusaSlicer's bytes. Only for
/// mini_cube_b: in mini_cube_ps2.8.1, 16 start G-code lines had inline comments, which MeatPack
/// drops but which change its bytes (one newline instead of two); the decoded text cannot know.
#[test]
fn fresh_gcode_blocks_equal_prusaslicers_bytes() {
    if !have_samples("fresh_gcode_blocks_equal_prusaslicers_bytes") {
        return;
    }
    let original = read("mini_cube_b.bgcode");
    let mut b = decode(&original).unwrap();
    for block in &mut b.blocks {
        if block.compression != Compression::Deflate {
            block.forget_stored();
        }
    }
    let fresh = encode(&b);
    assert!(fresh == original, "{}", first_difference(&fresh, &original));
}

/// Deflate goes through miniz_oxide, not zlib: other bytes, same content.
#[test]
fn fresh_deflate_blocks_decode_to_the_same_content() {
    if !have_samples("fresh_deflate_blocks_decode_to_the_same_content") {
        return;
    }
    for name in SAMPLES {
        let mut b = decode(&read(&format!("{name}.bgcode"))).unwrap();
        b.blocks.iter_mut().for_each(Block::forget_stored);
        let again = decode(&encode(&b)).unwrap();
        assert_eq!(again.to_ascii(), b.to_ascii(), "{name}");
        for (x, y) in again.blocks.iter().zip(&b.blocks) {
            assert_eq!(
                (x.kind, x.compression, x.params),
                (y.kind, y.compression, y.params)
            );
            assert_eq!(x.payload, y.payload);
        }
    }
}

#[test]
fn with_gcode_of_the_same_text_gives_the_same_file() {
    if !have_samples("with_gcode_of_the_same_text_gives_the_same_file") {
        return;
    }
    for name in SAMPLES {
        let original = read(&format!("{name}.bgcode"));
        let b = decode(&original).unwrap();
        let text: Vec<u8> = b
            .blocks
            .iter()
            .filter(|bl| bl.kind == BlockKind::GCode)
            .flat_map(|bl| bl.payload.iter().copied())
            .collect();
        let rebuilt = with_gcode(&b, &text);
        assert_eq!(
            rebuilt.blocks.len(),
            b.blocks.len(),
            "{name}: same block count"
        );
        let bytes = encode(&rebuilt);
        if name == "mini_cube_b" {
            assert!(
                bytes == original,
                "{name}: {}",
                first_difference(&bytes, &original)
            );
        } else {
            // See fresh_gcode_blocks_equal_prusaslicers_bytes for why not byte for byte.
            assert_eq!(decode(&bytes).unwrap().to_ascii(), b.to_ascii(), "{name}");
        }
    }
}

#[test]
fn with_gcode_splits_and_keeps_everything_else() {
    if !have_samples("with_gcode_splits_and_keeps_everything_else") {
        return;
    }
    let b = decode(&read("mini_cube_ps2.8.1.bgcode")).unwrap();
    let mut text = b.gcode_text();
    text.extend_from_slice(b"; poa was here\n");
    text.extend(std::iter::repeat_n(b"G1 X1.5 Y2.5 E0.1\n".iter().copied(), 10_000).flatten());
    let changed = with_gcode(&b, &text);
    let gcode_blocks: Vec<&Block> = changed
        .blocks
        .iter()
        .filter(|bl| bl.kind == BlockKind::GCode)
        .collect();
    assert!(gcode_blocks.len() >= 4);
    assert!(gcode_blocks
        .iter()
        .all(|bl| bl.payload.len() <= MAX_GCODE_BLOCK_TEXT));
    assert!(gcode_blocks
        .iter()
        .all(|bl| bl.compression == Compression::Heatshrink12_4
            && bl.params == BlockParams::GCode(GcodeEncoding::MeatPackComments)));
    let again = decode(&encode(&changed)).unwrap();
    assert_eq!(again.gcode_text(), text);
    let others = |x: &Bgcode| -> Vec<Vec<u8>> {
        x.blocks
            .iter()
            .filter(|bl| bl.kind != BlockKind::GCode)
            .map(|bl| bl.payload.clone())
            .collect()
    };
    assert_eq!(others(&again), others(&b));
}

fn corrupt(f: impl FnOnce(&mut Vec<u8>)) -> Result<Bgcode, BgcodeError> {
    let mut data = read("mini_cube_ps2.8.1.bgcode");
    f(&mut data);
    decode(&data)
}

#[test]
fn bad_magic_is_reported() {
    if !have_samples("bad_magic_is_reported") {
        return;
    }
    assert_eq!(corrupt(|d| d[0] = b'X').unwrap_err(), BgcodeError::BadMagic);
    assert_eq!(
        decode(b"; generated by PrusaSlicer\n").unwrap_err(),
        BgcodeError::BadMagic
    );
    assert_eq!(
        decode(b"").unwrap_err(),
        BgcodeError::TruncatedHeader { len: 0 }
    );
}

#[test]
fn unsupported_version_is_reported() {
    if !have_samples("unsupported_version_is_reported") {
        return;
    }
    assert_eq!(
        corrupt(|d| d[4] = 2).unwrap_err(),
        BgcodeError::UnsupportedVersion(2)
    );
}

#[test]
fn truncation_is_reported_with_its_block() {
    if !have_samples("truncation_is_reported_with_its_block") {
        return;
    }
    let full = read("mini_cube_ps2.8.1.bgcode");
    let err = decode(&full[..full.len() - 1]).unwrap_err();
    // The last block is the one G-code block, at offset 16727.
    assert!(
        matches!(
            err,
            BgcodeError::TruncatedBlock {
                block: 6,
                offset: 16727,
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("offset 16727"));
    let err = decode(&full[..13]).unwrap_err();
    assert!(
        matches!(
            err,
            BgcodeError::TruncatedBlock {
                block: 0,
                offset: 10,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn flipped_byte_is_a_crc_mismatch() {
    if !have_samples("flipped_byte_is_a_crc_mismatch") {
        return;
    }
    // A byte inside the print metadata block's compressed data (block 4 starts at 11823).
    let err = corrupt(|d| d[11823 + 30] ^= 0x10).unwrap_err();
    assert!(
        matches!(
            err,
            BgcodeError::CrcMismatch {
                block: 4,
                offset: 11823,
                ..
            }
        ),
        "{err}"
    );
    // A byte of a header field counts too.
    let err = corrupt(|d| d[10 + 4] ^= 1).unwrap_err();
    assert!(
        matches!(
            err,
            BgcodeError::CrcMismatch { block: 0, .. }
                | BgcodeError::TruncatedBlock { block: 0, .. }
        ),
        "{err}"
    );
}

#[test]
fn unknown_ids_are_reported() {
    if !have_samples("unknown_ids_are_reported") {
        return;
    }
    let err = corrupt(|d| d[10 + 2] = 7).unwrap_err();
    assert_eq!(
        err,
        BgcodeError::UnknownCompression {
            block: 0,
            offset: 10,
            id: 7
        }
    );
    let err = corrupt(|d| d[10] = 9).unwrap_err();
    assert_eq!(
        err,
        BgcodeError::UnknownBlockType {
            block: 0,
            offset: 10,
            kind: 9
        }
    );
    // The G-code block's encoding parameter sits right after its 12-byte header.
    let err = corrupt(|d| d[16727 + 12] = 5).unwrap_err();
    assert_eq!(
        err,
        BgcodeError::UnknownEncoding {
            block: 6,
            offset: 16727,
            kind: BlockKind::GCode,
            id: 5
        }
    );
}

fn synthetic(compression: Compression, encoding: GcodeEncoding, checksum: ChecksumType) -> Bgcode {
    let meta = |kind, text: &str| {
        Block::new(
            kind,
            compression,
            BlockParams::Metadata(MetadataEncoding::Ini),
            text.as_bytes().to_vec(),
        )
    };
    let gcode =
        "M73 P0 R3\n;LAYER_CHANGE\n;Z:0.2\nG1 Z.2 F720\nG1 X10.5 Y20.25 E.5\nM104 S215\nG4 S0\n";
    Bgcode {
        version: 1,
        checksum,
        blocks: vec![
            meta(BlockKind::FileMetadata, "Producer=poa test\n"),
            meta(
                BlockKind::PrinterMetadata,
                "printer_model=MK4S\nnozzle_diameter=0.4\n",
            ),
            Block::new(
                BlockKind::Thumbnail,
                compression,
                BlockParams::Thumbnail {
                    format: ThumbnailFormat::Png,
                    width: 2,
                    height: 2,
                },
                vec![0x89, b'P', b'N', b'G', 0, 0, 0, 0, 1, 2, 3],
            ),
            meta(
                BlockKind::PrintMetadata,
                "estimated printing time (normal mode)=3m\n",
            ),
            meta(BlockKind::SlicerMetadata, "layer_height=0.2\n"),
            Block::new(
                BlockKind::GCode,
                compression,
                BlockParams::GCode(encoding),
                gcode.as_bytes().to_vec(),
            ),
        ],
    }
}

#[test]
fn every_compression_and_encoding_round_trips() {
    for compression in Compression::ALL {
        for encoding in GcodeEncoding::ALL {
            for checksum in [ChecksumType::None, ChecksumType::Crc32] {
                let b = synthetic(compression, encoding, checksum);
                let bytes = encode(&b);
                let d =
                    decode(&bytes).unwrap_or_else(|e| panic!("{compression:?} {encoding:?}: {e}"));
                assert_eq!(d.checksum, checksum);
                let expected_gcode: &[u8] = match encoding {
                    GcodeEncoding::None => {
                        b"M73 P0 R3\n;LAYER_CHANGE\n;Z:0.2\nG1 Z.2 F720\nG1 X10.5 Y20.25 E.5\nM104 S215\nG4 S0\n"
                    }
                    // MeatPack drops the space before a letter it does not know (S of G4).
                    GcodeEncoding::MeatPackComments => {
                        b"M73 P0 R3\n;LAYER_CHANGE\n;Z:0.2\nG1 Z.2 F720\nG1 X10.5 Y20.25 E.5\nM104 S215\nG4S0\n"
                    }
                    GcodeEncoding::MeatPack => b"M73 P0 R3\nG1 Z.2 F720\nG1 X10.5 Y20.25 E.5\nM104 S215\nG4S0\n",
                };
                assert_eq!(
                    d.gcode_text(),
                    expected_gcode,
                    "{compression:?} {encoding:?}"
                );
                for (x, y) in d.blocks.iter().zip(&b.blocks) {
                    assert_eq!(
                        (x.kind, x.compression, x.params),
                        (y.kind, y.compression, y.params)
                    );
                    if x.kind != BlockKind::GCode {
                        assert_eq!(x.payload, y.payload);
                    }
                }
                // Decoded and written again, the file is the same bytes.
                assert!(encode(&d) == bytes, "{compression:?} {encoding:?}");
                let mut fresh = d.clone();
                fresh.blocks.iter_mut().for_each(Block::forget_stored);
                assert_eq!(decode(&encode(&fresh)).unwrap().to_ascii(), d.to_ascii());
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Any text either converts (and then decodes) or is refused; nothing panics.
    #[test]
    fn text_to_binary_never_panics(
        lines in proptest::collection::vec(
            proptest::sample::select(vec![
                "; generated by PrusaSlicer 2.8.1 on 2024", "; thumbnail begin 2x2 8", "; QUJD",
                "; thumbnail end", "; prusaslicer_config = begin", "; layer_height = 0.2",
                "; prusaslicer_config = end", "G1 X1 Y2 E3", ";", "", "; printer_model = MK4",
                "; filament used [mm] = 1.0", "M104 S200 ; heat", "\r", "\u{0}junk",
            ]),
            0..40,
        )
    ) {
        let text = lines.join("\n");
        let config = printonair::bgcode::BinarizeConfig::prusaslicer();
        if let Ok(file) = printonair::bgcode::from_ascii(text.as_bytes(), &config) {
            prop_assert!(decode(&encode(&file)).is_ok());
        }
    }


    #[test]
    fn random_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..2048), magic in any::<bool>()) {
        let mut data = data;
        if magic && data.len() >= 10 {
            data[..4].copy_from_slice(b"GCDE");
            data[4..8].copy_from_slice(&1u32.to_le_bytes());
            data[8] %= 2;
            data[9] = 0;
        }
        let _ = decode(&data);
    }

    #[test]
    fn mutated_samples_never_panic(
        which in 0usize..2,
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
        crc in any::<bool>(),
    ) {
        if !have_samples("mutated_samples_never_panic") {
            return Ok(());
        }
        let mut data = read(&format!("{}.bgcode", SAMPLES[which]));
        if crc {
            // Without checksums the damage reaches the decompressors and MeatPack.
            let mut b = decode(&data).unwrap();
            b.checksum = ChecksumType::None;
            data = encode(&b);
        }
        for (at, byte) in edits {
            let i = at.index(data.len());
            data[i] = byte;
        }
        if truncate {
            data.truncate(cut.index(data.len()));
        }
        let _ = decode(&data);
    }
}

/// Binary -> text -> binary: mini_cube_b (written by libbgcode's own converter) comes back
/// byte for byte. PrusaSlicer 2.8.1's file cannot: its text lost the inline comments MeatPack
/// dropped and the empty comment lines, and keeps its metadata in another order; everything
/// else (thumbnails, configuration, file metadata, the G-code text) comes back.
#[test]
fn text_converts_back_to_the_same_binary() {
    if !have_samples("text_converts_back_to_the_same_binary") {
        return;
    }
    use printonair::bgcode::{from_ascii, BinarizeConfig};
    let original = read("mini_cube_b.bgcode");
    let decoded = decode(&original).unwrap();
    let text = decoded.to_ascii();
    let again = from_ascii(&text, &BinarizeConfig::of(&decoded)).unwrap();
    let bytes = encode(&again);
    assert!(bytes == original, "{}", first_difference(&original, &bytes));

    let original = read("mini_cube_ps2.8.1.bgcode");
    let decoded = decode(&original).unwrap();
    let text = decoded.to_ascii();
    let again = decode(&encode(
        &from_ascii(&text, &BinarizeConfig::of(&decoded)).unwrap(),
    ))
    .unwrap();
    // The G-code text is the same but for one statistics comment the reference converter
    // reads into printer metadata (where the file states it already).
    let gcode = String::from_utf8(decoded.gcode_text()).unwrap();
    let expected = gcode.replacen("; max_layer_z = 6.2\n", "", 1);
    assert_ne!(expected, gcode);
    assert_eq!(String::from_utf8(again.gcode_text()).unwrap(), expected);
    for kind in [
        BlockKind::FileMetadata,
        BlockKind::Thumbnail,
        BlockKind::SlicerMetadata,
    ] {
        let a: Vec<_> = decoded
            .blocks
            .iter()
            .filter(|b| b.kind == kind)
            .map(|b| &b.payload)
            .collect();
        let b: Vec<_> = again
            .blocks
            .iter()
            .filter(|b| b.kind == kind)
            .map(|b| &b.payload)
            .collect();
        assert_eq!(a, b, "{kind:?}");
    }
    for kind in [BlockKind::PrinterMetadata, BlockKind::PrintMetadata] {
        let pairs = |f: &Bgcode| {
            let mut v: Vec<(Vec<u8>, Vec<u8>)> = f
                .blocks
                .iter()
                .filter(|b| b.kind == kind)
                .flat_map(|b| {
                    b.metadata()
                        .into_iter()
                        .map(|(k, v)| (k.to_vec(), v.to_vec()))
                })
                .collect();
            v.sort();
            v
        };
        assert_eq!(pairs(&decoded), pairs(&again), "{kind:?}");
    }
}

/// Text -> binary -> text -> binary is stable for every compression and encoding.
#[test]
fn text_to_binary_round_trips_for_every_combination() {
    if !have_samples("text_to_binary_round_trips_for_every_combination") {
        return;
    }
    use printonair::bgcode::{from_ascii, BinarizeConfig};
    let text = decode(&read("mini_cube_ps2.8.1.bgcode"))
        .unwrap()
        .to_ascii();
    for compression in Compression::ALL {
        for encoding in GcodeEncoding::ALL {
            let config = BinarizeConfig {
                file_metadata: compression,
                printer_metadata: compression,
                print_metadata: compression,
                slicer_metadata: compression,
                gcode: compression,
                gcode_encoding: encoding,
                checksum: ChecksumType::Crc32,
            };
            let first = encode(&from_ascii(&text, &config).unwrap());
            let back = decode(&first).unwrap();
            let second = encode(&from_ascii(&back.to_ascii(), &config).unwrap());
            assert!(
                first == second,
                "{compression:?} {encoding:?}: {}",
                first_difference(&first, &second)
            );
        }
    }
}
