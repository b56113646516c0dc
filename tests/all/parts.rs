//! The rewrite on parts other than the paper's specimens, made on the fly and sliced by
//! PrusaSlicer: every strand poa writes must rest on material, and nothing near a region may
//! be left in air.

use crate::common;

use common::*;
use printonair::check::{check_layer, CheckOptions, Support};
use printonair::layers::{filament_area, Layer, LayerKind, SlicerConfig};
use printonair::poa::BridgeMode;

fn layers_of(data: &[u8]) -> Vec<Layer> {
    all_layers(data)
        .into_iter()
        .filter(|l| l.kind == LayerKind::Layer)
        .collect()
}

/// Processes `data` and checks every rewritten layer. Returns the number of regions rewritten.
fn rewrite_and_check(data: &[u8], what: &str) -> usize {
    let (out, rep) = rewrite(data, BridgeMode::Keep);
    if let Ok(dir) = std::env::var("POA_KEEP") {
        // For a closer look at a failure: the input and the rewrite.
        let name = what.replace(' ', "_");
        std::fs::write(format!("{dir}/{name}.gcode"), data).unwrap();
        std::fs::write(format!("{dir}/{name}.poa.gcode"), &out).unwrap();
    }
    let fa = filament_area(SlicerConfig::parse(data).filament_diameter());
    let bl = poa_blocks(&out);
    assert_eq!(bl.len(), rep.regions_rewritten, "{what}");
    let layers = layers_of(&out);
    let opts = CheckOptions::default();
    for w in layers.windows(2) {
        let (below, layer) = (&w[0], &w[1]);
        let mine: Vec<&(u64, u64)> = bl
            .iter()
            .filter(|(a, b)| *a >= layer.first_line && *b <= layer.last_line)
            .collect();
        if mine.is_empty() {
            continue;
        }
        let c = check_layer(&[below], layer, fa, &opts, true);
        let bad: Vec<_> = c
            .samples
            .iter()
            .filter(|s| s.support != Support::Supported)
            .filter(|s| mine.iter().any(|(a, b)| s.line >= *a && s.line <= *b))
            .collect();
        assert!(
            bad.is_empty(),
            "{what}: layer {} Z {}: {} samples of poa's strands unsupported, first {:?} line {}",
            layer.index + 1,
            layer.z,
            bad.len(),
            bad[0].point,
            bad[0].line
        );
        assert!(
            c.density <= 1.6,
            "{what}: density {} on layer {}",
            c.density,
            layer.index + 1
        );
    }
    // The rewritten file reads back with the same layers.
    assert_eq!(layers.len(), layers_of(data).len(), "{what}");
    rep.regions_rewritten
}

#[test]
fn mushroom_ring_overhang() {
    let mut m = Mesh::default();
    m.cylinder([100.0, 100.0], 5.0, 0.0, 10.0)
        .cylinder([100.0, 100.0], 15.0, 10.0, 13.0);
    let Some(data) = slice_mesh(&m, &[]) else {
        return;
    };
    assert_eq!(rewrite_and_check(&data, "mushroom"), 1);
}

#[test]
fn slab_with_a_hole_over_a_column() {
    // A 40 x 30 slab 3 mm thick at Z 10 with a 10 x 10 hole over air, on a 10 x 30 column.
    let mut m = Mesh::default();
    m.cuboid([90.0, 85.0, 0.0], [100.0, 115.0, 10.0])
        .cuboid([90.0, 85.0, 10.0], [130.0, 95.0, 13.0])
        .cuboid([90.0, 105.0, 10.0], [130.0, 115.0, 13.0])
        .cuboid([90.0, 95.0, 10.0], [110.0, 105.0, 13.0])
        .cuboid([120.0, 95.0, 10.0], [130.0, 105.0, 13.0]);
    let Some(data) = slice_mesh(&m, &[]) else {
        return;
    };
    assert_eq!(rewrite_and_check(&data, "slab with hole"), 1);
}

#[test]
fn two_objects_and_zhop_in_absolute_e() {
    // Two separate cantilevers on one plate, absolute E.
    let mut m = Mesh::default();
    m.cuboid([80.0, 80.0, 0.0], [90.0, 95.0, 6.0])
        .cuboid([80.0, 80.0, 6.0], [105.0, 95.0, 8.0])
        .cuboid([80.0, 110.0, 0.0], [90.0, 125.0, 6.0])
        .cuboid([80.0, 110.0, 6.0], [105.0, 125.0, 8.0]);
    let Some(data) = slice_mesh(
        &m,
        &[
            "--no-use-relative-e-distances",
            "--before-layer-gcode",
            ";BEFORE_LAYER_CHANGE\n;[layer_z]\n",
        ],
    ) else {
        return;
    };
    assert_eq!(rewrite_and_check(&data, "two cantilevers"), 2);
}

#[test]
fn stepped_overhang_on_many_layers() {
    // Three steps of 4 mm, each 1 mm high: a region on three layers.
    let mut m = Mesh::default();
    m.cuboid([90.0, 90.0, 0.0], [100.0, 110.0, 5.0])
        .cuboid([90.0, 90.0, 5.0], [104.0, 110.0, 6.0])
        .cuboid([90.0, 90.0, 6.0], [108.0, 110.0, 7.0])
        .cuboid([90.0, 90.0, 7.0], [112.0, 110.0, 8.0]);
    let Some(data) = slice_mesh(&m, &[]) else {
        return;
    };
    assert_eq!(rewrite_and_check(&data, "steps"), 3);
}
