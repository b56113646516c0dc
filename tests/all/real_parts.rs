//! Print-on-Air on parts of our own (tests/parts/*.scad), sliced by PrusaSlicer and by
//! CuraEngine, judged by the deposition check: the floating layers end up supported, the
//! rewritten layers keep their printed area, the layer above a rewrite is no worse, the
//! undersides of a sphere and of 60 degree arms improve, and the print takes at most 10 %
//! longer. Numbers are printed for the record (`cargo test real_parts -- --nocapture`).

use crate::common::*;

use printonair::check::{CheckOptions, LayerCheck};
use printonair::geometry::{intersection, offset, printed_area, AreaOptions};
use printonair::layers::{LayerKind, SlicerConfig};
use printonair::poa::BridgeMode;
use printonair::report::CheckReport;

use geo::{Area, MultiPolygon};

fn check(d: &[u8]) -> CheckReport {
    printonair::report::check(d, SlicerConfig::parse(d), &CheckOptions::default(), "x").unwrap()
}

/// PrusaSlicer with `args` on top of the samples' config, and Cura.
fn slices_with(name: &str, args: &[&str]) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    if let Some(d) = slice(name, args) {
        v.push(("PrusaSlicer".to_string(), d));
    }
    if let Some(d) = slice_cura(
        &part(name),
        "prusa_i3_mk3",
        &["bridge_settings_enabled=true"],
    ) {
        v.push(("Cura".to_string(), d));
    }
    v
}

/// `name` sliced by PrusaSlicer with `args` and by Cura with a machine and its settings,
/// named by `labels` (a slicer that is not there is left out).
fn by_both<'l>(
    name: &str,
    args: &[&str],
    cura: (&str, &[&str]),
    labels: [&'l str; 2],
) -> Vec<(&'l str, Vec<u8>)> {
    let mut v = Vec::new();
    if let Some(d) = slice(name, args) {
        v.push((labels[0], d));
    }
    if let Some(d) = slice_cura(&part(name), cura.0, cura.1) {
        v.push((labels[1], d));
    }
    v
}

/// Printed area of each layer (index = layer number - 1).
fn areas(d: &[u8]) -> Vec<MultiPolygon<f64>> {
    all_layers(d)
        .iter()
        .filter(|l| l.kind == LayerKind::Layer)
        .map(|l| printed_area(l, &AreaOptions::default()))
        .collect()
}

/// Rewrites `name` as sliced by each slicer and checks what every part must meet.
fn judge(name: &str) -> Vec<(String, CheckReport, CheckReport)> {
    judge_with(name, &[])
}

fn judge_with(name: &str, args: &[&str]) -> Vec<(String, CheckReport, CheckReport)> {
    slices_with(name, args)
        .into_iter()
        .map(|(slicer, data)| judge_one(format!("{name} by {slicer}"), &data))
        .collect()
}

/// Rewrites one slice and checks what every part must meet.
///
/// Long by design: each claim of the issue's acceptance measured next to the others on the
/// same rewrite.
fn judge_one(what: String, data: &[u8]) -> (String, CheckReport, CheckReport) {
    {
        let (new, rep) = rewrite(data, BridgeMode::Auto);
        let (before, after) = (check(data), check(&new));
        assert_eq!(before.layers.len(), after.layers.len(), "{what}");
        let rewritten: std::collections::BTreeSet<usize> =
            rep.rewrites.iter().map(|r| r.layer).collect();
        // No region ends with nothing done: loops, or a gradual overhang's perimeter moved
        // onto the layer below (which the report says).
        for r in &rep.rewrites {
            assert!(
                r.loops > 0 || r.gradual,
                "{what}: region {} got 0 loops",
                r.region
            );
        }
        assert_eq!(
            rep.gradual,
            rep.rewrites.iter().filter(|r| r.gradual).count(),
            "{what}"
        );
        // Floating layers: what the slicer prints in air is held up, the slicer's own strand
        // ends beside the region included (at most 1 mm left in air).
        held_up(&what, &before, &after, 100.0);
        // A rewritten layer keeps its printed area outside the regions (over the layer
        // below as sliced, where nothing is rewritten).
        let (area0, area1) = (areas(data), areas(&new));
        for &l in rewritten.iter().filter(|&&l| l >= 2) {
            let over = offset(&area0[l - 2], 0.01);
            let a0 = intersection(&area0[l - 1], &over).unsigned_area();
            let a1 = intersection(&area1[l - 1], &over).unsigned_area();
            assert!(
                a1 >= 0.99 * a0,
                "{what}: layer {l} prints {a1:.1} mm2 outside its regions, {a0:.1} before"
            );
        }
        // Nothing the slicer printed is lost: every rewritten layer prints what it printed
        // as sliced, but for the moved perimeters' pull-in (0.05 mm) and the footprints'
        // noise.
        for &l in &rewritten {
            let lost = printonair::geometry::difference(&area0[l - 1], &offset(&area1[l - 1], 0.1));
            let (a0, lost) = (area0[l - 1].unsigned_area(), lost.unsigned_area());
            assert!(
                lost <= 0.005 * a0,
                "{what}: layer {l} lost {lost:.2} mm2 of {a0:.1} mm2 printed as sliced"
            );
        }
        // The layer above a rewrite is no worse.
        for &l in &rewritten {
            if rewritten.contains(&(l + 1)) || l >= before.layers.len() {
                continue;
            }
            let (b, a) = (&before.layers[l], &after.layers[l]);
            // Not more in air; an end the layer below no longer leaves hanging may turn a run
            // of this layer from in air into bridged, so the two count together.
            assert!(
                a.in_air_mm <= b.in_air_mm + 0.05
                    && a.in_air_mm + a.bridged_mm <= b.in_air_mm + b.bridged_mm + 1.0,
                "{what}: layer {} above a rewrite: {:.1} mm in air, {:.1} bridged ({:.1}, {:.1} before)",
                b.layer,
                a.in_air_mm,
                a.bridged_mm,
                b.in_air_mm,
                b.bridged_mm
            );
        }
        // Loops joined: travel between a region's own strands is a small share of them. (A
        // gradual overhang's ring is cut where the wall below already holds it: the travel
        // over those gaps is the gaps, and is only reported.) One crossing is left out: a
        // strip whose outline meets it at both ends (an arch's crown) is finished at one end
        // after all its loops, then at the other, and no order avoids going between them.
        for r in rep.rewrites.iter().filter(|r| !r.gradual) {
            let beyond = r.inner_travel_mm - r.longest_inner_travel_mm;
            assert!(
                beyond <= 0.10 * r.written_length_mm,
                "{what}: region {}: {:.1} mm of travel between loops (the longest {:.1} left out) for {:.1} mm of them",
                r.region,
                beyond,
                r.longest_inner_travel_mm,
                r.written_length_mm
            );
        }
        at_most_a_tenth_longer(&what, &before, &after);
        println!(
            "{what}: {} regions, in air {:.1} -> {:.1} mm, bridged {:.1} -> {:.1} mm, time {:.0} -> {:.0} s",
            rep.regions_rewritten,
            before.in_air_mm,
            after.in_air_mm,
            before.bridged_mm,
            after.bridged_mm,
            before.time_s,
            after.time_s
        );
        (what, before, after)
    }
}

#[test]
fn a_hook() {
    judge("hook");
}

#[test]
fn a_box_with_a_roof_and_a_window() {
    for (what, before, after) in judge("box_roof_window") {
        // The roof is rewritten (anchored all round, it is an overhang for loops).
        cut_to(&what, &before, &after, 0.05);
    }
}

/// The same box by PrusaSlicer with one perimeter: its 1.5 mm wall is two beads with a gap
/// between them, and PrusaSlicer lays the roof's first bridge strands along the wall over
/// that gap, beside the region but not in it. They are planned with the region, and the
/// loops there grow from both beads: the contour along the outer bead first (as sliced,
/// 1784 mm in air on the roof's layer; 109 mm of the strands beside the region were left
/// hanging, then 55 mm of loops beside a contour laid last).
#[test]
fn a_one_perimeter_box_s_roof_is_held_over_the_gap_inside_its_wall() {
    let Some(d) = slice("box_roof_window", &["--perimeters", "1"]) else {
        return;
    };
    let (what, before, after) =
        judge_one("box_roof_window by PrusaSlicer, one perimeter".into(), &d);
    held_up(&what, &before, &after, 20.0);
    cut_to(&what, &before, &after, 0.01);
}

/// A table whose top reaches 6 mm past its legs: between the legs a bridge, beyond them a
/// rim no bridge strand is anchored under. Kept as a bridge it left 2.4 m in air; now it is
/// an overhang, grown from the legs.
#[test]
fn a_table_top_reaching_past_its_legs_gets_loops() {
    for (what, before, after) in judge("table") {
        cut_to(&what, &before, &after, 0.01);
    }
}

/// An open bowl, its flank a gradual overhang up to the rim, by Cura with one wall: the
/// layer past the last one whose slicer perimeter hung (and was moved) found a speck of room
/// for a loop where the moved perimeter's pieces met, was planned as a wide region, kept
/// its perimeter where the slicer put it and hung past the moved one below (0 -> 63.5 mm in
/// air).
#[test]
fn a_bowl_flank_by_cura_with_one_wall_stays_held_above_its_moved_perimeters() {
    let settings = [
        "layer_height=0.16",
        "infill_sparse_thickness=0.16",
        "wall_line_count=1",
        "infill_pattern=cubic",
    ];
    // And by Cura's Ender 3 defaults: planning the ring over the first (wide) rewrite on
    // that layer as rewritten made it wide, and the ring above hung (0.7 -> 38.5 mm).
    let slices = [
        slice_cura(&part("bowl"), "prusa_i3_mk3", &settings).map(|d| ("one wall", d)),
        slice_cura(&part("bowl"), "creality_ender3", &["layer_height=0.2"]).map(|d| ("Ender 3", d)),
    ];
    for (name, d) in slices.into_iter().flatten() {
        let (what, before, after) = judge_one(format!("bowl by Cura ({name})"), &d);
        no_layer_worse(&what, &before, &after);
    }
}

/// A pipe elbow lying on the bed: its second layer hangs past the first one, which
/// PrusaSlicer draws in by its elephant-foot compensation. The loops grow from the first
/// layer as printed (they were laid from its squashed-out outline, 60 mm in air).
#[test]
fn an_elbow_lying_on_the_bed_is_held_from_its_first_layer() {
    for (what, before, after) in judge("elbow") {
        held_up(&what, &before, &after, 10.0);
    }
    // Outer wall first, the third layer's loops grew from the second layer's perimeter
    // where the slicer put it, not where the rewrite moved it (49.2 -> 48.9 mm in air; now
    // from the second layer as rewritten, its regions still those found as sliced: 25.3).
    let Some(d) = slice("elbow", &["--external-perimeters-first"]) else {
        return;
    };
    let (what, before, after) = judge_one("elbow by PrusaSlicer, outer wall first".into(), &d);
    let (b, a) = (&before.layers[2], &after.layers[2]);
    assert!(
        a.in_air_mm <= 0.6 * b.in_air_mm,
        "{what}: layer 3 {:.1} mm in air, {:.1} before",
        a.in_air_mm,
        b.in_air_mm
    );
}

/// A shelf with a slot through it, by Cura with the outer wall first: the slot's walls are
/// set a little apart from the shelf's skin, a floating island beside the overhang region.
/// They were taken out with the region and not laid again (no perimeter round the slot),
/// and the layer above hung over the slot (0 -> 37.3 mm in air).
#[test]
fn a_slot_in_a_shelf_keeps_its_walls_when_cura_prints_the_outer_wall_first() {
    let settings = ["outer_inset_first=true", "bridge_settings_enabled=true"];
    if let Some(d) = slice_cura(&part("slot_shelf"), "prusa_i3_mk3", &settings) {
        let (what, before, after) = judge_one("slot_shelf by Cura (outer wall first)".into(), &d);
        cut_to(&what, &before, &after, 0.01);
    }
}

/// A domed ceiling closing round a shrinking hole (Cura, 0.12 mm): on a 64-faceted ring
/// the second loop of a thin ring lay near the mark in and out of it every facet, its short
/// pieces were dropped, and the perimeter hung 0.35 mm past loop 1 (22 mm in air).
#[test]
fn a_domed_ceiling_is_held_round_its_closing_hole() {
    let settings = [
        "layer_height=0.12",
        "infill_sparse_thickness=0.12",
        "infill_pattern=gyroid",
        "wall_line_count=3",
    ];
    let Some(d) = slice_cura(&part("dome_box"), "creality_ender3", &settings) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Keep);
    let (before, after) = (check(&d), check(&new));
    // Every layer poa rewrote (the floor's own top over its sparse infill is the slicer's).
    for r in &rep.rewrites {
        let (b, a) = (&before.layers[r.layer - 1], &after.layers[r.layer - 1]);
        assert!(
            a.in_air_mm <= 1.0,
            "dome_box by Cura: layer {} {:.1} mm in air, {:.1} before",
            r.layer,
            a.in_air_mm,
            b.in_air_mm
        );
    }
}

/// `--bridges auto`: a bridge whose slicer strands span it is kept as sliced (Cura's short
/// bridge: nothing in air); one the deposition check finds partly in air is rewritten
/// (PrusaSlicer's overhang perimeters along the same deck, paths of their own that start
/// and end over the gap: 25 mm; the 40 mm bridge sample's spans: 1953 mm).
#[test]
fn bridges_auto_rewrites_only_the_bridges_whose_strands_hang() {
    if let Some(d) = slice_cura(
        &part("short_bridge"),
        "prusa_i3_mk3",
        &["bridge_settings_enabled=true"],
    ) {
        let (_, rep) = rewrite(&d, BridgeMode::Auto);
        assert_eq!(rep.regions_rewritten, 0, "{:?}", rep.rewrites);
        assert!(
            rep.skipped.iter().all(|s| s.reason.starts_with("bridge")),
            "{:?}",
            rep.skipped
        );
    }
    if let Some(d) = slice("short_bridge", &[]) {
        let (what, before, after) = judge_one("short_bridge by PrusaSlicer".into(), &d);
        assert!(before.in_air_mm > 10.0, "{what}: {:.1}", before.in_air_mm);
        cut_to(&what, &before, &after, 0.01);
    }
    let span40 = std::fs::read(sample("bridge_prusa_abs.gcode")).unwrap();
    let (what, before, after) = judge_one("bridge sample".into(), &span40);
    cut_to(&what, &before, &after, 0.01);
    let (kept, rep) = rewrite(&span40, BridgeMode::Keep);
    assert_eq!(rep.regions_rewritten, 0);
    assert_eq!(check(&kept).in_air_mm, before.in_air_mm);
}

#[test]
fn two_shelves_with_holes() {
    judge("shelves_hole");
}

/// PrusaSlicer anchors each step's bridge over the block's sparse infill, and the last strand
/// of it ends 6 mm past the perimeter over a gap of the gyroid below: held by an anchor, the
/// first floating layer keeps under 1 mm in air.
#[test]
fn a_stepped_ledge_s_bridge_ends_beside_it_are_held() {
    for (what, before, after) in judge("steps_over") {
        let first = before
            .layers
            .iter()
            .position(|l| l.in_air_mm > 20.0)
            .unwrap_or_else(|| panic!("{what}: no floating layer"));
        assert!(
            after.layers[first].in_air_mm <= 1.0,
            "{what}: first floating layer {} keeps {:.1} mm in air ({:.1} before)",
            first + 1,
            after.layers[first].in_air_mm,
            before.layers[first].in_air_mm
        );
        cut_to(&what, &before, &after, 0.1);
    }
}

#[test]
fn the_paper_shapes_sliced_by_both() {
    for name in ["rect_overhang", "circ_overhang", "tri_overhang"] {
        for (what, before, after) in judge(name) {
            cut_to(&what, &before, &after, 0.01);
        }
    }
}

#[test]
fn a_sphere_underside_is_held_up_layer_by_layer() {
    let mut judged = judge("sphere_stem");
    // Cura's adaptive layers and 0.28 mm layers: each layer's ring a bead wide or more near
    // the equator, where the layer above a moved perimeter once came out worse (an adaptive
    // slice: 0 -> 3.8 mm in air on one layer) and a ring wider than a bead kept 14 mm in air.
    for (name, settings) in [
        ("adaptive", &["adaptive_layer_height_enabled=true"][..]),
        (
            "0.28 mm",
            &["layer_height=0.28", "infill_sparse_thickness=0.28"][..],
        ),
        // The outer wall before the inner ones: the moved perimeter has only the layer
        // below and the loops to rest on (a dome by Cura this way kept 33.6 mm in air).
        (
            "outer wall first",
            &["outer_inset_first=true", "wall_line_count=4"][..],
        ),
    ] {
        if let Some(d) = slice_cura(&part("sphere_stem"), "prusa_i3_mk3", settings) {
            judged.push(judge_one(format!("sphere_stem by Cura ({name})"), &d));
        }
    }
    for (what, before, after) in judged {
        // The underside: the ball (radius 10, bottom at Z 8) below its 12 mm level.
        for (b, a) in before.layers.iter().zip(&after.layers) {
            if b.z > 8.0 && b.z < 12.0 && b.in_air_mm > 5.0 {
                assert!(
                    a.in_air_mm <= 0.1 * b.in_air_mm,
                    "{what}: layer {} (Z {}) {:.1} mm in air, {:.1} before",
                    b.layer,
                    b.z,
                    a.in_air_mm,
                    b.in_air_mm
                );
            }
        }
    }
}

/// An Ultimaker S5 slice (Cura's Griffin flavour, 2.85 mm filament the header does not
/// state): poa reads E as 2.85 mm filament. Taken as 1.75 mm, its loops came out 1.64 x too
/// heavy and the deposition check saw 100 times the air.
#[test]
fn an_ultimaker_s5_slice_is_read_as_2_85_mm_filament() {
    let Some(d) = slice_cura(
        &part("rect_overhang"),
        "ultimaker_s5",
        &["material_diameter=2.85", "layer_height=0.2"],
    ) else {
        return;
    };
    assert_eq!(SlicerConfig::parse(&d).filament_diameter(), 2.85);
    let (what, before, after) = judge_one("rect_overhang by Cura (Ultimaker S5)".into(), &d);
    cut_to(&what, &before, &after, 0.01);
    // The walls read at their sliced width (0.4 mm nozzle), not 1.64 x wider.
    let mut walls: Vec<f64> = all_layers(&d)
        .iter()
        .flat_map(|l| l.paths.iter())
        .filter(|p| p.role == printonair::layers::Role::ExternalPerimeter)
        .map(|p| p.width)
        .collect();
    walls.sort_by(f64::total_cmp);
    let median = walls[walls.len() / 2];
    assert!(
        median > 0.3 && median < 0.55,
        "{what}: walls {median:.2} mm wide"
    );
}

/// A hull's flared bottom: the region at the bow runs on as a thin arm along each side,
/// where no loop fits. Its perimeter there stays where the slicer put it, so the layer above
/// (sliced on that outline) is no worse, within a mm (PrusaSlicer's slices of it differ a
/// little from run to run); pulled in by the inset it went from 23.6 to 52.2 mm in air.
#[test]
fn a_hull_side_keeps_the_outline_the_layer_above_stands_on() {
    let Some(d) = slice(
        "hull",
        &[
            "--layer-height",
            "0.28",
            "--perimeters",
            "2",
            "--infill-overlap",
            "40%",
        ],
    ) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Keep);
    let (before, after) = (check(&d), check(&new));
    let rewritten: std::collections::BTreeSet<usize> =
        rep.rewrites.iter().map(|r| r.layer).collect();
    assert!(!rewritten.is_empty());
    for &l in &rewritten {
        if rewritten.contains(&(l + 1)) || l >= before.layers.len() {
            continue;
        }
        let (b, a) = (&before.layers[l], &after.layers[l]);
        assert!(
            a.in_air_mm <= b.in_air_mm + 1.0,
            "layer {} above a rewrite: {:.1} mm in air, {:.1} before",
            b.layer,
            a.in_air_mm,
            b.in_air_mm
        );
    }
}

/// PrusaSlicer draws the first layer in by its elephant-foot compensation (0.2 mm by
/// default) because the squashed layer spreads that far. The check counts it spread: a
/// straight post's second layer stands on it even at 0.4 mm (read as 119 mm in air before),
/// and the hull's flared second layer, whose region poa finds against the spread layer, is
/// held by poa's loops (by the nominal first layer that layer read 70.9 mm in air as sliced
/// and 42.8 after poa, whose regions disagreed with the check).
#[test]
fn the_second_layer_stands_on_the_first_layer_squashed_out() {
    let Some(post) = slice("mushroom", &["--elefant-foot-compensation", "0.4"]) else {
        return;
    };
    let c = check(&post);
    assert!(c.layers[1].in_air_mm < 0.5, "{:?}", c.layers[1]);
    let Some(d) = slice("hull", &[]) else {
        return;
    };
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = (check(&d), check(&new));
    assert!(before.layers[1].in_air_mm > 5.0, "{:?}", before.layers[1]);
    held_up("hull by PrusaSlicer", &before, &after, 5.0);
}

/// PrusaSlicer's bare defaults (no printer profile: 0.3 mm layers, widths automatic, the
/// first layer 200 % wide, 0.7 mm for 0.45 mm walls, no elephant-foot compensation): the
/// hull's second and third layers flare past the first. Their plans took the first layer's
/// wall width (the median of the layers seen so far), pulled the perimeter in by 0.35 mm
/// instead of 0.225, off the stern's thin ring, and left it as sliced there, 0.17 mm past
/// the first layer's edge: 39 mm in air on layer 2 after the rewrite, 77 before.
#[test]
fn a_wide_first_layer_does_not_set_the_width_of_the_layers_above() {
    if !have_prusaslicer() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hull.gcode");
    let o = std::process::Command::new("prusa-slicer")
        .arg("--export-gcode")
        .arg("-o")
        .arg(&out)
        .arg(part("hull"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d = std::fs::read(&out).unwrap();
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = (check(&d), check(&new));
    for l in 1..3 {
        let (b, a) = (&before.layers[l], &after.layers[l]);
        assert!(b.in_air_mm > 10.0, "{b:?}");
        assert!(
            a.in_air_mm <= 0.1 * b.in_air_mm,
            "layer {}: {:.1} mm in air, {:.1} before",
            b.layer,
            a.in_air_mm,
            b.in_air_mm
        );
    }
}

/// The hull with one perimeter round a honeycomb infill and a 0.6 mm nozzle: the layer above
/// a moved perimeter is searched on the layer as rewritten and read back, where strands cut
/// at a zone's edge split the infill's outline into pockets left open. The honeycomb's cells
/// read as air, layer after layer: 153 regions for the 7 as sliced, +458 s on a 12 min print.
#[test]
fn a_honeycomb_next_to_a_rewrite_stays_infill_for_the_layer_above() {
    let args = [
        "--first-layer-height",
        "0.3",
        "--layer-height",
        "0.28",
        "--perimeters",
        "1",
        "--top-solid-layers",
        "3",
        "--fill-pattern",
        "honeycomb",
        "--nozzle-diameter",
        "0.6",
        "--extrusion-width",
        "0.68",
    ];
    let Some(d) = slice("hull", &args) else {
        return;
    };
    let (_, rep) = rewrite(&d, BridgeMode::Keep);
    let before = check(&d);
    assert!(
        rep.time_added_s <= 0.1 * before.time_s && rep.regions_found <= 40,
        "{} regions, +{:.0} s on {:.0} s",
        rep.regions_found,
        rep.time_added_s,
        before.time_s
    );
}

/// A block with bolt holes and a 45-degree chamfered lip, by PrusaSlicer at 0.3 mm with three
/// perimeters and by Cura for an Ender 3 at 0.28 mm: near the top of the 12 mm hole the
/// chamfer's thin ring and the hole's closing ceiling are one region, planned wide; no loop
/// fitted in the strip and its perimeter hung as sliced (47 mm in air on one layer, more than
/// before the rewrite). A half-width loop now goes under it.
#[test]
fn a_chamfer_strip_beside_a_hole_ceiling_is_held() {
    let mut slices = Vec::new();
    let args = [
        "--perimeters",
        "3",
        "--fill-pattern",
        "gyroid",
        "--layer-height",
        "0.3",
        "--first-layer-height",
        "0.3",
    ];
    if let Some(d) = slice("bolt_block", &args) {
        slices.push(("PrusaSlicer", d));
    }
    let settings = ["layer_height=0.28", "wall_line_count=2"];
    if let Some(d) = slice_cura(&part("bolt_block"), "creality_ender3", &settings) {
        slices.push(("Cura", d));
    }
    for (slicer, d) in slices {
        let (new, _) = rewrite(&d, BridgeMode::Keep);
        let (before, after) = (check(&d), check(&new));
        let what = format!("bolt_block by {slicer}");
        cut_to(&what, &before, &after, 0.1);
        no_layer_worse(&what, &before, &after);
    }
}

/// PrusaSlicer's settings for a hollow part with a roof: no infill, two perimeters, four top
/// layers.
const HOLLOW_ROOFED: [&str; 6] = [
    "--fill-density",
    "0%",
    "--perimeters",
    "2",
    "--top-solid-layers",
    "4",
];

/// A mushroom sliced hollow (`--fill-density 0%`): its cap's roof is the first solid layer
/// over the hollow inside, 2.9 m of bridge in air. The inside was read as held (a gap the
/// infill rule could not see into, and the quick proof took it as held): the roof is now a
/// region and gets loops from the walls inward.
#[test]
fn the_roof_of_a_hollow_part_gets_loops() {
    let Some(d) = slice("mushroom", &HOLLOW_ROOFED) else {
        return;
    };
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = (check(&d), check(&new));
    assert!(before.in_air_mm > 2000.0, "{:.1}", before.in_air_mm);
    cut_to("hollow mushroom", &before, &after, 0.01);
    no_layer_worse("hollow mushroom", &before, &after);
}

/// A shelf held by a gusset, sliced hollow at PrusaSlicer's own 0.3 mm defaults: the shelf's
/// first layer is bridge infill over the air beside the gusset and over its hollow inside, the
/// strands 0.05 mm apart. Each strip between two was a region of its own, and each planned
/// loops over the whole zone the strips make once their slits close: 30 plans over one area
/// (2.6 m of strands on a layer that 1.3 m fills, +27 % time). Now the strips are one region:
/// on every layer, poa's strands laid a loop step apart cover no more than the layer prints.
#[test]
fn strips_of_a_bridge_a_slit_apart_are_planned_once() {
    let Some(d) = slice_defaults("gusset_shelf", &HOLLOW_ROOFED) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    let area = areas(&d);
    let mut written: std::collections::BTreeMap<usize, f64> = Default::default();
    for r in &rep.rewrites {
        *written.entry(r.layer).or_default() += r.written_length_mm;
    }
    assert!(!written.is_empty(), "the shelf is rewritten");
    // Loops 0.45 mm wide overlapping by 0.4 (the defaults) lie 0.27 mm apart.
    let step = 0.6 * 0.45;
    for (layer, mm) in written {
        let printed = area[layer - 1].unsigned_area();
        assert!(
            mm * step <= printed,
            "layer {layer}: {mm:.0} mm of strands cover {:.0} mm2 at a loop step, the layer prints {printed:.0} mm2",
            mm * step
        );
    }
    let (before, after) = (check(&d), check(&new));
    assert!(
        after.in_air_mm < 0.05 * before.in_air_mm,
        "{:.1} -> {:.1} mm in air",
        before.in_air_mm,
        after.in_air_mm
    );
    assert!(
        after.time_s <= 1.12 * before.time_s,
        "time {:.0} -> {:.0} s",
        before.time_s,
        after.time_s
    );
}

/// An inverted pyramid flaring at 55 degrees, sliced hollow at PrusaSlicer's 0.3 mm defaults:
/// each layer of the flare is a ring of two perimeters, its outer side a gradual overhang,
/// its inner side over the ring below. The moved perimeter's area came out of two booleans
/// a sliver apart along that inner side, and the sliver's two edges were laid as strands
/// 0.015 mm apart on every side of every layer (2.9 times the length taken out, +16 % time).
/// A gradual overhang's strands now come to little more than what they replace.
#[test]
fn a_hollow_flare_s_rings_are_not_laid_twice() {
    let Some(d) = slice_defaults("inv_pyramid", &HOLLOW_ROOFED) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    let gradual: Vec<_> = rep.rewrites.iter().filter(|r| r.gradual).collect();
    assert!(gradual.len() >= 10, "{} gradual rewrites", gradual.len());
    // The perimeter alone comes to the slicer's perimeter it replaces, its ends and hops
    // aside; each loop under it adds about as much again.
    for r in gradual {
        let most = (1.6 + r.loops as f64) * r.removed_length_mm;
        assert!(
            r.written_length_mm <= most,
            "layer {}: {:.0} mm written ({} loops) for {:.0} mm taken out",
            r.layer,
            r.written_length_mm,
            r.loops,
            r.removed_length_mm
        );
    }
    let (before, after) = (check(&d), check(&new));
    assert!(
        after.in_air_mm < 0.01 * before.in_air_mm,
        "{:.1} -> {:.1} mm in air",
        before.in_air_mm,
        after.in_air_mm
    );
    no_layer_worse("hollow inverted pyramid", &before, &after);
}

/// PrusaSlicer's settings for a hollow part at quarter-millimetre layers: no infill, three
/// perimeters, four top layers, 0.25 mm layers (its defaults otherwise).
const HOLLOW_FINE: [&str; 8] = [
    "--fill-density",
    "0%",
    "--perimeters",
    "3",
    "--top-solid-layers",
    "4",
    "--layer-height",
    "0.25",
];

/// Hollow parts at 0.25 mm layers, where three ways of leaving a loop out met (2.3 m in air
/// after the rewrite over these three parts):
/// - a shelf's back wall goes on up over the shelf's last layer: the wall's side over the
///   shelf stands on its edge, the rest of that side hangs over the wall's hollow inside. The
///   perimeter along the edge was moved 0.3 mm off it, into the air, and laid first (25.6 mm
///   in air on each shelf's next layer);
/// - the shelf's top infill turns along that edge in notches, cutting the first loop into
///   pieces too short to lay;
/// - a roof's bridge lines meet the wall at 45 degrees, in pairs, leaving V notches between
///   the wall and the roof: loops 1 and 2 found no room there, and the first loop laid hung
///   0.58 mm past the wall (95.8 mm in air on the roof's first layer).
///
/// Every layer the slicer left over 5 mm in air has at most 1 mm left, and no layer is worse.
/// A bowl's flank (a hollow shell, its wall's inside a void the rings step over) is no worse
/// on any layer either: the void of a layer rewritten near the rim was widened, and the layer
/// above, not a region itself, bridged it (0 -> 75.6 mm in air).
/// The same parts by CuraEngine (MK3, no infill, three walls, 0.25 mm layers) are held too.
#[test]
fn hollow_parts_at_quarter_millimetre_layers_are_held_along_their_walls() {
    for name in ["shelves_hole", "slope_steps", "inv_pyramid", "bowl"] {
        // PrusaSlicer's own defaults under the flags (the samples' config holds the shelf's
        // first layer up too, but leaves 0.7 mm more in air at a corner of the layer above
        // it, 4.2 -> 4.9 mm, as it did before this test).
        let mut slices = Vec::new();
        if let Some(d) = slice_defaults(name, &HOLLOW_FINE) {
            slices.push(("PrusaSlicer", d));
        }
        if let Some(d) = slice_cura(
            &part(name),
            "prusa_i3_mk3",
            &[
                "infill_sparse_density=0",
                "wall_line_count=3",
                "layer_height=0.25",
                "top_layers=4",
                "bottom_layers=4",
            ],
        ) {
            slices.push(("Cura", d));
        }
        for (slicer, d) in slices {
            let what = format!("{name} by {slicer}");
            let (new, _) = rewrite(&d, BridgeMode::Auto);
            let (before, after) = before_after(&what, &d, &new);
            // PrusaSlicer's slice of the inverted pyramid varies from run to run (3 744 to
            // 3 754 mm in air as sliced, over twelve runs); on one in twelve a region's
            // rewrite gains nothing and it stays as sliced, its strands held but for
            // 1.7 mm on layer 25 (by design: a rewrite must print less in air than the
            // slicer's strands).
            let left = if name == "inv_pyramid" { 2.0 } else { 1.0 };
            if name != "bowl" {
                held_up_left(&what, &before, &after, 5.0, f64::INFINITY, left);
            }
            no_layer_worse(&what, &before, &after);
        }
    }
}

/// Horizontal holes through hollow parts at 0.25 mm layers (a bolt block, a lying pipe):
/// near a hole's ceiling PrusaSlicer lays bridge lines along the hole, over the slit the
/// layer below leaves, while the ceiling's sides are gradual overhangs whose perimeters hold.
/// Those regions were left as sliced for their held perimeters, and the bridge line hung
/// (16.8 mm in air on the bolt block's layer 48, 27.3 on the pipe's layer 56); a region over
/// whose zone a bridge line hangs is now rewritten where that leaves the layer less in air.
/// Every layer the slicer left over 5 mm in air has at most 1 mm left, and none is worse.
#[test]
fn a_bridge_line_along_a_hole_s_ceiling_is_replaced_by_loops() {
    for name in ["bolt_block", "pipe_lying"] {
        let Some(d) = slice_defaults(name, &HOLLOW_FINE) else {
            return;
        };
        let what = format!("{name} by PrusaSlicer, hollow at 0.25 mm");
        let (new, _) = rewrite(&d, BridgeMode::Auto);
        let (before, after) = before_after(&what, &d, &new);
        held_up(&what, &before, &after, 5.0);
        no_layer_worse(&what, &before, &after);
    }
}

/// Spiral vase prints (Cura's `magic_spiralize`, PrusaSlicer's `--spiral-vase`): a turn of
/// the helix has no one height, and a sphere's top turns were rewritten at a fixed Z (an elbow
/// by Cura in vase mode: one turn 0 -> 59 mm in air). Nothing of a helical layer is rewritten.
#[test]
fn spiral_vase_turns_are_left_as_sliced() {
    let mut slices = Vec::new();
    let vase = [
        "--spiral-vase",
        "--perimeters",
        "1",
        "--top-solid-layers",
        "0",
        "--fill-density",
        "0%",
    ];
    if let Some(d) = slice("sphere_stem", &vase) {
        slices.push(("sphere_stem by PrusaSlicer", d));
    }
    for name in ["sphere_stem", "elbow"] {
        if let Some(d) = slice_cura(&part(name), "creality_ender3", &["magic_spiralize=true"]) {
            slices.push((name, d));
        }
    }
    for (what, d) in slices {
        let (_, rep) = rewrite(&d, BridgeMode::Keep);
        let helical: std::collections::BTreeSet<usize> = all_layers(&d)
            .iter()
            .filter(|l| l.kind == LayerKind::Layer && l.helical)
            .map(|l| l.index + 1)
            .collect();
        assert!(
            helical.len() > 20,
            "{what}: {} helical layers",
            helical.len()
        );
        for r in &rep.rewrites {
            assert!(
                !helical.contains(&r.layer),
                "{what}: helical layer {} rewritten",
                r.layer
            );
        }
    }
}

/// Fuzzy skin moves each wall point up to its thickness in or out at random, so a vertical
/// wall's perimeter stands out of the one below by more than half its width every few
/// millimetres: no overhang. The mushroom's stem gets no rewrite (PrusaSlicer, all walls
/// fuzzy at 0.5 mm: 354 "gradual overhangs" on it were rewritten, +15 % time, the texture
/// smoothed there); its cap still gets loops.
#[test]
fn fuzzy_skin_on_a_vertical_wall_is_no_overhang() {
    let fuzzy = ["--fuzzy-skin", "all", "--fuzzy-skin-thickness", "0.5"];
    let Some(d) = slice("mushroom", &fuzzy) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    // The stem is 10 mm tall; the cap's first layer is at 10.2 mm and gets its loops.
    let cap: Vec<_> = rep
        .rewrites
        .iter()
        .filter(|r| (r.z - 10.2).abs() < 0.01)
        .collect();
    assert!(
        cap.len() == 1 && !cap[0].gradual && cap[0].loops > 10,
        "the cap: {:?}",
        rep.rewrites
    );
    // The fuzz of two layers can differ by twice its thickness, more than the tolerance
    // (half a width and the thickness): on the stem or the cap's fuzzy side a spot now and
    // then still reads as a gradual overhang (about 1 slice in 10 gets one or two, of 2
    // loops each; PrusaSlicer's fuzz differs from slice to slice) - a few, not hundreds.
    let elsewhere: Vec<_> = rep
        .rewrites
        .iter()
        .filter(|r| (r.z - 10.2).abs() >= 0.01)
        .collect();
    assert!(
        elsewhere.len() <= 4 && elsewhere.iter().all(|r| r.gradual && r.loops <= 2),
        "{elsewhere:?}"
    );
    // The cap's first layer is held and the print takes no longer than any rewrite may.
    // (The layer above is not judged here: its fuzzy perimeter stands out of the cap's
    // smooth moved one below as much as out of the fuzzy one, at random, up to a millimetre
    // more or less in air.)
    let (before, after) = (check(&d), check(&new));
    let cap = cap[0].layer;
    let (b, a) = (&before.layers[cap - 1], &after.layers[cap - 1]);
    assert!(
        a.in_air_mm <= 1.0 && b.in_air_mm > 1000.0,
        "cap layer {cap}: {:.1} mm in air, {:.1} before",
        a.in_air_mm,
        b.in_air_mm
    );
    at_most_a_tenth_longer("fuzzy mushroom", &before, &after);
    // `poa analyze` says where its tolerance comes from.
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("fuzzy.gcode");
    std::fs::write(&f, &d).unwrap();
    let o = poa().arg("analyze").arg(&f).output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("(tolerance 0.725 mm, with the file's fuzzy skin thickness 0.50 mm"),
        "{text}"
    );
}

/// The rewrite adds at most 10 % to the print's time.
fn at_most_a_tenth_longer(what: &str, before: &CheckReport, after: &CheckReport) {
    assert!(
        after.time_s <= 1.10 * before.time_s,
        "{what}: {:.0} s, {:.0} s before",
        after.time_s,
        before.time_s
    );
}

/// A horizontal cylinder on a post: its first layers are two wings anchored only at the
/// post, whose first fronts are slivers too small to print. Both wings get their loops (the
/// growth stopped after two empty fronts: one wing of a Cura slice got none, and the layer
/// kept 31 mm in air), and a wing's loops, short strokes across it, are joined by extruded
/// connectors (hops between them were 19 % of their length). A wing too narrow for a loop
/// across its loop area gets a ladder, by either slicer.
#[test]
fn both_wings_of_a_cylinder_on_a_post_get_loops() {
    let settings = [
        "layer_height=0.12",
        "infill_sparse_thickness=0.12",
        "wall_line_count=3",
        "infill_pattern=triangles",
    ];
    // PrusaSlicer at 0.12 mm cuts each wing 1.3 mm wide: room for a contour round a thread
    // of loop area 0.23 mm wide, none for a loop across it; the contour and perimeter were
    // laid along the wing in air (30.8 mm on the layer) until the ladder took over.
    let slices = by_both(
        "t_cylinders",
        &["--layer-height", "0.12"],
        ("prusa_i3_mk3", &settings),
        [
            "t_cylinders by PrusaSlicer (0.12 mm)",
            "t_cylinders by Cura (0.12 mm)",
        ],
    );
    for (what, d) in slices {
        let (new, rep) = rewrite(&d, BridgeMode::Keep);
        assert!(
            rep.rewrites.iter().all(|r| r.loops > 0 || r.gradual),
            "{what}: {:?}",
            rep.rewrites
        );
        held_up(what, &check(&d), &check(&new), 20.0);
        // Travel between a region's strands, but for one crossing (from one wing to the
        // other).
        for r in rep.rewrites.iter().filter(|r| !r.gradual) {
            let beyond = r.inner_travel_mm - r.longest_inner_travel_mm;
            assert!(
                beyond <= 0.10 * r.written_length_mm && r.connectors > 0,
                "{what}: region {}: {:.1} mm of travel between loops for {:.1} mm of them, \
                 {} connectors",
                r.region,
                beyond,
                r.written_length_mm,
                r.connectors
            );
        }
    }
}

#[test]
fn an_arch_and_a_hole_ceiling_are_held_up_to_their_crown() {
    // Near the crown each layer hangs more than a bead past the one below: a thin strip
    // with no room for a contour, where one half-width loop left the moved perimeter
    // hanging (Cura, 0.5 mm lines at 0.28 mm: 11.4 mm in air on one layer).
    let mut judged = judge("arch_hole");
    let cr10 = [
        "layer_height=0.28",
        "infill_sparse_thickness=0.28",
        "line_width=0.5",
        "wall_line_width=0.5",
        "wall_line_width_0=0.5",
        "wall_line_width_x=0.5",
        "infill_line_width=0.5",
        "skin_line_width=0.5",
        "wall_line_count=2",
    ];
    if let Some(d) = slice_cura(&part("arch_hole"), "creality_cr10", &cr10) {
        judged.push(judge_one("arch_hole by Cura (CR-10)".into(), &d));
    }
    for (what, before, after) in judged {
        held_up(&what, &before, &after, 10.0);
    }
}

/// PrusaSlicer's thick bridges lay overhang perimeters and bridges with a round bead as tall
/// as the nozzle (0.39 mm in a 0.2 mm layer). Such a layer once read as resting on the two
/// layers under it, so the layer over a moved gradual perimeter was planned on the layer
/// below as sliced, and its first loop hung 0.38 mm past the moved perimeter (a nut trap's
/// closing layer: 20.7 -> 64.1 mm in air).
#[test]
fn thick_bridges_rest_on_the_layer_below_and_the_hole_closes_on_moved_perimeters() {
    let Some(d) = slice("arch_hole", &["--thick-bridges", "--perimeters", "4"]) else {
        return;
    };
    let layers = all_layers(&d);
    for l in layers
        .iter()
        .filter(|l| l.kind == LayerKind::Layer && l.index > 0)
    {
        assert!(
            l.on_previous() && (l.height - 0.2).abs() < 0.01,
            "layer {} (Z {}): height {}, rests on {:?}",
            l.index + 1,
            l.z,
            l.height,
            l.rests_on
        );
    }
    let (what, before, after) = judge_one("arch_hole by PrusaSlicer, thick bridges".into(), &d);
    cut_to(&what, &before, &after, 0.5);
}

/// Thick bridges again, on gradual slopes of 30 to 75 degrees: a moved perimeter written
/// after the slicer's `;HEIGHT:0.39` read as a bead 0.29 mm wide instead of 0.45, so the
/// check (and poa reading its own layer back) took the perimeter above for hanging (0 ->
/// 9 mm in air on two layers). poa's strands say their own height.
#[test]
fn strands_written_after_a_thick_bridge_say_their_own_height() {
    let Some(d) = slice("slope_steps", THICK_BRIDGES) else {
        return;
    };
    let (what, before, after) = judge_one("slope_steps by PrusaSlicer, thick bridges".into(), &d);
    assert!(
        after.in_air_mm <= 1.0,
        "{what}: {:.1} mm in air, {:.1} before",
        after.in_air_mm,
        before.in_air_mm
    );
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    let blocks = poa_blocks(&new);
    assert!(!blocks.is_empty());
    let mut ours = 0;
    for p in all_layers(&new).iter().flat_map(|l| l.paths.iter()) {
        let line = p.seg_line.first().copied().unwrap_or(0);
        if blocks.iter().any(|&(a, b)| (a..=b).contains(&line)) {
            ours += 1;
            assert!(
                (p.height - 0.2).abs() < 0.01,
                "line {line}: height {}",
                p.height
            );
        }
    }
    assert!(ours > 0);
}

/// A hook's arm rounded underneath, by Cura with one wall at 0.3 mm: each layer of the
/// round hangs 0.35-0.4 mm past the one below, and with no inner wall nothing but the layer
/// below holds the perimeter. A loop goes under it once it would hang a quarter width past
/// the moved perimeter below (0.3 w before: one layer kept 50.9 mm in air).
#[test]
fn a_round_arm_with_one_wall_is_held_layer_by_layer() {
    let settings = [
        "layer_height=0.3",
        "layer_height_0=0.3",
        "wall_line_count=1",
        "infill_pattern=gyroid",
    ];
    let Some(d) = slice_cura(&part("round_arm"), "anycubic_i3_mega", &settings) else {
        return;
    };
    let (what, before, after) = judge_one("round_arm by Cura, one wall".into(), &d);
    // The arm's round, up to its flat top at 33 mm (the plate's top above has in-air strands
    // of the slicer's own, no region).
    held_up_to(&what, &before, &after, 10.0, 33.0);
}

/// A hook on a raft with support under its tip and its arm, by PrusaSlicer and by Cura:
/// the raft and the support hold the part across the slicer's contact gap. PrusaSlicer's
/// support under the tip starts in a layer of its own under the hook's first layer, which
/// was read as 60 mm2 over air, planned with no loop, and lost its solid infill; Cura types
/// its raft SUPPORT-INTERFACE, which was read as part of the print.
#[test]
fn a_part_on_a_raft_and_support_is_held_by_them() {
    let args = [
        "--raft-layers",
        "2",
        "--support-material",
        "--support-material-auto",
    ];
    let settings = [
        "support_enable=true",
        "adhesion_type=raft",
        "support_roof_enable=true",
    ];
    let slices = by_both(
        "hook",
        &args,
        ("prusa_i3_mk3", &settings),
        ["PrusaSlicer", "Cura"],
    );
    for (slicer, d) in slices {
        let (new, rep) = rewrite(&d, BridgeMode::Auto);
        let (before, after) = (check(&d), check(&new));
        // The check stands the part on the raft and the support: the hook as sliced without
        // them leaves 90 mm in air at its arm.
        assert!(
            before.in_air_mm < 25.0,
            "hook on a raft by {slicer}: {:.1} mm in air as sliced",
            before.in_air_mm
        );
        for r in &rep.rewrites {
            assert!(
                r.z > 2.0,
                "{slicer}: layer {} (Z {}) rewritten",
                r.layer,
                r.z
            );
        }
        for (b, a) in before.layers.iter().zip(&after.layers) {
            assert!(
                a.in_air_mm <= b.in_air_mm + 0.3 && a.filament_mm >= 0.99 * b.filament_mm,
                "{slicer}: layer {} (Z {}) {:.1} mm in air ({:.1} before), filament {:.2} ({:.2})",
                b.layer,
                b.z,
                a.in_air_mm,
                b.in_air_mm,
                a.filament_mm,
                b.filament_mm
            );
        }
    }
}

/// Cura prints a C-shaped cap on support with interface and a layer's gap under the cap; a
/// small bar of the cap's first layer beside the post is over air. The rewrite is judged on
/// what `poa check` stands the layer on, the support across the gap included: judged on the
/// gap layer alone, the whole layer read as in air as sliced and as rewritten, and a rewrite
/// 1.7 mm worse on `poa check` went out.
#[test]
fn a_cap_on_cura_s_support_is_judged_with_the_support_under_it() {
    let Some(d) = slice_cura(
        &part("c_cap"),
        "prusa_i3_mk3",
        &["support_enable=true", "support_interface_enable=true"],
    ) else {
        return;
    };
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    no_layer_worse("c_cap on Cura's support", &check(&d), &check(&new));
}

/// A hull on PrusaSlicer's support, whose layers come at heights of their own between the
/// part's: the layer printed after one of the hull's is support alone, and the hull's next
/// layer rests on both. Its bow's perimeter, moved onto the layer below with nothing known
/// above it, left that next layer's bow 25 mm more in air than as sliced; the next layer is
/// now planned on the layer as rewritten, as over any rewritten layer.
#[test]
fn a_hull_on_support_layers_of_their_own_keeps_its_next_layer_held() {
    let Some(d) = slice_defaults("hull", &["--support-material", "--support-material-auto"]) else {
        return;
    };
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    let what = "hull on support by PrusaSlicer";
    let (before, after) = before_after(what, &d, &new);
    no_layer_worse(what, &before, &after);
    cut_to(what, &before, &after, 0.2);
}

/// A chamfered box at 0.1 mm layers beside arms at 0.25 mm on one plate (per-object layer
/// heights, PrusaSlicer's defaults otherwise): between two of the box's layers the file
/// prints some of the arms'. Each gradual rewrite of the box moved its perimeter with no
/// layer above known (the next one was the arms'), and the box's next layer kept 0.3 mm in
/// air at every step of the chamfer (9.9 mm in all); it is now planned on the layer as
/// rewritten.
#[test]
fn a_chamfer_beside_a_part_of_another_layer_height_keeps_its_next_layer_held() {
    let what = "chamfer box and arms at two layer heights";
    let plate = [
        ("chamfer_box", [60.0, 100.0], 0.1),
        ("arms60", [140.0, 100.0], 0.25),
    ];
    let Some((_, after)) = mixed_heights_rewrite(what, &plate) else {
        return;
    };
    assert!(
        after.in_air_mm < 2.0,
        "{what}: {:.1} mm in air after the rewrite",
        after.in_air_mm
    );
}

/// A hull at 0.1 mm layers beside a shelf at 0.2 mm and a triangle at 0.3 mm: the hull's
/// third layer rests on its second and on the first layer of all three. Its second layer's
/// gradual rewrite moved the bow's perimeter; the third was not planned on it, the first
/// layer's area (never made: detection proved that layer) missing from what it rests on,
/// and its bow hung 1.1 mm more than as sliced. Judged layer by layer, not on the plate's
/// total: what stays in air is the shelf's internal solid infill ending over the gaps of its
/// sparse infill (support by design), and PrusaSlicer 2.5 lays it differently run to run
/// (6-26 mm on the plate over six slices of the same models, once 20.9 mm on one layer, as
/// much after the rewrite: no region there). The hull's floating layers hold 700-900 mm.
#[test]
fn a_hull_beside_parts_of_two_other_layer_heights_keeps_every_layer_held() {
    let what = "hull beside parts at two other layer heights";
    let plate = [
        ("shelves_hole", [50.0, 60.0], 0.2),
        ("hull", [140.0, 60.0], 0.1),
        ("tri_overhang", [100.0, 150.0], 0.3),
    ];
    let Some((before, after)) = mixed_heights_rewrite(what, &plate) else {
        return;
    };
    held_up(what, &before, &after, 50.0);
}

/// A plate of test parts, each at (offset, layer height), sliced by PrusaSlicer's defaults
/// (first layer 0.2 mm) and rewritten: the deposition check before and after, no layer
/// worse than sliced. `None` without PrusaSlicer.
fn mixed_heights_rewrite(
    what: &str,
    parts: &[(&str, [f64; 2], f64)],
) -> Option<(CheckReport, CheckReport)> {
    if !have_prusaslicer() {
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let amf = dir.path().join("plate.amf");
    let stls: Vec<_> = parts.iter().map(|(name, _, _)| part(name)).collect();
    let objects: Vec<_> = stls
        .iter()
        .zip(parts)
        .map(|(stl, (_, at, h))| (stl.as_path(), *at, Some(*h)))
        .collect();
    write_amf(&objects, &amf);
    let d = slice_stl_defaults(&amf, &["--first-layer-height", "0.2"])?;
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = before_after(what, &d, &new);
    no_layer_worse(what, &before, &after);
    Some((before, after))
}

/// PrusaSlicer with thick bridges, four perimeters, cubic infill, concentric top and the seam
/// at the rear (a held-out settings set).
const THICK_BRIDGES: &[&str] = &[
    "--thick-bridges",
    "--perimeters",
    "4",
    "--fill-pattern",
    "cubic",
    "--fill-density",
    "30%",
    "--top-fill-pattern",
    "concentric",
    "--seam-position",
    "rear",
];

/// With thick bridges PrusaSlicer rings a plate's floating layer with overhang perimeters
/// whose round beads leave hairline gaps: each ring is an island, a floating region of its
/// own. Those next to the plate's region, ring after ring, are planned with it; the outermost
/// one, left as sliced, hung 0.35 mm past the loops (130 mm in air).
#[test]
fn a_plate_ringed_by_thick_bridge_perimeters_is_planned_to_its_edge() {
    let Some(d) = slice("plate_windows", THICK_BRIDGES) else {
        return;
    };
    let (what, before, after) = judge_one("plate_windows by PrusaSlicer, thick bridges".into(), &d);
    held_up(&what, &before, &after, 10.0);
}

/// The deposition check of a slice and of its rewrite, their in-air totals printed for the
/// record.
fn before_after(what: &str, d: &[u8], new: &[u8]) -> (CheckReport, CheckReport) {
    let (before, after) = (check(d), check(new));
    println!(
        "{what}: in air {:.1} -> {:.1} mm",
        before.in_air_mm, after.in_air_mm
    );
    (before, after)
}

/// The rewrite leaves less than `share` of what the slicer printed in air.
fn cut_to(what: &str, before: &CheckReport, after: &CheckReport, share: f64) {
    assert!(
        after.in_air_mm < share * before.in_air_mm,
        "{what}: {:.1} mm in air, {:.1} before",
        after.in_air_mm,
        before.in_air_mm
    );
}

/// Every layer the slicer left more than `over` mm in air has at most 1 mm left.
fn held_up(what: &str, before: &CheckReport, after: &CheckReport, over: f64) {
    held_up_to(what, before, after, over, f64::INFINITY);
}

/// [`held_up`] for the layers at or below `z_max`.
fn held_up_to(what: &str, before: &CheckReport, after: &CheckReport, over: f64, z_max: f64) {
    held_up_left(what, before, after, over, z_max, 1.0);
}

/// [`held_up_to`] with at most `left` mm in air left on each such layer.
fn held_up_left(
    what: &str,
    before: &CheckReport,
    after: &CheckReport,
    over: f64,
    z_max: f64,
    left: f64,
) {
    for (b, a) in before.layers.iter().zip(&after.layers) {
        if b.z <= z_max && b.in_air_mm > over {
            assert!(
                a.in_air_mm <= left,
                "{what}: layer {} (Z {}) {:.1} mm in air, {:.1} before",
                b.layer,
                b.z,
                a.in_air_mm,
                b.in_air_mm
            );
        }
    }
}

#[test]
fn arms_at_60_degrees_bridge_less() {
    for (what, before, after) in judge("arms60") {
        let unsupported = |c: &CheckReport| c.in_air_mm + c.bridged_mm;
        if before.in_air_mm < 10.0 {
            // Thinner layers (Cura's 0.15 mm for this printer) leave each layer's edge
            // within the tolerance: nothing to do, nothing made worse.
            assert!(unsupported(&after) <= unsupported(&before) + 1.0, "{what}");
            continue;
        }
        assert!(
            unsupported(&after) <= 0.6 * unsupported(&before),
            "{what}: {:.1} mm unsupported, {:.1} before",
            unsupported(&after),
            unsupported(&before)
        );
        // Every sloped layer (the arms rise from Z 2 to 12).
        sloped_layers_held(&what, &before, &after, 4.0..11.0);
    }
}

/// PrusaSlicer anchors a bridge a few millimetres into the part beside it, over the part's
/// sparse infill; there its strands ran along the gaps of the infill below (in air: a slot
/// shelf over lightning infill 22.5 mm on its first floating layer, a shelf by a 0.6 mm
/// nozzle 47.8 mm on its second, a wing 22.4 mm). Planned with the region, the strip gets
/// loops grown from the walls that hold it.
#[test]
fn bridge_anchors_over_sparse_infill_are_planned_with_the_region() {
    let cases: [(&str, &[&str], f64); 3] = [
        (
            "slot_shelf",
            &["--fill-pattern", "lightning", "--perimeters", "1"],
            1.0,
        ),
        (
            "shelves_hole",
            &["--nozzle-diameter", "0.6", "--layer-height", "0.3"],
            1.0,
        ),
        ("wing", &[], 3.0),
    ];
    for (name, args, most) in cases {
        let Some(data) = slice(name, args) else {
            return;
        };
        let what = format!("{name} {args:?}");
        let (new, _) = rewrite(&data, BridgeMode::Auto);
        let (before, after) = before_after(&what, &data, &new);
        no_layer_worse(&what, &before, &after);
        for (b, a) in before.layers.iter().zip(&after.layers) {
            // The floating layers poa rewrote (the lightning's own top layers, further up,
            // bridge between its branches, as sliced).
            let rewritten = (a.length_mm - b.length_mm).abs() > 1e-6;
            if rewritten && b.in_air_mm > 20.0 {
                assert!(
                    a.in_air_mm <= most,
                    "{what}: layer {} keeps {:.1} mm in air ({:.1} before)",
                    b.layer,
                    a.in_air_mm,
                    b.in_air_mm
                );
            }
        }
    }
}

/// Four mushrooms with sparse rectilinear infill: each cap's bridge is anchored over its
/// stem's sparse infill, where the anchors ran along the gaps (13.4 mm in air on the caps'
/// layer when the stems' strips were left as sliced). The copies share one representative's
/// strips, moved, and its plan (made for each, the strips' booleans differ by noise).
#[test]
fn copies_share_their_anchor_strips() {
    let args = [
        "--fill-pattern",
        "rectilinear",
        "--fill-density",
        "10%",
        "--layer-height",
        "0.15",
        "--extrusion-width",
        "0.5",
        "--duplicate",
        "4",
    ];
    let Some(data) = slice("mushroom", &args) else {
        return;
    };
    let what = "four mushrooms, sparse infill";
    let (b, a) = caps_alike(what, &data, BridgeMode::Auto, 0.1);
    assert!(b.in_air_mm > 100.0, "{}", b.in_air_mm);
    assert!(a.in_air_mm <= 1.0, "{}", a.in_air_mm);
}

/// A box chamfered on all four sides, more steeply on two: each layer's gradual ring is
/// wide where the perimeter is moved and a sliver elsewhere, narrower than the perimeter's
/// pull-in. The slicer's wall along the sliver was taken out with the ring and nothing laid
/// there (Cura, 0.6 mm lines: the sides' wall missing on every sloped layer, the layer above
/// then finding them over air). Every rewritten layer keeps its printed area but for the
/// moved perimeter's pull-in.
#[test]
fn a_chamfered_box_keeps_the_walls_of_its_sides() {
    let cura_wide = [
        "machine_nozzle_size=0.6",
        "wall_line_width_0=0.6",
        "wall_line_width_x=0.6",
        "skin_line_width=0.6",
        "infill_line_width=0.6",
        "layer_height=0.3",
    ];
    for (what, data) in by_both(
        "chamfer_box",
        &["--nozzle-diameter", "0.6", "--layer-height", "0.3"],
        ("prusa_i3_mk3", &cura_wide),
        ["chamfer box by PrusaSlicer", "chamfer box by Cura"],
    ) {
        let (new, rep) = rewrite(&data, BridgeMode::Auto);
        assert!(rep.gradual > 5, "{what}: {} gradual rewrites", rep.gradual);
        let (area0, area1) = (areas(&data), areas(&new));
        let rewritten: std::collections::BTreeSet<usize> =
            rep.rewrites.iter().map(|r| r.layer).collect();
        for &l in &rewritten {
            // Lost: printed as sliced, farther than the pull-in (0.05 mm) and the
            // footprints' noise from anything printed as rewritten.
            let lost = printonair::geometry::difference(&area0[l - 1], &offset(&area1[l - 1], 0.1));
            let (a0, lost) = (area0[l - 1].unsigned_area(), lost.unsigned_area());
            assert!(
                lost <= 0.005 * a0,
                "{what}: layer {l} lost {lost:.2} mm2 of {a0:.1} mm2 printed as sliced"
            );
        }
        let (before, after) = before_after(what, &data, &new);
        no_layer_worse(what, &before, &after);
    }
}

/// A gradual overhang's block goes in where the slicer's wall enters its zone and ends where
/// the wall leaves it: the wall goes on from there, not from a hop back across the zone.
/// (Written before the wall, the nozzle went out to the block and back, and the wall then
/// jumped the zone with a retraction and a lift: 60 degree arms by PrusaSlicer, +8.6 % time.)
#[test]
fn a_gradual_overhang_s_block_sits_in_the_wall_it_replaces() {
    let Some(data) = slice("arms60", &[]) else {
        return;
    };
    let (new, rep) = rewrite(&data, BridgeMode::Auto);
    let gradual = rep.rewrites.iter().filter(|r| r.gradual).count();
    assert!(gradual >= 20, "{gradual} gradual rewrites");
    // The XY distance from each gradual block's last extrusion to the next one after it.
    let text = String::from_utf8_lossy(&new);
    let word = |l: &str, k: char| {
        l.split(';')
            .next()
            .unwrap_or("")
            .split_whitespace()
            .find_map(|w| w.strip_prefix(k).and_then(|v| v.parse::<f64>().ok()))
    };
    let (mut at, mut laid, mut in_block) = ([0.0f64; 2], [0.0f64; 2], false);
    let mut since_end = None::<[f64; 2]>;
    let mut hops = Vec::new();
    for l in text.lines() {
        if l.starts_with(";POA_BEGIN") {
            in_block = l.contains("(overhang)");
        }
        if l.starts_with(";POA_END") && in_block {
            since_end = Some(laid);
            in_block = false;
        }
        if l.starts_with("G1 ") || l.starts_with("G0 ") {
            let to = [word(l, 'X').unwrap_or(at[0]), word(l, 'Y').unwrap_or(at[1])];
            if to != at && word(l, 'E').is_some_and(|e| e > 0.0) {
                if let Some(end) = since_end.take() {
                    hops.push((at[0] - end[0]).hypot(at[1] - end[1]));
                }
                laid = to;
            }
            at = to;
        }
    }
    let near = hops.iter().filter(|&&d| d <= 1.0).count();
    assert!(
        near * 10 >= hops.len() * 8,
        "{near} of {} blocks followed by the wall within 1 mm: {hops:?}",
        hops.len()
    );
    let before = check(&data);
    let after = check(&new);
    assert!(
        after.time_s <= 1.06 * before.time_s,
        "time {:.0} -> {:.0} s",
        before.time_s,
        after.time_s
    );
}

/// Every layer between `z` that hung 1.5 mm or more in air is held up, to a tenth, or to
/// 0.3 mm where that is more (a sample or three of the check).
fn sloped_layers_held(
    what: &str,
    before: &CheckReport,
    after: &CheckReport,
    z: std::ops::Range<f64>,
) {
    for (b, a) in before.layers.iter().zip(&after.layers) {
        if z.contains(&b.z) && b.in_air_mm >= 1.5 {
            assert!(
                a.in_air_mm <= (0.1 * b.in_air_mm).max(0.3),
                "{what}: layer {} (Z {}) {:.2} mm in air, {:.2} before",
                b.layer,
                b.z,
                a.in_air_mm,
                b.in_air_mm
            );
        }
    }
}

/// A hemispherical shell open side down: its inner wall closes in by 0.3-0.45 mm a layer
/// between about 57 and 66 degrees from vertical (0.2 mm layers). There the strip past the
/// tolerance lies in the cavity of the layer below and no strand's centre line enters it;
/// it was taken for the part's inside closed round nothing, and three layers kept the whole
/// inner wall in air (32-45 mm each) before loops began higher up.
#[test]
fn a_dome_shells_inner_wall_is_held_on_every_sloped_layer() {
    for (what, before, after) in judge("dome_shell") {
        sloped_layers_held(&what, &before, &after, 10.0..f64::INFINITY);
        cut_to(&what, &before, &after, 0.1);
    }
}

/// A ring tilted 30 degrees on a post, at 0.3 mm layers: most layers carry two short
/// gradual overhangs, 56 in all. Each ring's first loop lies on the wall below and goes at
/// loop speed, and the hops inside a ring's block go without retraction and lift: with the
/// cooling minimum on those loops and a retraction per hop the print took 12 % longer.
#[test]
fn a_tilted_ring_s_many_short_gradual_overhangs_cost_little_time() {
    // Not judge_one: the layer over the crown's last gradual ring (PrusaSlicer, layer 65)
    // stands partly bridged on the moved perimeter, a case of its own.
    for (slicer, d) in slices_with("tilted_ring", &["--layer-height", "0.3"]) {
        let what = format!("tilted_ring by {slicer}");
        let (new, rep) = rewrite(&d, BridgeMode::Auto);
        let (before, after) = (check(&d), check(&new));
        assert!(rep.gradual >= 5, "{what}: {} gradual", rep.gradual);
        assert!(
            after.time_s <= 1.10 * before.time_s,
            "{what}: {:.0} s, {:.0} s before",
            after.time_s,
            before.time_s
        );
        // PrusaSlicer's coarse layers hang most. Its spoke's leading face, a strip under
        // 1 mm2 a layer whose perimeter hangs 2-3 mm, is held too (208 -> 33 mm in air when
        // regions under 1 mm2 were never rewritten; 12 mm now).
        if slicer == "PrusaSlicer" {
            cut_to(&what, &before, &after, 0.08);
        }
        println!(
            "{what}: {} gradual rings, in air {:.1} -> {:.1} mm, time {:.0} -> {:.0} s",
            rep.gradual, before.in_air_mm, after.in_air_mm, before.time_s, after.time_s
        );
    }
}

#[test]
fn frustums_at_42_and_63_degrees_leave_no_layer_worse() {
    // At 0.15 mm layers the 63 degree flare is a thin ring on every layer; the layer above
    // the last rewritten one once stood on a perimeter moved in and hung 64 mm in air.
    for (what, before, after) in judge_with("frustums", &["--layer-height", "0.15"]) {
        // PrusaSlicer's slices of this part differ from run to run (its threads order
        // strands): on one slice in three a layer comes out about 1.1 mm worse (a gradual
        // overhang's moved perimeter beside the slicer's own bridge infill, which leaves
        // 10.8 mm in air there already). 1.5 mm or 15 % of what the slicer left is allowed;
        // the fault this test guards against left 64 mm.
        for (b, a) in before.layers.iter().zip(&after.layers) {
            assert!(
                a.in_air_mm <= b.in_air_mm + 1.5_f64.max(0.15 * b.in_air_mm),
                "{what}: layer {} (Z {}) {:.1} mm in air, {:.1} before",
                b.layer,
                b.z,
                a.in_air_mm,
                b.in_air_mm
            );
        }
    }
}

#[test]
fn sequential_printing_starts_each_copy_on_the_bed() {
    // Two copies printed one after the other: the second copy's first layer comes after the
    // first copy's top, and rests on the bed, not on that top.
    let Some(data) = slice("ledge_post", &["--duplicate", "2", "--complete-objects"]) else {
        return;
    };
    let layers = all_layers(&data);
    let restarts = layers
        .windows(2)
        .filter(|w| w[0].kind == LayerKind::Layer && w[1].z < w[0].z - 1.0)
        .count();
    assert_eq!(
        restarts, 1,
        "the copies are not printed one after the other"
    );
    let (new, rep) = rewrite(&data, BridgeMode::Keep);
    // Only the two ledges are rewritten, each at its copy's ledge height.
    assert_eq!(rep.regions_rewritten, 2, "{:?}", rep.rewrites);
    for r in &rep.rewrites {
        assert!(r.z > 3.0 && r.z < 3.5 && r.loops > 0, "{r:?}");
    }
    let (before, after) = (check(&data), check(&new));
    for (l, (b, a)) in layers
        .iter()
        .filter(|l| l.kind == LayerKind::Layer)
        .zip(before.layers.iter().zip(&after.layers))
    {
        if l.on_bed() {
            assert!(
                b.in_air_mm < 1e-9 && a.in_air_mm < 1e-9,
                "layer {} on the bed",
                b.layer
            );
        }
    }
    assert!(
        after.in_air_mm < 0.05 * before.in_air_mm,
        "{} {}",
        after.in_air_mm,
        before.in_air_mm
    );
}

#[test]
fn objects_of_different_layer_heights_interleave_and_each_rests_on_its_own_layer() {
    // Two parts sliced at 0.2 and 0.15 mm (PrusaSlicer's per-object layer height): their
    // layers interleave in the file (0.35 mm of one, 0.4 of the other, ...), so the layer
    // before a layer is mostly the other part's. Each layer must be judged against what lies
    // under it: only the two real overhangs are found, and their loops are laid at their own
    // part's layer height.
    if !have_prusaslicer() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let amf = dir.path().join("two.amf");
    write_amf(
        &[
            (&part("rect_overhang"), [60.0, 40.0], Some(0.2)),
            (&part("tri_overhang"), [60.0, 120.0], Some(0.15)),
        ],
        &amf,
    );
    let Some(data) = slice_stl(&amf, &[]) else {
        return;
    };
    let layers = all_layers(&data);
    let interleaved = layers.iter().filter(|l| l.rests_on.len() >= 2).count();
    assert!(interleaved > 20, "the parts' layers do not interleave");
    let info = printonair::report::info(&data[..], SlicerConfig::parse(&data), "x").unwrap();
    assert_eq!(info.interleaved_layers, interleaved);
    let (new, rep) = rewrite(&data, BridgeMode::Keep);
    // The rectangle's overhang starts at Z 10 (first layer 10.2), the triangle's too
    // (10.1 or 10.05 in 0.15 mm layers over a 0.2 mm first layer).
    assert_eq!(rep.regions_found, 2, "{:?}", rep.skipped);
    assert_eq!(rep.regions_rewritten, 2);
    for r in &rep.rewrites {
        assert!(r.z > 10.0 && r.z < 10.25 && r.loops > 10, "{r:?}");
    }
    let (before, after) = (check(&data), check(&new));
    println!(
        "two layer heights: in air {:.1} -> {:.1} mm",
        before.in_air_mm, after.in_air_mm
    );
    assert!(
        after.in_air_mm < 0.02 * before.in_air_mm,
        "{} {}",
        after.in_air_mm,
        before.in_air_mm
    );
    for (b, a) in before.layers.iter().zip(&after.layers) {
        assert!(a.in_air_mm <= b.in_air_mm + 0.5, "layer {}: {a:?}", a.layer);
    }
    // Each rewritten layer is held: the slicer's infill ends beside the regions are anchored
    // or cut against the layers each rests on, as in a file of one layer height.
    for r in &rep.rewrites {
        let a = &after.layers[r.layer - 1];
        assert!(
            a.in_air_mm <= 1.0,
            "layer {}: {} mm in air",
            r.layer,
            a.in_air_mm
        );
    }
    // The loops' beads are as wide as planned at their part's layer height (E made for the
    // 0.15 mm part at 0.15 mm, not at the layer's 0.2).
    let fa = printonair::layers::filament_area(1.75);
    let blocks = poa_blocks(&new);
    let in_block = |line: u64| blocks.iter().any(|&(a, b)| a <= line && line <= b);
    let mut loops = 0;
    for l in all_layers(&new) {
        for p in &l.paths {
            if p.length() > 5.0 && p.seg_line.first().is_some_and(|&n| in_block(n)) {
                loops += 1;
                let w = p.e_width(fa);
                assert!(
                    (w - 0.45).abs() < 0.06,
                    "layer {} z {}: bead {w:.3} mm at {}",
                    l.index + 1,
                    l.z,
                    p.height
                );
            }
        }
    }
    assert!(loops > 20, "{loops} loops read back");
}

#[test]
fn support_material_is_left_to_the_slicer() {
    // PrusaSlicer's support is sliced at its own layer heights (0.25 mm beside 0.2 mm part
    // layers) and its lines stand beside the stem. Nothing of it is a region, and the cap
    // rests on its interface, touching it (contact distance 0) or across the default 0.2 mm
    // gap: nothing is rewritten, and no layer gets more in air.
    for (args, regions) in [
        (
            &[
                "--support-material",
                "--support-material-auto",
                "--support-material-contact-distance",
                "0",
            ][..],
            0,
        ),
        (&["--support-material", "--support-material-auto"][..], 0),
    ] {
        let Some(data) = slice("mushroom", args) else {
            return;
        };
        let (new, rep) = rewrite(&data, BridgeMode::Keep);
        assert_eq!(rep.regions_found, regions, "{args:?}: {:?}", rep.rewrites);
        for r in &rep.rewrites {
            assert!(r.z > 9.9 && r.z < 10.5, "{args:?}: {r:?}");
        }
        let (before, after) = (check(&data), check(&new));
        for (b, a) in before.layers.iter().zip(&after.layers) {
            assert!(
                a.in_air_mm <= b.in_air_mm + 0.05,
                "{args:?} layer {}: {} -> {}",
                a.layer,
                b.in_air_mm,
                a.in_air_mm
            );
        }
    }
}

#[test]
fn a_neighbouring_object_does_not_cut_a_region_short() {
    // The rectangle's slab reaches 40 mm from its column, but another object stands 6 mm
    // past its tip: measured to the nearest material below, the region "reaches" less, and
    // its loops once stopped there, leaving the slab's far end in air.
    if !have_prusaslicer() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let amf = dir.path().join("two.amf");
    write_amf(
        &[
            (&part("rect_overhang"), [40.0, 30.0], None),
            (&part("shelves_hole"), [80.0, 120.0], None),
        ],
        &amf,
    );
    let Some(data) = slice_stl(&amf, &[]) else {
        return;
    };
    let (new, rep) = rewrite(&data, BridgeMode::Keep);
    assert!(rep.regions_rewritten >= 2, "{:?}", rep.skipped);
    let (before, after) = (check(&data), check(&new));
    println!(
        "rect beside shelves: in air {:.1} -> {:.1} mm",
        before.in_air_mm, after.in_air_mm
    );
    assert!(
        after.in_air_mm < 0.005 * before.in_air_mm,
        "{} mm in air",
        after.in_air_mm
    );
    for (b, a) in before.layers.iter().zip(&after.layers) {
        assert!(a.in_air_mm <= b.in_air_mm + 0.5, "layer {}: {a:?}", a.layer);
    }
}

#[test]
fn a_multi_material_toolchange_is_no_retraction_to_undo() {
    // PrusaSlicer's single-extruder multi-material unloads ~94 mm of filament with E alone at
    // each toolchange and loads the next one while moving along the wipe tower. Counted as
    // retraction never undone, it summed to metres, and the block's unretract pushed them
    // all through the nozzle (`G1 E9400`).
    let args = [
        "--nozzle-diameter",
        "0.4,0.4",
        "--filament-diameter",
        "1.75,1.75",
        "--wipe-tower",
        "--single-extruder-multi-material",
        "--perimeter-extruder",
        "2",
    ];
    let Some(data) = slice("hook", &args) else {
        return;
    };
    let (new, rep) = rewrite(&data, BridgeMode::Keep);
    assert_eq!(rep.regions_rewritten, 1, "{:?}", rep.skipped);
    let text = String::from_utf8_lossy(&new);
    let mut inside = false;
    for line in text.lines() {
        if line.starts_with(";POA_BEGIN") {
            inside = true;
        } else if line.starts_with(";POA_END") {
            inside = false;
        } else if inside && line.starts_with("G1 E") {
            let e: f64 = line[4..]
                .split_whitespace()
                .next()
                .unwrap()
                .parse()
                .unwrap();
            assert!(e.abs() <= 20.0, "{line}");
        }
    }
    assert!(rep.time_added_s < 60.0, "{} s added", rep.time_added_s);
}

/// One wall, sparse infill printed every other layer at twice the height
/// (`--infill-every-layers 2`): every second layer's beads of its own height rest on the layer
/// before, its infill on the one before that too.
const COMBINED_INFILL: [&str; 6] = [
    "--perimeters",
    "1",
    "--fill-density",
    "5%",
    "--infill-every-layers",
    "2",
];

/// A ledge 67 degrees from vertical: each layer reaches 0.48 mm past the one below. With
/// combined infill, every second layer rests on two (its infill reaches down two): its loops
/// grew from the layer before as sliced, not as rewritten, and its perimeter hung 19.4 mm in
/// air on every such layer.
#[test]
fn a_steep_ledge_with_infill_every_other_layer_is_held_on_every_layer() {
    let Some(d) = slice("steep_ledge", &COMBINED_INFILL) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    assert!(rep.regions_rewritten >= 20, "{rep:?}");
    let (before, after) = before_after("steep ledge, infill every other layer", &d, &new);
    // The ledge's layers (its top solid layers over 5 % infill are the slicer's business).
    held_up_to("steep_ledge", &before, &after, 5.0, 12.6);
    no_layer_worse("steep_ledge", &before, &after);
}

/// A pin with one wall and combined infill: on the layers without infill the pin's wall is a
/// ring round nothing, and the next layer's stroke of infill inside it read as a region over
/// a hole (ten loops laid inside the pin, 13.6 mm of them in air). Sparse infill never closes
/// a real hole; only the washer's first layer is a region.
#[test]
fn a_pin_with_infill_every_other_layer_keeps_its_inside() {
    let Some(d) = slice("pin_washer", &COMBINED_INFILL) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    assert_eq!(rep.regions_found, 1, "{:?}", rep.rewrites);
    for r in &rep.rewrites {
        assert!(r.z > 8.0 && r.z < 8.5, "{r:?}");
    }
    let (before, after) = before_after("pin and washer, infill every other layer", &d, &new);
    held_up_to("pin_washer", &before, &after, 5.0, 8.3);
    no_layer_worse("pin_washer", &before, &after);
}

/// The round arm at 0.15 mm layers: its first layer is the tangent of the half round, a strip
/// 26 mm long and 0.7 mm wide held at the wall only, printed by the slicer as one loop out and
/// back, all in air (51 mm). No ring of the layer below runs beside it and it has no room for
/// a contour: it is printed as a ladder of short strands across it from the wall outward.
#[test]
fn a_narrow_cantilever_is_printed_as_a_ladder_from_the_wall() {
    let Some(d) = slice("round_arm", &["--layer-height", "0.15"]) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = (check(&d), check(&new));
    let tangent = before
        .layers
        .iter()
        .position(|l| l.in_air_mm > 20.0)
        .expect("the arm's tangent layer is in air as sliced");
    let (b, a) = (&before.layers[tangent], &after.layers[tangent]);
    println!(
        "round arm at 0.15 mm, its tangent layer (Z {}): {:.1} -> {:.1} mm in air",
        b.z, b.in_air_mm, a.in_air_mm
    );
    assert!(
        a.in_air_mm <= 1.0,
        "Z {}: {:.1} mm in air",
        b.z,
        a.in_air_mm
    );
    let rungs = rep
        .rewrites
        .iter()
        .find(|r| (r.z - b.z).abs() < 1e-6)
        .expect("the tangent layer rewritten");
    assert!(rungs.loops > 20 && !rungs.gradual, "{rungs:?}");
    held_up("round_arm at 0.15 mm", &before, &after, 5.0);
    no_layer_worse("round_arm at 0.15 mm", &before, &after);
}

/// A mug's handle: its underside's rings are gradual overhangs, and a layer above them (the
/// handle's inner flank) stood on moved perimeters 0.4 mm worse than as sliced, under the
/// old 0.5 mm margin of the "never worse" guard. The guard's margin is the check's own.
#[test]
fn the_layers_over_a_cup_handles_rings_are_no_worse() {
    let Some(d) = slice("cup_handle", &[]) else {
        return;
    };
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = before_after("cup handle", &d, &new);
    cut_to("cup_handle", &before, &after, 0.5);
    no_layer_worse("cup_handle", &before, &after);
}

#[test]
fn copies_on_a_plate_are_each_held_by_one_shared_plan() {
    // Four mushrooms re-sliced by PrusaSlicer (`--duplicate 4`): their caps' surroundings are
    // the same shape moved, so one plan serves all four. Each copy's cap must still be held
    // where it stands: every cap rewritten, with the loops and the length of the others,
    // and the first floating layer held as on a plate of one.
    let Some(data) = slice("mushroom", &["--duplicate", "4"]) else {
        return;
    };
    let (b, a) = caps_alike("four mushrooms", &data, BridgeMode::Keep, 0.01);
    assert!(
        b.in_air_mm > 100.0,
        "the caps hang as sliced: {}",
        b.in_air_mm
    );
    assert!(
        a.in_air_mm <= 4.0,
        "{} mm in air on the caps' layer",
        a.in_air_mm
    );
    assert!(
        a.supported_mm + a.bridged_mm >= 0.99 * a.length_mm,
        "{} of {} held",
        a.supported_mm + a.bridged_mm,
        a.length_mm
    );
}

/// Rewrites a plate of four copies of a part with one floating layer: every copy's region on
/// that layer rewritten with as many loops and the same length (within `tol` mm) as the
/// others, and no layer worse than sliced; that layer's check before and after.
fn caps_alike(what: &str, data: &[u8], bridges: BridgeMode, tol: f64) -> (LayerCheck, LayerCheck) {
    let (new, rep) = rewrite(data, bridges);
    let first = rep
        .rewrites
        .iter()
        .map(|r| r.layer)
        .min()
        .expect("a rewrite");
    let caps: Vec<_> = rep.rewrites.iter().filter(|r| r.layer == first).collect();
    assert_eq!(caps.len(), 4, "{what}: {:?}", rep.rewrites);
    for c in &caps {
        assert!(c.loops > 10, "{what}: {c:?}");
        assert_eq!(c.loops, caps[0].loops, "{what}: {c:?}");
        assert!(
            (c.written_length_mm - caps[0].written_length_mm).abs() < tol,
            "{what}: {c:?}"
        );
    }
    let (before, after) = before_after(what, data, &new);
    no_layer_worse(what, &before, &after);
    let at = |r: &CheckReport| r.layers.iter().find(|l| l.layer == first).cloned().unwrap();
    (at(&before), at(&after))
}

/// A wing's underside rises 1 mm over 22 mm: each layer's region reaches 2.6 mm past the
/// one below, which poa rewrote with its external perimeter pulled in. The loops of each
/// layer grew from the layer below as the slicer had it, the first one 0.08 mm past the
/// moved perimeter's bead and in air (0.25 mm nozzle, 0.12 mm layers: 121 mm in air over
/// 9 layers); they grow from the layer as rewritten and read back.
#[test]
fn a_wing_s_layers_grow_from_the_layer_below_as_rewritten() {
    let fine = [
        "--nozzle-diameter",
        "0.25",
        "--extrusion-width",
        "0.27",
        "--external-perimeter-extrusion-width",
        "0.27",
        "--perimeter-extrusion-width",
        "0.27",
        "--infill-extrusion-width",
        "0.3",
        "--solid-infill-extrusion-width",
        "0.27",
        "--top-infill-extrusion-width",
        "0.25",
        "--first-layer-extrusion-width",
        "0.3",
        "--layer-height",
        "0.12",
        "--first-layer-height",
        "0.15",
    ];
    let Some(d) = slice("wing", &fine) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = before_after("wing, 0.25 mm nozzle", &d, &new);
    let wide: Vec<usize> = rep
        .rewrites
        .iter()
        .filter(|r| !r.gradual && r.loops > 5)
        .map(|r| r.layer)
        .collect();
    // Layers over a wide rewrite, themselves rewritten wide.
    let over: Vec<usize> = wide
        .iter()
        .copied()
        .filter(|l| wide.contains(&(l - 1)))
        .collect();
    assert!(over.len() >= 5, "{:?}", rep.rewrites);
    for l in over {
        let (b, a) = (&before.layers[l - 1], &after.layers[l - 1]);
        assert!(
            a.in_air_mm <= 0.5,
            "layer {l} (Z {}): {:.1} mm in air, {:.1} as sliced",
            b.z,
            a.in_air_mm,
            b.in_air_mm
        );
    }
    held_up("wing, 0.25 mm nozzle", &before, &after, 5.0);
    no_layer_worse("wing, 0.25 mm nozzle", &before, &after);
}

/// PrusaSlicer's flags for a hollow part: no infill, one perimeter, no top layers.
const HOLLOW: [&str; 8] = [
    "--fill-density",
    "0%",
    "--perimeters",
    "1",
    "--top-solid-layers",
    "0",
    "--bottom-solid-layers",
    "2",
];

/// A hollow bracket (`fill_density = 0%`, one perimeter, no top layers): where the fillet
/// starts, PrusaSlicer lays a strip of solid infill along the inside of the plate's wall.
/// The strip holds itself, not the plate's empty inside: taken for the whole inside, the
/// layer got 13 loops over the air in the plate (30.6 mm in air, 1.6 as sliced).
#[test]
fn solid_infill_in_a_hollow_part_holds_only_itself() {
    let Some(d) = slice("fillet_bracket", &HOLLOW) else {
        return;
    };
    let (new, _) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = before_after("hollow fillet bracket", &d, &new);
    no_layer_worse("hollow fillet bracket", &before, &after);
    assert!(
        after.in_air_mm <= 0.1 * before.in_air_mm,
        "{:.1} mm in air, {:.1} as sliced",
        after.in_air_mm,
        before.in_air_mm
    );
}

/// PrusaSlicer's flags for a 0.6 mm nozzle, 0.3 mm layers and 0.68 mm lines.
const WIDE_PS: [&str; 18] = [
    "--nozzle-diameter",
    "0.6",
    "--layer-height",
    "0.3",
    "--first-layer-height",
    "0.3",
    "--extrusion-width",
    "0.68",
    "--external-perimeter-extrusion-width",
    "0.68",
    "--perimeter-extrusion-width",
    "0.68",
    "--solid-infill-extrusion-width",
    "0.68",
    "--infill-extrusion-width",
    "0.68",
    "--top-infill-extrusion-width",
    "0.6",
];

/// Cura's settings for 0.6 mm lines and 0.3 mm layers (Ender 3).
const WIDE_CURA: [&str; 6] = [
    "machine_nozzle_size=0.6",
    "line_width=0.6",
    "wall_line_width_0=0.6",
    "wall_line_width_x=0.6",
    "layer_height=0.3",
    "adhesion_type=none",
];

/// `name` sliced with 0.6 mm lines by both slicers: its first rewritten layer keeps at most
/// `air` mm in air and prints at least `share` of the area the slicer's did (the moved
/// perimeters' inset takes a little off thin parts), there.
fn through_strips(name: &str, what: &str, air: f64, share: f64) {
    let labels = [
        format!("{what} by PrusaSlicer, 0.6 mm nozzle"),
        format!("{what} by Cura, 0.6 mm lines"),
    ];
    let slices = by_both(
        name,
        &WIDE_PS,
        ("creality_ender3", &WIDE_CURA),
        [&labels[0], &labels[1]],
    );
    for (what, d) in slices {
        let (new, rep) = rewrite(&d, BridgeMode::Auto);
        let (before, after) = before_after(what, &d, &new);
        let l = rep.rewrites.iter().map(|r| r.layer).min().expect(what);
        let (b, a) = (&before.layers[l - 1], &after.layers[l - 1]);
        assert!(
            b.in_air_mm > 50.0 && a.in_air_mm <= air,
            "{what}: layer {l} {:.1} mm in air, {:.1} as sliced",
            a.in_air_mm,
            b.in_air_mm
        );
        let (a0, a1) = (areas(&d), areas(&new));
        let (s0, s1) = (a0[l - 1].unsigned_area(), a1[l - 1].unsigned_area());
        assert!(
            s1 >= share * s0,
            "{what}: layer {l} prints {s1:.1} mm2, {s0:.1} as sliced"
        );
        let kept = intersection(&a0[l - 1], &a1[l - 1]).unsigned_area();
        assert!(
            kept >= (share - 0.01) * s0,
            "{what}: {kept:.1} of {s0:.1} mm2 kept"
        );
    }
}

/// A beam out of a post with a hole near its tip. Beside the hole the beam is narrower than
/// a contour and a perimeter on each side: the loop area comes apart there (PrusaSlicer,
/// 0.6 mm nozzle) or keeps a thread (Cura, 0.6 mm lines). The fronts stopped at the hole and
/// the tip past it was left empty, the slicer's strands there taken out (16.5 and 17.8 mm2;
/// 15.4 and 25.6 mm of perimeter in air): they go on through the strips.
#[test]
fn a_beam_s_tip_past_a_hole_gets_loops() {
    through_strips("beam_hole", "beam with a hole", 2.0, 0.98);
}

/// A wheel's rim floating on spokes narrower than a contour and a perimeter each side: the
/// loop area is the rim alone (PrusaSlicer, 0.6 mm nozzle) or the rim and a thread down each
/// spoke (Cura, 0.6 mm lines). No front began (0 loops, 246 mm in air) or none printed in
/// the spokes (79 mm in air); they start at the hub and are printed across the spokes.
#[test]
fn a_wheel_s_rim_is_reached_along_its_spokes() {
    through_strips("wheel", "wheel", 12.0, 0.9);
}

/// The wheel by PrusaSlicer's own defaults with a 0.6 mm nozzle at 0.3 mm layers: the rim's
/// loop area is too narrow for a loop of full width, so the region took the plan of a
/// gradual overhang's thin ring, whose rings are offsets of the wall below: none fitted in
/// the spokes, and the rim's rings, 12 mm out, were laid first, round the rim in air
/// (177 mm in air on the floating layer). A ring laid with nothing laid between it and the
/// wall below means the fronts must cross the spokes as rungs; those loops left 78 mm in air
/// where they met between the spokes, and the rim now takes the ladder, whose rungs cover
/// more of it (0 mm).
#[test]
fn a_wheel_s_rim_is_not_laid_before_its_spokes_with_a_wide_nozzle() {
    let what = "wheel by PrusaSlicer's defaults, 0.6 mm nozzle";
    let Some(d) = slice_defaults(
        "wheel",
        &["--nozzle-diameter", "0.6", "--layer-height", "0.3"],
    ) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = before_after(what, &d, &new);
    let l = rep.rewrites.iter().map(|r| r.layer).min().expect(what);
    assert_layer_held(what, &before, &after, l, 300.0, 5.0);
    // The rungs up one spoke and round the rim are laid before the next spoke's (laid front
    // by front, they hopped from spoke to spoke: 2 961 mm of travel for 767 mm of rungs).
    for r in &rep.rewrites {
        assert!(
            r.inner_travel_mm <= 0.3 * r.written_length_mm,
            "{what}: region {}: {:.1} mm of travel for {:.1} mm written",
            r.region,
            r.inner_travel_mm,
            r.written_length_mm
        );
    }
    let (a0, a1) = (areas(&d), areas(&new));
    let (s0, s1) = (a0[l - 1].unsigned_area(), a1[l - 1].unsigned_area());
    // The layer keeps what the slicer printed, and the layer above is no worse for it.
    assert!(
        s1 >= 0.8 * s0,
        "{what}: layer {l} prints {s1:.1} mm2, {s0:.1} as sliced"
    );
    let above = |r: &CheckReport| r.layers[l].in_air_mm;
    assert!(
        above(&after) <= above(&before) + 1.0,
        "{what}: the layer above"
    );
}

/// A ring held by one bar through its post, the bar 1.5 mm wide: with a 0.6 mm nozzle the
/// loops, grown along the bar, left the ring's far sides to its contour and perimeter (22 mm
/// in air on its first layer); the ring now takes the ladder, out along the bar and round
/// the ring both ways. By PrusaSlicer's samples' settings and Cura the loops hold it.
#[test]
fn a_ring_on_a_bar_through_its_post_is_held_from_the_bar() {
    let mut slices = Vec::new();
    if let Some(d) = slice_defaults(
        "ring_hang",
        &["--nozzle-diameter", "0.6", "--layer-height", "0.3"],
    ) {
        slices.push(("ring on a bar, 0.6 mm nozzle".to_string(), d));
    }
    slices.extend(slices_with("ring_hang", &[]));
    // By Cura with 0.6 mm lines at 0.3 mm: the rungs across the bar stopped a width short of
    // the ring's loop area, and the ring's first loops at the junction hung (1.7 mm in air).
    let ender = [
        "line_width=0.6",
        "wall_line_width_0=0.6",
        "wall_line_count=2",
        "layer_height=0.3",
    ];
    if let Some(d) = slice_cura(&part("ring_hang"), "creality_ender3", &ender) {
        slices.push(("ring on a bar by Cura, 0.6 mm lines".to_string(), d));
    }
    for (what, d) in slices {
        let (new, _) = rewrite(&d, BridgeMode::Auto);
        let (before, after) = before_after(&what, &d, &new);
        held_up(&what, &before, &after, 20.0);
        let most = if what.contains("Cura, 0.6") { 1.0 } else { 2.0 };
        assert!(
            after.in_air_mm <= most && after.time_s <= 1.3 * before.time_s,
            "{what}: {:.1} mm in air, {:.0} s ({:.0} as sliced)",
            after.in_air_mm,
            after.time_s,
            before.time_s
        );
    }
}

/// A hollow torus (no infill, one perimeter, no top layers) closing over its top: a ring
/// one bead wide steps inward over air each layer. Pulled in from both sides for a gradual
/// overhang's moved perimeter, nothing was left of it: the slicer's 176 mm of perimeter
/// went and 1 mm was written. Every rewritten layer prints what the slicer's did.
#[test]
fn a_hollow_torus_keeps_its_perimeters() {
    let Some(d) = slice("torus", &HOLLOW) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    assert!(rep.regions_rewritten > 5, "{:?}", rep.skipped);
    let (a0, a1) = (areas(&d), areas(&new));
    for r in &rep.rewrites {
        let (s0, s1) = (
            a0[r.layer - 1].unsigned_area(),
            a1[r.layer - 1].unsigned_area(),
        );
        assert!(
            s1 >= 0.9 * s0,
            "hollow torus: layer {} prints {s1:.1} mm2, {s0:.1} as sliced",
            r.layer
        );
    }
}

/// A tunnel's ceiling closes at its crown: the rings of its gradual overhang leave a gap the
/// layer above bridges. Poa's perimeter along that gap stays where the slicer put it (the
/// layer above was sliced to stand on it); pulled in by the inset it widened the gap by
/// 0.1 mm under each bridging strand (Cura, Ender 3 at 0.28 mm: 70.8 -> 74.9 mm bridged on
/// the layer above). A tilted ring's crown by PrusaSlicer: the layer above steps out half a
/// bead past the rewritten layer's outline with no region of its own, and bridged 0.5 -> 5.9
/// mm over the perimeter pulled in. Every layer right above a rewritten one bridges and hangs
/// no more than as sliced, within half a millimetre.
#[test]
fn the_layer_over_a_rewrite_bridges_no_more_than_as_sliced() {
    let ender = ["layer_height=0.28", "infill_pattern=grid"];
    let bb = ["bridge_settings_enabled=true", "layer_height=0.12"];
    let mut slices: Vec<(String, Vec<u8>)> = Vec::new();
    for (machine, settings) in [
        ("creality_ender3", &ender[..]),
        ("creality_ender3", &bb[..]),
    ] {
        if let Some(d) = slice_cura(&part("tunnel"), machine, settings) {
            slices.push((format!("tunnel by Cura {machine} {settings:?}"), d));
        }
    }
    for name in ["tunnel", "tilted_ring"] {
        if let Some(d) = slice(name, &[]) {
            slices.push((format!("{name} by PrusaSlicer"), d));
        }
    }
    for (what, d) in &slices {
        let (new, rep) = rewrite(d, BridgeMode::Auto);
        let rewritten: std::collections::BTreeSet<usize> =
            rep.rewrites.iter().map(|r| r.layer).collect();
        assert!(!rewritten.is_empty(), "{what}: nothing rewritten");
        let (before, after) = before_after(what, d, &new);
        cut_to(what, &before, &after, 0.2);
        no_layer_worse(what, &before, &after);
        for (b, a) in before.layers.iter().zip(&after.layers) {
            if rewritten.contains(&b.layer) || !rewritten.contains(&(b.layer - 1)) {
                continue;
            }
            let (held_b, held_a) = (b.bridged_mm + b.in_air_mm, a.bridged_mm + a.in_air_mm);
            assert!(
                held_a <= held_b + 0.5,
                "{what}: layer {} over a rewrite bridges {held_a:.1} mm, {held_b:.1} as sliced",
                b.layer
            );
        }
    }
}

/// Support material that starts on the part (inside a box, under its dome) is printed a
/// contact gap above it so that it comes off: PrusaSlicer's bottom contact distance (one
/// layer), Cura's `support_bottom_distance`. Its first layer stands on the part across that
/// gap, as the part's first layer over support stands on the support across the top gap: the
/// check read the whole first support layer in the box as in air (501 mm of 548 mm for the
/// print, PrusaSlicer).
#[test]
fn support_on_the_part_stands_across_its_bottom_gap() {
    let args = [
        "--support-material",
        "--support-material-auto",
        "--fill-pattern",
        "honeycomb",
    ];
    let mut slices: Vec<(&str, Vec<u8>)> = Vec::new();
    if let Some(d) = slice("dome_box", &args) {
        slices.push(("PrusaSlicer", d));
    }
    if let Some(d) = slice_cura(
        &part("dome_box"),
        "creality_cr10",
        &["support_enable=true", "layer_height=0.1"],
    ) {
        slices.push(("Cura", d));
    }
    for (what, d) in &slices {
        let c = check(d);
        let support_layers = all_layers(d)
            .iter()
            .filter(|l| l.paths.iter().any(|p| p.role.is_support()))
            .count();
        assert!(
            support_layers > 10,
            "{what}: {support_layers} layers of support"
        );
        let worst = c.layers.iter().map(|l| l.in_air_mm).fold(0.0, f64::max);
        assert!(
            worst < 60.0,
            "{what}: a layer keeps {worst:.1} mm in air ({:.1} in all)",
            c.in_air_mm
        );
    }
}

/// A cylinder lying on a narrow block, by PrusaSlicer at 0.15 mm and by Cura at 0.28 mm:
/// its underside is a run of gradual overhangs whose perimeters move onto the layer
/// below. The last region of the run (the slicer's perimeter a little past the moved one
/// below, which still holds it) was reported "no loop fits", as if left in air: now it says
/// it rests as sliced, and it does.
#[test]
fn a_lying_cylinder_s_underside_is_held_and_each_region_left_says_why() {
    let slices = by_both(
        "lying_cylinder",
        &["--layer-height", "0.15"],
        (
            "anycubic_i3_mega",
            &["layer_height=0.28", "infill_pattern=cubic"],
        ),
        ["PrusaSlicer", "Cura"],
    );
    for (slicer, d) in &slices {
        let what = format!("lying cylinder by {slicer}");
        let (new, rep) = rewrite(d, BridgeMode::Auto);
        let (before, after) = (check(d), check(&new));
        assert!(rep.gradual > 4, "{what}: {} gradual regions", rep.gradual);
        for s in &rep.skipped {
            use printonair::emit::{HELD_AS_SLICED, PERIMETER_HELD};
            assert!(
                [HELD_AS_SLICED, PERIMETER_HELD].contains(&s.reason.as_str()),
                "{what}: region {} on layer {}: {}",
                s.region,
                s.layer,
                s.reason
            );
            let (b, a) = (&before.layers[s.layer - 1], &after.layers[s.layer - 1]);
            assert!(
                a.in_air_mm <= b.in_air_mm + 0.05 && a.in_air_mm < 0.5,
                "{what}: layer {} left as sliced has {:.1} mm in air ({:.1} before)",
                s.layer,
                a.in_air_mm,
                b.in_air_mm
            );
        }
        // The underside's run, from its first region up: held.
        let first = rep
            .rewrites
            .iter()
            .map(|r| r.layer)
            .min()
            .expect("rewrites");
        let last = rep
            .rewrites
            .iter()
            .map(|r| r.layer)
            .max()
            .expect("rewrites");
        let air = |c: &CheckReport| -> f64 {
            c.layers[first - 1..last].iter().map(|l| l.in_air_mm).sum()
        };
        assert!(
            air(&after) <= 0.1 * air(&before),
            "{what}: layers {first}-{last}: {:.1} mm in air, {:.1} before",
            air(&after),
            air(&before)
        );
        note(&format!(
            "{what}: {} regions ({} gradual), layers {first}-{last} in air {:.1} -> {:.1} mm, {} left as sliced",
            rep.regions_found,
            rep.gradual,
            air(&before),
            air(&after),
            rep.skipped.len()
        ));
    }
}

/// `part` sliced by PrusaSlicer's own defaults plus `args` and rewritten: the check of the
/// file as sliced and as rewritten, and the rewrite's report (`None`: no slicer here).
fn defaults_rewritten(
    part: &str,
    args: &[&str],
    what: &str,
) -> Option<(CheckReport, CheckReport, printonair::emit::ProcessReport)> {
    let d = slice_defaults(part, args)?;
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    let (before, after) = before_after(what, &d, &new);
    Some((before, after, rep))
}

/// Layer `l` (1 = first) had more than `sliced` mm in air as sliced and has at most `left`.
fn assert_layer_held(
    what: &str,
    before: &CheckReport,
    after: &CheckReport,
    l: usize,
    sliced: f64,
    left: f64,
) {
    let (b, a) = (&before.layers[l - 1], &after.layers[l - 1]);
    assert!(
        b.in_air_mm > sliced && a.in_air_mm <= left,
        "{what}: layer {l} {:.1} mm in air, {:.1} as sliced",
        a.in_air_mm,
        b.in_air_mm
    );
}

/// A wheel by PrusaSlicer's defaults at 0.12 mm layers and three perimeters: where each
/// spoke runs into the rim the slicer's walls leave gaps of 0.3 mm. Grown by the contour's
/// inset they cut the loop area through at every joint, the fronts crossed there printing
/// nothing, and the rim's first loops beside each joint hung (10.8 mm in air on the floating
/// layer, about 1.8 at each of the six joints). A gap smaller than a bead is no hole.
#[test]
fn a_wheel_s_spoke_joints_hold_the_rim_s_first_loops() {
    let args = [
        "--layer-height",
        "0.12",
        "--perimeters",
        "3",
        "--fill-density",
        "20%",
    ];
    let what = "wheel by PrusaSlicer at 0.12 mm";
    let Some((before, after, rep)) = defaults_rewritten("wheel", &args, what) else {
        return;
    };
    let l = rep.rewrites.iter().map(|r| r.layer).min().expect(what);
    assert_layer_held(what, &before, &after, l, 100.0, 1.0);
}

/// A pipe lying on two feet, sliced hollow (0 % infill, two perimeters) by PrusaSlicer's
/// defaults: low on the bore's sides each layer's inner perimeter steps over the void inside
/// the wall below, in air (56 mm a layer), while its external perimeter is held. The rewrite
/// judged the external perimeter alone and left those regions as sliced ("the slicer's
/// perimeter is held as sliced"); every perimeter counts now.
#[test]
fn a_hollow_pipe_s_inner_perimeters_over_its_walls_void_are_not_left_in_air() {
    let what = "hollow lying pipe by PrusaSlicer";
    let Some((before, after, _)) = defaults_rewritten("pipe_lying", &HOLLOW_ROOFED, what) else {
        return;
    };
    for l in [17, 18] {
        assert_layer_held(what, &before, &after, l, 40.0, 3.0);
    }
}
