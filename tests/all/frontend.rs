//! The G-code front end on real files: losslessness, filament totals, layer counts.

use crate::common;

use common::*;
use printonair::gcode::LineReader;
use printonair::layers::{LayerKind, LayerSource};

fn concat_lines(data: &[u8]) -> Vec<u8> {
    LineReader::new(data).flat_map(|l| l.unwrap().raw).collect()
}

fn concat_layers(data: &[u8]) -> Vec<u8> {
    let (layers, _) = read_layers(data, true);
    layers.into_iter().flat_map(|l| l.raw).collect()
}

#[test]
fn every_sample_round_trips_byte_for_byte() {
    for path in samples() {
        let data = read(&path);
        assert!(
            concat_lines(&data) == data,
            "{}: line reader",
            path.display()
        );
        assert!(
            concat_layers(&data) == data,
            "{}: layer reader",
            path.display()
        );
    }
}

#[test]
fn oddities_round_trip() {
    let long_line = format!("; {}\nG1 X1 E1\n", "x".repeat(100_000));
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("crlf", b"G1 X1\r\nG1 Y1 E1\r\n".to_vec()),
        ("mixed endings", b"G1 X1\r\nG1 Y1 E1\nG1 Z1\r\n".to_vec()),
        ("no final newline", b"G1 X1\nG1 Y1 E1".to_vec()),
        (
            "non-utf8 comment",
            b"G1 X1 ; \xff\xfe caf\xe9\nG1 Y2 E1\n".to_vec(),
        ),
        ("trailing blanks", b"G1 X1   \t\n  \n\n".to_vec()),
        ("long line", long_line.into_bytes()),
        ("lone cr", b"G1 X1\rG1 Y1\n".to_vec()),
        ("empty", Vec::new()),
    ];
    for (name, data) in cases {
        assert!(concat_lines(&data) == data, "{name}: line reader");
        assert!(concat_layers(&data) == data, "{name}: layer reader");
    }
}

#[test]
fn fifty_megabytes_round_trip_streaming() {
    // A plate of copies of a real layer-annotated file, checked while streaming so that the
    // test itself does not hold two copies.
    let one = read(&sample("rect_overhang_prusa_rel.gcode"));
    let copies = (50 * 1024 * 1024) / one.len() + 1;
    let mut data = Vec::with_capacity(one.len() * copies);
    for _ in 0..copies {
        data.extend_from_slice(&one);
    }
    assert!(data.len() >= 50 * 1024 * 1024);
    let mut offset = 0usize;
    let reader = printonair::layers::LayerReader::new(
        &data[..],
        printonair::layers::ReaderOptions {
            keep_raw: true,
            ..Default::default()
        },
    );
    for layer in reader {
        let layer = layer.unwrap();
        assert!(
            data[offset..offset + layer.raw.len()] == layer.raw[..],
            "mismatch at byte {offset}"
        );
        offset += layer.raw.len();
    }
    assert_eq!(offset, data.len());
}

/// The interpreter's filament on extrusion moves inside layers equals PrusaSlicer's footer.
/// The footer leaves out the start G-code's intro line (about 21.5 mm, printed before the
/// first `;LAYER_CHANGE`), which the layer model keeps in the preamble block.
#[test]
fn filament_matches_prusaslicer_footer_in_relative_and_absolute_e() {
    let mut checked = 0;
    for path in samples() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if !name.contains("_prusa_") {
            continue;
        }
        let data = read(&path);
        let (layers, reader) = read_layers(&data, false);
        let stated = reader.facts().stated_filament_mm.expect("footer");
        let in_layers: f64 = layers
            .iter()
            .filter(|l| l.kind == LayerKind::Layer)
            .flat_map(|l| &l.paths)
            .map(|p| p.e())
            .sum();
        let rel = (in_layers - stated).abs() / stated;
        assert!(rel < 0.005, "{name}: {in_layers} vs footer {stated}");
        let intro: f64 = layers
            .iter()
            .filter(|l| l.kind == LayerKind::Preamble)
            .flat_map(|l| &l.paths)
            .map(|p| p.e())
            .sum();
        assert!((intro - 21.5).abs() < 0.1, "{name}: intro line {intro}");
        checked += 1;
    }
    assert!(
        checked >= 8,
        "relative and absolute samples of four specimens"
    );
}

#[test]
fn layer_counts_equal_markers_and_survive_comment_stripping() {
    for path in samples() {
        let data = read(&path);
        let text = String::from_utf8_lossy(&data);
        let markers = text
            .lines()
            .filter(|l| {
                let t = l.trim();
                t == ";LAYER_CHANGE" || t == "; CHANGE_LAYER" || t.starts_with(";LAYER:")
            })
            .count();
        if markers == 0 {
            continue;
        }
        let name = path.display().to_string();
        let (layers, reader) = read_layers(&data, false);
        assert_eq!(reader.facts().layer_source, LayerSource::Markers, "{name}");
        assert_eq!(layer_count(&layers), markers, "{name}");

        let stripped = strip_comments(&data);
        let (inferred, reader) = read_layers(&stripped, false);
        assert_eq!(
            reader.facts().layer_source,
            LayerSource::InferredFromZ,
            "{name}"
        );
        assert_eq!(layer_count(&inferred), markers, "{name}: stripped");
        // Same Z sequence.
        let za: Vec<f64> = layers
            .iter()
            .filter(|l| l.kind == LayerKind::Layer)
            .map(|l| l.z)
            .collect();
        let zb: Vec<f64> = inferred
            .iter()
            .filter(|l| l.kind == LayerKind::Layer)
            .map(|l| l.z)
            .collect();
        for (a, b) in za.iter().zip(&zb) {
            assert!((a - b).abs() < 1e-4, "{name}: {a} vs {b}");
        }
    }
}

#[test]
fn slic3r_and_nocomment_samples_infer_layers() {
    for name in [
        "rect_overhang_slic3r.gcode",
        "rect_overhang_nocomments.gcode",
    ] {
        let data = read(&sample(name));
        let (layers, reader) = read_layers(&data, false);
        assert_eq!(
            reader.facts().layer_source,
            LayerSource::InferredFromZ,
            "{name}"
        );
        assert_eq!(layer_count(&layers), 100, "{name}");
    }
}

#[test]
fn slic3r_trailing_comments_give_roles() {
    use printonair::layers::Role;
    let data = read(&sample("rect_overhang_slic3r.gcode"));
    let (layers, _) = read_layers(&data, false);
    let roles: std::collections::BTreeSet<Role> = layers
        .iter()
        .flat_map(|l| &l.paths)
        .map(|p| p.role)
        .collect();
    assert!(roles.contains(&Role::Perimeter), "{roles:?}");
    assert!(roles.contains(&Role::Infill), "{roles:?}");
}

#[test]
fn widths_from_comments_and_from_e_agree_on_prusaslicer_output() {
    // PrusaSlicer's `;WIDTH:` and the flow-model width from E describe the same bead.
    let data = read(&sample("rect_overhang_prusa_rel.gcode"));
    let (layers, reader) = read_layers(&data, false);
    let area = reader.filament_area();
    let mut n = 0;
    for l in layers
        .iter()
        .filter(|l| l.kind == LayerKind::Layer && l.index > 0)
    {
        for p in &l.paths {
            if p.length() < 5.0 || p.role == printonair::layers::Role::BridgeInfill {
                continue;
            }
            let ew = p.e_width(area);
            assert!(
                (ew - p.width).abs() < 0.03,
                "line {}: {} vs {}",
                p.seg_line[0],
                ew,
                p.width
            );
            n += 1;
        }
    }
    assert!(n > 100);
}

#[test]
fn arcs_units_relative_and_firmware_retraction_samples() {
    // Hand-written samples state their own filament in a PrusaSlicer-style footer.
    for name in [
        "arcs.gcode",
        "inches_g20.gcode",
        "relative_g91.gcode",
        "firmware_retraction.gcode",
        "crlf.gcode",
        "klipper_objects.gcode",
    ] {
        let data = read(&sample(name));
        let (layers, reader) = read_layers(&data, false);
        let stated = reader.facts().stated_filament_mm.expect(name);
        let e: f64 = layers.iter().flat_map(|l| &l.paths).map(|p| p.e()).sum();
        assert!(
            (e - stated).abs() <= 0.005 * stated + 1e-3,
            "{name}: {e} vs {stated}"
        );
        assert!(layer_count(&layers) >= 2, "{name}");
    }
}
