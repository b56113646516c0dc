//! The cheap proof that a layer is supported (`geometry::proof`) never changes a result: the
//! regions found with it and without it are identical on every sample and on the test parts
//! sliced by PrusaSlicer (default, single-wall hollow, fine layers) and CuraEngine, and it
//! does spare the polygon work on most layers of ordinary parts.

use crate::common::*;

use printonair::geometry::{detect, DetectOptions, Region};
use printonair::layers::{LayerKind, LayerReader, ReaderOptions, SlicerConfig};

/// Regions of every layer (as text, to the last bit of every coordinate), and the number of
/// layers whose area detection never computed (the proof held for them and the next).
fn regions(data: &[u8], prove: bool) -> (Vec<String>, usize) {
    let config = SlicerConfig::parse(data);
    let opts = DetectOptions {
        external_width: config.external_perimeter_width(),
        prove,
        ..Default::default()
    };
    let reader = LayerReader::new(
        data,
        ReaderOptions {
            keep_raw: false,
            config,
        },
    );
    let mut out = Vec::new();
    let mut spared = 0;
    detect(reader, &opts, |d| {
        if d.layer.kind == LayerKind::Layer && d.area.is_none() {
            spared += 1;
        }
        out.extend(d.regions.iter().map(describe));
        Ok(())
    })
    .unwrap();
    (out, spared)
}

fn describe(r: &Region) -> String {
    let ring = |l: &geo::LineString<f64>| {
        l.0.iter()
            .map(|c| format!("{:x},{:x}", c.x.to_bits(), c.y.to_bits()))
            .collect::<Vec<_>>()
            .join(" ")
    };
    format!(
        "layer {} {:?} area {:x} dist {:x} anchored {:x}/{} ext {:?} | {} | {}",
        r.layer,
        r.kind,
        r.area.to_bits(),
        r.max_distance.to_bits(),
        r.anchored_length.to_bits(),
        r.anchors,
        r.extrusions,
        ring(r.polygon.exterior()),
        r.polygon
            .interiors()
            .iter()
            .map(ring)
            .collect::<Vec<_>>()
            .join(" / ")
    )
}

/// Asserts the regions are identical both ways; returns the layers spared.
fn same_both_ways(data: &[u8], what: &str) -> usize {
    let (exact, _) = regions(data, false);
    let (proven, spared) = regions(data, true);
    assert_eq!(exact.len(), proven.len(), "{what}: region count");
    for (a, b) in exact.iter().zip(&proven) {
        assert_eq!(a, b, "{what}");
    }
    spared
}

#[test]
fn the_proof_changes_no_region_of_any_sample() {
    let mut spared = 0;
    for s in samples() {
        let data = read(&s);
        spared += same_both_ways(&data, &s.display().to_string());
    }
    // The PrusaSlicer samples rise straight for most of their height.
    assert!(spared > 100, "the proof spared only {spared} layers");
}

const PARTS: [&str; 13] = [
    "rect_overhang",
    "circ_overhang",
    "tri_overhang",
    "bridge",
    "arms60",
    "box_roof_window",
    "frustums",
    "holes_mixed",
    "hook",
    "mushroom",
    "perforated",
    "shelves_hole",
    "sphere_stem",
];

#[test]
fn the_proof_changes_no_region_of_any_part_sliced_by_prusaslicer() {
    let settings: [&[&str]; 3] = [
        &[],
        // A single wall and no infill: the inside of a loop is a real hole below a roof.
        &["--perimeters", "1", "--fill-density", "0"],
        &[
            "--layer-height",
            "0.1",
            "--fill-pattern",
            "gyroid",
            "--perimeters",
            "3",
        ],
    ];
    let mut spared = 0;
    for name in PARTS {
        for args in settings {
            let Some(data) = slice(name, args) else {
                return;
            };
            spared += same_both_ways(&data, &format!("{name} {args:?}"));
        }
    }
    assert!(spared > 500, "the proof spared only {spared} layers");
}

#[test]
fn the_proof_changes_no_region_of_any_part_sliced_by_cura() {
    for name in PARTS {
        for settings in [
            &[][..],
            &["wall_line_count=1", "infill_sparse_density=0"][..],
        ] {
            let Some(data) = slice_cura(&part(name), "prusa_i3_mk3", settings) else {
                return;
            };
            same_both_ways(&data, &format!("{name} by Cura {settings:?}"));
        }
    }
}

#[test]
fn a_wide_nozzle_s_layers_are_proven() {
    // PrusaSlicer's defaults with a 0.6 mm nozzle at 0.3 mm layers: the layer above may reach
    // 1.4 mm from a loop below (its 0.68 mm external perimeter, and the tolerance of half of
    // it on either side), farther than a fixed 1 mm search for loops close to each other.
    for name in ["holes_mixed", "mushroom", "hook"] {
        let args = ["--nozzle-diameter", "0.6", "--layer-height", "0.3"];
        let Some(data) = slice_defaults(name, &args) else {
            return;
        };
        let spared = same_both_ways(&data, &format!("{name} {args:?}"));
        let layers = String::from_utf8_lossy(&data)
            .lines()
            .filter(|l| l.starts_with(";LAYER_CHANGE"))
            .count();
        assert!(
            spared * 3 > layers * 2,
            "{name}: spared {spared} of {layers} layers"
        );
    }
}

#[test]
fn a_roof_over_a_single_walled_box_is_found_with_the_proof_on() {
    // 20 x 20 x 10 box, one wall, no infill, closed by a 2 mm roof.
    let mut m = Mesh::default();
    m.cuboid([100.0, 100.0, 0.0], [120.0, 120.0, 12.0]);
    let Some(data) = slice_mesh(&m, &["--perimeters", "1", "--fill-density", "0"]) else {
        return;
    };
    same_both_ways(&data, "single-walled box");
    // The roof's first layer spans the box's inside: one region. (No layer is spared: with
    // one wall nothing flanks the external perimeter, so the proof never holds.)
    let (found, spared) = regions(&data, true);
    assert_eq!(spared, 0);
    assert_eq!(found.len(), 1, "{found:?}");
}

/// A test part sliced by PrusaSlicer (the samples' config), its regions checked the same
/// both ways ([`same_both_ways`]): the G-code, the layers spared and the layers in all.
fn sliced_both_ways(name: &str) -> Option<(Vec<u8>, usize, usize)> {
    let data = slice(name, &[])?;
    let spared = same_both_ways(&data, name);
    let layers = String::from_utf8_lossy(&data)
        .lines()
        .filter(|l| l.starts_with(";LAYER_CHANGE"))
        .count();
    Some((data, spared, layers))
}

#[test]
fn layers_over_holes_rising_straight_are_proven() {
    // Through-holes, a blind hole roofed half way up, holes narrowing and widening, a slot.
    let Some((data, spared, layers)) = sliced_both_ways("holes_mixed") else {
        return;
    };
    // Of 80 layers, all but those where a hole changes (the cones every layer, the roof)
    // and the one after each.
    assert!(spared * 2 > layers, "spared {spared} of {layers} layers");
    // The roof over the blind hole is over air, found with the proof on.
    let (found, _) = regions(&data, true);
    assert!(!found.is_empty());
}

#[test]
fn a_perforated_plate_is_proven_and_the_lid_over_its_holes_found() {
    let Some((data, spared, layers)) = sliced_both_ways("perforated") else {
        return;
    };
    // The plate's layers above the first two rise straight; the lid's first layer and the
    // one after it go to the exact path. Joins from one hole's wall to the next across a
    // hole, or between the pieces of a perimeter threading between the holes, failed the
    // proof on every layer.
    assert!(spared + 5 >= layers, "spared {spared} of {layers} layers");
    // The lid's first layer bridges the holes under it: a region over each.
    let (found, _) = regions(&data, true);
    assert!(found.len() >= 21, "{} regions: {found:?}", found.len());
}
