//! Region detection on the Print-on-Air specimens, sliced many ways.

use crate::common;

use common::*;
use printonair::geometry::RegionKind;
use printonair::layers::SlicerConfig;
use printonair::report::{self, AnalyzeReport};

struct Specimen {
    name: &'static str,
    kind: RegionKind,
    /// Nominal area of the floating part, mm2.
    area: f64,
}

const SPECIMENS: [Specimen; 4] = [
    Specimen {
        name: "rect_overhang",
        kind: RegionKind::Overhang,
        area: 800.0,
    },
    Specimen {
        name: "bridge",
        kind: RegionKind::Bridge,
        area: 800.0,
    },
    Specimen {
        name: "circ_overhang",
        kind: RegionKind::Overhang,
        area: std::f64::consts::PI * 12.5 * 12.5 / 2.0,
    },
    Specimen {
        name: "tri_overhang",
        kind: RegionKind::Overhang,
        area: 35.0 * 18.75 / 2.0,
    },
];

fn analyze(data: &[u8]) -> AnalyzeReport {
    let config = SlicerConfig::parse(data);
    let opts = report::detect_options(&config);
    report::analyze(data, config, &opts, "test").unwrap()
}

/// Exactly one region, of the right kind and size, on the first layer printed above Z = 10
/// (the slab's underside), and none on any other layer.
fn check(s: &Specimen, data: &[u8], what: &str) {
    let rep = analyze(data);
    let regions = &rep.regions;
    assert_eq!(regions.len(), 1, "{} {what}: {:#?}", s.name, regions);
    let r = &regions[0];
    assert_eq!(r.kind, s.kind, "{} {what}", s.name);
    let rel = (r.area_mm2 - s.area).abs() / s.area;
    assert!(
        rel < 0.05,
        "{} {what}: area {} vs {}",
        s.name,
        r.area_mm2,
        s.area
    );
    // The layer's slice plane (its middle) is the first above the slab's underside at 10 mm.
    let layer_height = data_layer_height(data);
    let mid = r.z - layer_height / 2.0;
    assert!(
        mid > 10.0 && mid < 10.0 + layer_height,
        "{} {what}: region at Z {}",
        s.name,
        r.z
    );
}

fn data_layer_height(data: &[u8]) -> f64 {
    SlicerConfig::parse(data).layer_height().unwrap_or(0.2)
}

#[test]
fn specimens_relative_e() {
    for s in &SPECIMENS {
        let data = read(&sample(&format!("{}_prusa_rel.gcode", s.name)));
        check(s, &data, "relative E");
        let rep = analyze(&data);
        assert!((rep.regions[0].z - 10.2).abs() < 1e-6);
    }
}

#[test]
fn specimens_absolute_e() {
    for s in &SPECIMENS {
        let data = read(&sample(&format!("{}_prusa_abs.gcode", s.name)));
        check(s, &data, "absolute E");
    }
}

#[test]
fn specimens_without_any_comment() {
    for s in &SPECIMENS {
        let data = strip_comments(&read(&sample(&format!("{}_prusa_rel.gcode", s.name))));
        // No config block left: the layer height is what the slice used.
        let rep = analyze(&data);
        assert_eq!(
            rep.regions.len(),
            1,
            "{} stripped: {:#?}",
            s.name,
            rep.regions
        );
        let r = &rep.regions[0];
        assert_eq!(r.kind, s.kind, "{}", s.name);
        assert!((r.z - 10.2).abs() < 1e-6, "{}: {}", s.name, r.z);
        assert!(
            (r.area_mm2 - s.area).abs() / s.area < 0.05,
            "{}: {}",
            s.name,
            r.area_mm2
        );
    }
}

#[test]
fn specimens_at_0_1_mm_layers() {
    for s in &SPECIMENS {
        let Some(data) = slice(s.name, &["--layer-height", "0.1"]) else {
            return;
        };
        check(s, &data, "0.1 mm layers");
    }
}

#[test]
fn specimens_at_0_3_mm_layers() {
    for s in &SPECIMENS {
        let Some(data) = slice(s.name, &["--layer-height", "0.3"]) else {
            return;
        };
        check(s, &data, "0.3 mm layers");
    }
}

#[test]
fn specimens_with_0_6_mm_widths() {
    let w = "0.6";
    for s in &SPECIMENS {
        let Some(data) = slice(
            s.name,
            &[
                "--extrusion-width",
                w,
                "--perimeter-extrusion-width",
                w,
                "--external-perimeter-extrusion-width",
                w,
                "--infill-extrusion-width",
                w,
                "--solid-infill-extrusion-width",
                w,
                "--top-infill-extrusion-width",
                w,
            ],
        ) else {
            return;
        };
        check(s, &data, "0.6 mm widths");
    }
}

#[test]
fn specimens_with_absolute_e_at_0_3_mm() {
    for s in &SPECIMENS {
        let Some(data) = slice(
            s.name,
            &[
                "--layer-height",
                "0.3",
                "--no-use-relative-e-distances",
                "--before-layer-gcode",
                ";BEFORE_LAYER_CHANGE\n;[layer_z]\n",
            ],
        ) else {
            return;
        };
        check(s, &data, "absolute E, 0.3 mm");
    }
}

#[test]
fn stripped_slic3r_and_cura_find_the_overhang() {
    for name in ["rect_overhang_slic3r.gcode", "rect_overhang_cura.gcode"] {
        let rep = analyze(&read(&sample(name)));
        assert_eq!(rep.regions.len(), 1, "{name}: {:#?}", rep.regions);
        assert_eq!(rep.regions[0].kind, RegionKind::Overhang);
        assert!((rep.regions[0].z - 10.2).abs() < 1e-6);
    }
}

#[test]
fn over_air_extrusion_is_reported() {
    let rep = analyze(&read(&sample("rect_overhang_prusa_rel.gcode")));
    let r = &rep.regions[0];
    // The slicer covers the 40 x 20 mm overhang with bridge infill and perimeters.
    assert!(
        r.over_air_length_mm > 40.0 * 20.0 / 0.45 * 0.8,
        "{}",
        r.over_air_length_mm
    );
    assert!(r.extrusions.iter().any(|e| e.role == "bridge infill"));
    assert_eq!(rep.summary.over_air_length_mm, r.over_air_length_mm);
    assert_eq!(r.object.as_deref(), Some("rect_overhang.stl id:0 copy 0"));
}

/// A 0.25 mm nozzle with PrusaSlicer's elephant-foot compensation (0.2 mm, more than the
/// tolerance of 0.135 mm there): the first layer is drawn in from the outline and squashes
/// out to it, so the second layer is no overhang (it was, on every part, and its wall was
/// pulled in for nothing).
#[test]
fn the_layer_on_an_elephant_foot_compensated_first_layer_is_no_overhang() {
    for s in &SPECIMENS[..1] {
        let Some(data) = slice(
            s.name,
            &[
                "--nozzle-diameter",
                "0.25",
                "--extrusion-width",
                "0.27",
                "--external-perimeter-extrusion-width",
                "0.27",
                "--perimeter-extrusion-width",
                "0.27",
                "--first-layer-extrusion-width",
                "0.27",
                "--layer-height",
                "0.08",
                "--first-layer-height",
                "0.15",
                "--elefant-foot-compensation",
                "0.2",
            ],
        ) else {
            return;
        };
        check(s, &data, "0.25 mm nozzle, elephant foot 0.2 mm");
    }
}
