//! `poa ab`: the original and a shifted copy on one plate, Print-on-Air on the copy only.

use crate::common;

use printonair::check::{check_layer, CheckOptions};
use printonair::layers::{filament_area, Layer, LayerKind};

use crate::common::poa;

/// Runs `poa ab INPUT -o OUT` with `args`.
fn ab(input: &std::path::Path, out: &std::path::Path, args: &[&str]) -> std::process::Output {
    crate::common::poa_to("ab", input, out, args)
}

/// The layer with only the paths of one object (None: paths of no object).
fn only(layer: &Layer, object: Option<u32>) -> Layer {
    let mut l = layer.clone();
    l.paths.retain(|p| p.object == object);
    l
}

fn same_points(a: &Layer, b: &Layer, d: [f64; 2]) -> bool {
    let pa: Vec<[f64; 2]> = a
        .paths
        .iter()
        .flat_map(|p| p.points.iter().copied())
        .collect();
    let pb: Vec<[f64; 2]> = b
        .paths
        .iter()
        .flat_map(|p| p.points.iter().copied())
        .collect();
    pa.len() == pb.len()
        && pa
            .iter()
            .zip(&pb)
            .all(|(p, q)| (p[0] + d[0] - q[0]).abs() < 2e-3 && (p[1] + d[1] - q[1]).abs() < 2e-3)
}

#[test]
fn ab_plate_prints_the_original_unchanged_and_a_supported_copy() {
    let d = [60.0, 0.0];
    let dir = tempfile::tempdir().unwrap();
    let input = common::sample("tri_overhang_prusa_rel.gcode");
    let out = dir.path().join("ab.gcode");
    let o = ab(&input, &out, &["--offset", "60,0"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let before: Vec<Layer> = common::all_layers(&std::fs::read(&input).unwrap())
        .into_iter()
        .filter(|l| l.kind == LayerKind::Layer)
        .collect();
    let data = std::fs::read(&out).unwrap();
    let (after, reader) = common::read_layers(&data, false);
    let after: Vec<Layer> = after
        .into_iter()
        .filter(|l| l.kind == LayerKind::Layer)
        .collect();
    assert_eq!(
        before.len(),
        after.len(),
        "one layer per layer: both copies print in it"
    );
    let names = reader.objects().to_vec();
    let orig = names.iter().position(|n| n.ends_with("copy 0")).unwrap() as u32;
    let copy = names.iter().position(|n| n.ends_with("copy 1")).unwrap() as u32;

    let fa = filament_area(1.75);
    let opts = CheckOptions::default();
    let mut rewritten = Vec::new();
    for (i, (b, a)) in before.iter().zip(&after).enumerate() {
        // The original's strands are the slicer's, untouched, in every layer.
        let b_part = only(b, Some(orig));
        assert!(
            same_points(&b_part, &only(a, Some(orig)), [0.0, 0.0]),
            "layer {}",
            i + 1
        );
        // The copy is the original shifted, except where Print-on-Air rewrote it.
        let c = only(a, Some(copy));
        if !same_points(&b_part, &c, d) {
            rewritten.push(i);
            let below = only(&after[i - 1], Some(copy));
            let r = check_layer(&[&below], &c, fa, &opts, false);
            let ok = (r.supported_mm + r.bridged_mm) / r.length_mm;
            // As good as the part rewritten on its own (the slicer's own infill ends leave a
            // couple of mm in air next to the region there too).
            let single = dir.path().join("single.gcode");
            let o = poa()
                .arg("process")
                .arg(&input)
                .arg("-o")
                .arg(&single)
                .output()
                .unwrap();
            assert!(o.status.success());
            let alone = common::all_layers(&std::fs::read(&single).unwrap());
            let alone: Vec<&Layer> = alone
                .iter()
                .filter(|l| l.kind == LayerKind::Layer)
                .collect();
            let s = check_layer(&[alone[i - 1]], alone[i], fa, &opts, false);
            assert!(ok >= 0.99, "copy layer {}: {r:?}", i + 1);
            assert!(
                r.in_air_mm <= s.in_air_mm + 1e-6,
                "copy layer {}: {r:?} vs {s:?}",
                i + 1
            );
            assert!(r.in_air_mm <= 1.0 + s.in_air_mm);
            // The original's same layer still prints over air, as sliced.
            let orig_r = check_layer(
                &[&only(&after[i - 1], Some(orig))],
                &only(a, Some(orig)),
                fa,
                &opts,
                false,
            );
            assert!(orig_r.in_air_mm > 10.0, "{orig_r:?}");
        }
    }
    assert_eq!(
        rewritten.len(),
        1,
        "only the copy's floating layer changes: {rewritten:?}"
    );
    assert!((after[rewritten[0]].z - 10.2).abs() < 1e-6);
}

#[test]
fn ab_refuses_a_copy_off_the_bed_or_on_the_part() {
    let dir = tempfile::tempdir().unwrap();
    let input = common::sample("tri_overhang_prusa_rel.gcode");
    for offset in ["300,0", "0,-150", "5,0"] {
        let out = dir.path().join("ab.gcode");
        let o = ab(&input, &out, &["--offset", offset]);
        assert_eq!(o.status.code(), Some(1), "{offset}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("leave the bed") || err.contains("within"),
            "{err}"
        );
        assert!(err.lines().count() <= 2, "{err}");
        assert!(!out.exists());
    }
}

/// Klipper labels: each object's copy gets its own EXCLUDE_OBJECT name and definition, and
/// prints the original's strands shifted.
#[test]
fn ab_with_klipper_labels_defines_and_names_every_copy() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ab.gcode");
    let o = ab(
        &common::sample("klipper_objects.gcode"),
        &out,
        &["--offset", "0,30", "--bed", "0,0,250,210"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let data = std::fs::read(&out).unwrap();
    let text = String::from_utf8_lossy(&data);
    for name in ["cube_a_id_0_copy_0_poa_copy", "cube_b_id_1_copy_0_poa_copy"] {
        assert!(
            text.contains(&format!("EXCLUDE_OBJECT_DEFINE NAME={name} ")),
            "{name}"
        );
    }
    let (layers, reader) = common::read_layers(&data, false);
    let names = reader.objects().to_vec();
    assert_eq!(names.len(), 4, "{names:?}");
    for l in layers.iter().filter(|l| l.kind == LayerKind::Layer) {
        for (i, n) in names
            .iter()
            .enumerate()
            .filter(|(_, n)| !n.ends_with("_poa_copy"))
        {
            let copy = names
                .iter()
                .position(|c| *c == format!("{n}_poa_copy"))
                .unwrap();
            assert!(same_points(
                &only(l, Some(i as u32)),
                &only(l, Some(copy as u32)),
                [0.0, 30.0]
            ));
        }
    }
}

/// Cura's `;MESH:` labels get a copy of their own (so only the copy is rewritten); a file in
/// inches is refused, since a shift in mm would land elsewhere.
#[test]
fn ab_handles_cura_labels_and_refuses_inches() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ab.gcode");
    let o = ab(
        &common::sample("rect_overhang_cura.gcode"),
        &out,
        &["--offset", "80,0", "--bed", "0,0,300,300"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("rect_overhang.stl_poa_copy") && stdout.contains("1 region(s)"),
        "{stdout}"
    );
    let data = std::fs::read(&out).unwrap();
    let (_, reader) = common::read_layers(&data, false);
    assert_eq!(
        reader.objects(),
        ["rect_overhang.stl", "rect_overhang.stl_poa_copy"]
    );

    let out = dir.path().join("inch.gcode");
    let o = ab(
        &common::sample("inches_g20.gcode"),
        &out,
        &["--offset", "80,0", "--bed", "0,0,300,300"],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("inches"));
    assert!(!out.exists());
}
