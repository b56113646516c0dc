//! Cura slices from several machine definitions and settings sets: the real region is found
//! on the first floating layer (not on the layer above), and the rewrite leaves nothing in
//! air there. Cura tags bridged walls and skin with `;BRIDGE` and coasts over the end of a
//! bridged wall, which once left the outline open and the region unseen.

use crate::common::*;

use printonair::check::CheckOptions;
use printonair::layers::SlicerConfig;
use printonair::poa::BridgeMode;
use printonair::report::CheckReport;

/// The deposition check of a file, with the default options.
fn check(d: &[u8]) -> CheckReport {
    printonair::report::check(d, SlicerConfig::parse(d), &CheckOptions::default(), "x").unwrap()
}

/// (machine definition, settings): three printers, bridge settings on and off, grid and
/// lines infill, 0.1-0.2 mm layers.
const SETS: &[(&str, &[&str])] = &[
    (
        "prusa_i3_mk3",
        &[
            "bridge_settings_enabled=true",
            "layer_height=0.2",
            "infill_pattern=grid",
            "infill_sparse_density=15",
            "infill_line_distance=5.33",
        ],
    ),
    (
        "creality_ender3",
        &[
            "bridge_settings_enabled=true",
            "infill_pattern=lines",
            "infill_sparse_density=20",
        ],
    ),
    (
        "anycubic_i3_mega",
        &[
            "layer_height=0.15",
            "wall_line_count=3",
            "infill_pattern=grid",
            "infill_sparse_density=15",
            "infill_line_distance=5.33",
        ],
    ),
];

/// Both test parts rise 10 mm before the slab: the first floating layer is the first whose
/// slicing plane (mid-layer, as Cura and PrusaSlicer slice) lies above.
const LIFT: f64 = 10.0;

fn first_floating_z(data: &[u8]) -> f64 {
    let layers = all_layers(data);
    layers
        .iter()
        .filter(|l| {
            l.kind == printonair::layers::LayerKind::Layer && l.z - l.height / 2.0 > LIFT + 1e-3
        })
        .map(|l| l.z)
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn the_first_floating_layer_is_found_and_nothing_above_it() {
    for (machine, settings) in SETS {
        for part_name in ["rect_overhang", "bridge"] {
            let Some(data) = slice_cura(&part(part_name), machine, settings) else {
                return;
            };
            let config = SlicerConfig::parse(&data);
            let opts = printonair::report::detect_options(&config);
            let rep = printonair::report::analyze(&data[..], config, &opts, part_name).unwrap();
            let z = first_floating_z(&data);
            let what = format!("{part_name} by Cura ({machine}, {settings:?})");
            assert!(!rep.regions.is_empty(), "{what}: no region found");
            for r in &rep.regions {
                assert!(
                    (r.z - z).abs() < 1e-6,
                    "{what}: region {} at Z {} (first floating layer Z {z})",
                    r.id,
                    r.z
                );
            }
            let area: f64 = rep.regions.iter().map(|r| r.area_mm2).sum();
            // The slab's floating part is 40 x 20 mm, less the walls' own width.
            assert!(area > 700.0 && area < 820.0, "{what}: region area {area}");
        }
    }
}

#[test]
fn the_rewrite_leaves_nothing_in_air_on_the_first_floating_layer() {
    for (machine, settings) in SETS {
        let Some(data) = slice_cura(&part("rect_overhang"), machine, settings) else {
            return;
        };
        let what = format!("rect_overhang by Cura ({machine}, {settings:?})");
        let z = first_floating_z(&data);
        let (out, rep) = rewrite(&data, BridgeMode::Keep);
        assert_eq!(rep.regions_rewritten, 1, "{what}");
        let (before, after) = (check(&data), check(&out));
        let at = |c: &CheckReport| {
            c.layers
                .iter()
                .find(|l| (l.z - z).abs() < 1e-6)
                .map(|l| (l.in_air_mm, l.length_mm, l.supported_mm + l.bridged_mm))
                .unwrap()
        };
        let (air0, _, _) = at(&before);
        let (air1, len1, held1) = at(&after);
        assert!(
            air0 > 500.0,
            "{what}: the slice should print the slab in air ({air0} mm)"
        );
        // What stays in air is the slicer's own sparse infill, printed before the walls on
        // that layer, whose tips end a tenth of a millimetre short of the wall below.
        assert!(
            air1 <= 1.0 || air1 <= 0.005 * air0,
            "{what}: {air1} mm still in air ({air0} before)"
        );
        assert!(held1 >= 0.99 * len1, "{what}: {held1} of {len1} mm held");
        // The layer above is no worse.
        let above = |c: &CheckReport| {
            c.layers
                .iter()
                .filter(|l| l.z > z + 1e-6)
                .map(|l| l.in_air_mm)
                .fold(0.0, f64::max)
        };
        assert!(
            above(&after) <= above(&before) + 0.5,
            "{what}: layers above: {} mm in air, {} before",
            above(&after),
            above(&before)
        );
    }
}

#[test]
fn ultigcode_counts_e_in_cubic_millimetres() {
    // Cura's UltiGCode flavour (Ultimaker 2) writes E as a volume: the layer model, the check
    // and the loops poa writes must all read and write it so.
    let Some(data) = slice_cura(&part("rect_overhang"), "ultimaker2", &["layer_height=0.2"]) else {
        return;
    };
    volumetric_loops(&data);
}

/// Cura's "Marlin (Volumetric)" flavour writes E as a volume too (read as 1.75 mm filament,
/// its beads came out 2.4 times too wide and the loops got 2.4 times too little E).
#[test]
fn marlin_volumetric_counts_e_in_cubic_millimetres() {
    let Some(data) = slice_cura(
        &part("rect_overhang"),
        "creality_ender3",
        &[
            "machine_gcode_flavor=RepRap (Volumetric)",
            "layer_height=0.2",
            "adhesion_type=none",
        ],
    ) else {
        return;
    };
    assert!(String::from_utf8_lossy(&data[..200.min(data.len())]).contains("Volumetric"));
    volumetric_loops(&data);
}

/// A volumetric file's rewrite: read as volumes, loops written as beads of the nozzle's width,
/// the floating layer held.
fn volumetric_loops(data: &[u8]) {
    let config = SlicerConfig::parse(data);
    assert!(config.volumetric_e() && config.e_area() == 1.0);
    let (out, rep) = rewrite(data, BridgeMode::Keep);
    assert_eq!(rep.regions_rewritten, 1, "{:?}", rep.skipped);
    let blocks = poa_blocks(&out);
    let in_block = |line: u64| blocks.iter().any(|&(a, b)| a <= line && line <= b);
    let mut loops = 0;
    for l in all_layers(&out) {
        for p in &l.paths {
            if p.length() > 5.0 && p.seg_line.first().is_some_and(|&n| in_block(n)) {
                loops += 1;
                // A 0.4 mm nozzle's loop: the bead as wide as planned, not 2.4 times thinner.
                let w = p.e_width(1.0);
                assert!(
                    (0.3..0.6).contains(&w),
                    "layer {}: bead {w:.3} mm",
                    l.index + 1
                );
            }
        }
    }
    assert!(loops > 20, "{loops} loops");
    // The report counts filament, not E: the material added (a volume, as E is here) over
    // the filament's cross-section.
    let volume = |d: &[u8]| -> f64 {
        all_layers(d)
            .iter()
            .flat_map(|l| l.paths.iter())
            .map(|p| p.e())
            .sum()
    };
    let added = volume(&out) - volume(data);
    let area = printonair::layers::filament_area(config.filament_diameter());
    assert!(
        (rep.filament_added_cm3 * 1000.0 - added).abs() <= 0.01 * added.abs() + 0.1,
        "{} cm3 added, E says {added:.1} mm3",
        rep.filament_added_cm3
    );
    assert!(
        (rep.filament_added_mm - added / area).abs() <= 0.01 * (added / area).abs() + 0.1,
        "{} mm of filament added, E says {:.1}",
        rep.filament_added_mm,
        added / area
    );
    let (before, after) = (check(data), check(&out));
    assert!(before.in_air_mm > 1000.0, "{}", before.in_air_mm);
    assert!(after.in_air_mm < 2.0, "{}", after.in_air_mm);
}

/// A Cura file for a 2.85 mm filament printer of Marlin flavour states no diameter: read as
/// 1.75 mm filament its walls come out 0.4 of the nozzle wide, so poa reads it as 2.85 mm
/// filament, says so, and lays its loops with the slicer's flow (read as 1.75 mm they
/// carried 2.65 times the plastic). A 1.75 mm file is read as it is, and so is one of Cura's
/// Griffin flavour (2.85 mm unless stated) whose walls read right only at 1.75 mm.
#[test]
fn an_unstated_2_85_mm_filament_is_read_from_the_walls() {
    let dir = tempfile::tempdir().unwrap();
    // Cura's Griffin flavour (Ultimaker 3 and S-line) means 2.85 mm filament; set on an
    // Ender 3's profile its E is for 1.75 mm: read as 2.85 mm, the walls came out 2.65
    // times too wide, a mushroom's cap got 26 loops for 58, the loops 0.38 of the flow.
    for (diameter, flavor, said) in [
        ("2.85", "Marlin", Some("E is read as 2.85 mm filament")),
        ("1.75", "Marlin", None),
        ("1.75", "Griffin", Some("E is read as 1.75 mm filament")),
    ] {
        let settings = [
            format!("material_diameter={diameter}"),
            format!("machine_gcode_flavor={flavor}"),
        ];
        let settings: Vec<&str> = settings.iter().map(String::as_str).collect();
        let Some(d) = slice_cura(&part("rect_overhang"), "creality_ender3", &settings) else {
            return;
        };
        let inferred = said.is_some();
        let f = dir.path().join(format!("d{diameter}{flavor}.gcode"));
        std::fs::write(&f, &d).unwrap();
        let o = poa().arg("info").arg(&f).output().unwrap();
        assert!(o.status.success());
        let text = String::from_utf8_lossy(&o.stdout);
        assert_eq!(
            text.contains("E is read as"),
            inferred,
            "{diameter} mm: {text}"
        );
        assert!(
            said.is_none_or(|s| text.contains(s)),
            "{diameter} mm: {text}"
        );
        let out = dir.path().join(format!("d{diameter}{flavor}.poa.gcode"));
        let o = poa_to("process", &f, &out, &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            String::from_utf8_lossy(&o.stdout).contains("note: the file states no filament"),
            inferred
        );
        // The output read with the diameter it was sliced for: poa's strands as wide as
        // the slicer's walls give or take the loop width, not 2.65 times.
        let data = read(&out);
        let mut stated = format!("; filament_diameter = {diameter}\n").into_bytes();
        stated.extend_from_slice(&data);
        let blocks = poa_blocks(&stated);
        assert!(!blocks.is_empty(), "{diameter} mm: nothing rewritten");
        let (layers, _) = read_layers(&stated, false);
        let (mut ours, mut walls) = (Vec::new(), Vec::new());
        for p in layers.iter().flat_map(|l| l.paths.iter()) {
            let length = p.length();
            if length < 1.0 || p.height <= 0.0 {
                continue;
            }
            let e: f64 = p.seg_e.iter().sum();
            let w = printonair::layers::flow_width(
                e,
                length,
                p.height,
                printonair::layers::filament_area(diameter.parse().unwrap()),
            );
            let line = p.seg_line[0];
            if blocks.iter().any(|&(a, b)| (a..=b).contains(&line)) {
                ours.push(w);
            } else if p.role == printonair::layers::Role::ExternalPerimeter {
                walls.push(w);
            }
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (ours, walls) = (median(&mut ours), median(&mut walls));
        assert!(
            (0.75..=1.35).contains(&(ours / walls)),
            "{diameter} mm: poa's strands {ours:.3} mm wide, the slicer's walls {walls:.3}"
        );
    }
}

/// Cura's coasting ends every wall loop 1.6 mm short of its start; with the seams aligned, a
/// ring's walls all opened at one place, the ring read as a C and the hole it walls as
/// filled: a lamp shade's hollow was planned as an overhang and filled with 60-odd loops a
/// layer (print time 1 h 13 min -> 2 h 29 min). Every strand poa writes lies on the part:
/// within a millimetre of what the slicer extruded on that layer.
#[test]
fn coasted_wall_loops_still_wall_their_holes() {
    let Some(d) = slice_cura(&part("shade"), "creality_ender3", &["coasting_enable=true"]) else {
        return;
    };
    let (new, rep) = rewrite(&d, BridgeMode::Auto);
    // The slicer's extrusions per layer, as segments.
    let sliced: Vec<Vec<([f64; 2], [f64; 2])>> = all_layers(&d)
        .iter()
        .filter(|l| l.kind == printonair::layers::LayerKind::Layer)
        .map(|l| {
            l.paths
                .iter()
                .flat_map(|p| p.points.windows(2).map(|w| (w[0], w[1])))
                .collect()
        })
        .collect();
    let near = |q: [f64; 2], segs: &[([f64; 2], [f64; 2])]| {
        segs.iter().any(|&(a, b)| {
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let l2 = dx * dx + dy * dy;
            let t = if l2 > 0.0 {
                (((q[0] - a[0]) * dx + (q[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (q[0] - a[0] - t * dx).hypot(q[1] - a[1] - t * dy) <= 1.0
        })
    };
    let blocks = poa_blocks(&new);
    let mut off = 0.0;
    for l in all_layers(&new)
        .iter()
        .filter(|l| l.kind == printonair::layers::LayerKind::Layer)
    {
        for p in &l.paths {
            let line = p.seg_line.first().copied().unwrap_or(0);
            if !blocks.iter().any(|&(a, b)| (a..=b).contains(&line)) {
                continue;
            }
            for w in p.points.windows(2) {
                let n = (w[0][0] - w[1][0]).hypot(w[0][1] - w[1][1]);
                let k = (n / 0.2).ceil().max(1.0) as usize;
                for i in 0..=k {
                    let t = i as f64 / k as f64;
                    let q = [
                        w[0][0] + t * (w[1][0] - w[0][0]),
                        w[0][1] + t * (w[1][1] - w[0][1]),
                    ];
                    if !near(q, &sliced[l.index]) {
                        off += n / k as f64;
                    }
                }
            }
        }
    }
    assert!(off < 1.0, "{off:.1} mm of poa's strands lie off the part");
    let (before, after) = (check(&d), check(&new));
    assert!(
        after.time_s <= 1.1 * before.time_s,
        "{} regions rewritten: {:.0} s, {:.0} s as sliced",
        rep.regions_rewritten,
        after.time_s,
        before.time_s
    );
}

/// Cura's infill layer thickness (`infill_sparse_thickness`) two and three times the layer
/// height: the sparse infill is laid every second or third layer, taller, on the infill that
/// many layers down. A plain cylinder read 16.4 m "in air" (every infill strand judged
/// against the layer just below, which has none there); the check now holds it.
#[test]
fn combined_infill_is_held_by_the_infill_it_is_laid_on() {
    for thickness in ["0.2", "0.3"] {
        let settings = [
            "layer_height=0.1".to_string(),
            format!("infill_sparse_thickness={thickness}"),
        ];
        let settings: Vec<&str> = settings.iter().map(String::as_str).collect();
        let Some(d) = slice_cura(&part("vase_cylinder"), "creality_ender3", &settings) else {
            return;
        };
        let c = check(&d);
        assert!(
            c.in_air_mm < 1.0,
            "infill {thickness} mm: {:.1} mm in air",
            c.in_air_mm
        );
    }
}

/// The same with one wall round a square column: a layer's wall is four segments, and the
/// walls' width was judged by segment count (eight needed): the infill printed every other
/// layer read in air on every one of them (an inverted pyramid: 2.7 m).
#[test]
fn combined_infill_inside_a_single_square_wall_is_held() {
    let settings = [
        "layer_height=0.2",
        "wall_line_count=1",
        "infill_sparse_thickness=0.4",
        "infill_sparse_density=10",
    ];
    let Some(d) = slice_cura(&part("rect_overhang"), "prusa_i3_mk3", &settings) else {
        return;
    };
    let c = check(&d);
    // The column, below its overhang at Z 10.
    let column: f64 = c
        .layers
        .iter()
        .filter(|l| l.z < 9.9)
        .map(|l| l.in_air_mm)
        .sum();
    assert!(column < 1.0, "the column: {column:.1} mm in air");
}

/// `part` sliced by Cura for an Ender 3 with its first layer 180 % wide at 0.2 mm layers,
/// rewritten (more than `regions` regions): the deposition check as sliced and as
/// rewritten. `None` without CuraEngine.
fn wide_first_layer_rewrite(part_name: &str, regions: usize) -> Option<(CheckReport, CheckReport)> {
    let settings = ["initial_layer_line_width_factor=180", "layer_height=0.2"];
    let data = slice_cura(&part(part_name), "creality_ender3", &settings)?;
    let (out, rep) = rewrite(&data, BridgeMode::Auto);
    assert!(
        rep.regions_rewritten > regions,
        "{part_name}: {} rewritten",
        rep.regions_rewritten
    );
    Some((check(&data), check(&out)))
}

/// Gradual slopes of 30 to 75 degrees side by side, by Cura with a wide first layer: on the
/// layer above the first sloped one, one strip of the zone (no loop reaches it) runs across
/// a 45 and a 55 degree step, and a half-width loop laid all along it under the perimeter
/// left the perimeter over the 55 degree step hanging past its edge (9.3 mm in air on that
/// layer). Where the strip lies well inside the perimeter for a face's length, the loop
/// there is of full width.
#[test]
fn a_strip_across_steps_of_different_slopes_holds_the_perimeter_over_each() {
    let Some((before, after)) = wide_first_layer_rewrite("slope_steps", 10) else {
        return;
    };
    assert!(
        before.in_air_mm > 100.0,
        "{} mm in air as sliced",
        before.in_air_mm
    );
    for l in &after.layers {
        assert!(
            l.in_air_mm <= 1.0,
            "layer at Z {:.2}: {:.1} mm in air after the rewrite",
            l.z,
            l.in_air_mm
        );
    }
}

/// A boat hull by Cura with a wide first layer: at the bow's tip, the thin plan's ring 1 and
/// ring 2 were both half width, a full step (0.27 mm) apart, so the second's centre lay
/// 0.16 mm past the first's edge: 1.5 mm in air on each of two layers the slicer printed
/// without any. A ring after a half-width one goes a quarter width nearer.
#[test]
fn rings_after_a_half_width_ring_rest_on_it() {
    let Some((before, after)) = wide_first_layer_rewrite("hull", 5) else {
        return;
    };
    no_layer_worse("hull by Cura, wide first layer", &before, &after);
}
