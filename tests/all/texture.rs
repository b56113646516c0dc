//! `poa texture`: speed modulation at constant extrusion on a PrusaSlicer cylinder and box.
//! E per second along every textured external perimeter, by poa's estimator on the output,
//! is the slicer's; no other line changes; the bead widths the output lays follow the
//! picture; commanded speeds stay in the range; the contrast report is the hand calculation;
//! bad pictures, roles and ranges are refused with one line and nothing written.

use std::path::Path;

use printonair::estimate::{feed_text, Estimator, Limits};
use printonair::layers::{LayerKind, Role, SlicerConfig};
use printonair::machine::Machine;

use crate::common::{all_layers, part, poa, poa_to, read, sample, slice_mesh, slice_stl, Mesh};

/// External perimeter paths: (source lines, total E, length, nominal E per second).
fn perimeters(text: &[u8]) -> Vec<(Vec<u64>, f64, f64, f64)> {
    all_layers(text)
        .iter()
        .filter(|l| l.kind == LayerKind::Layer)
        .flat_map(|l| l.paths.iter())
        .filter(|p| p.role == Role::ExternalPerimeter)
        .map(|p| {
            let e: f64 = p.seg_e.iter().sum();
            let len = p.length();
            (p.seg_line.clone(), e, len, e / len * p.feed / 60.0)
        })
        .collect()
}

/// Time (s) of each line's move by poa's estimator.
fn line_durations(text: &[u8]) -> std::collections::HashMap<u64, f64> {
    let config = SlicerConfig::parse(text);
    let mut est = Estimator::new(Limits::from_config(&config)).with_marks(1e-9);
    let mut machine = Machine::new();
    feed_text(&mut est, &mut machine, text, 0);
    let marks = est.finish().1;
    let mut out = std::collections::HashMap::new();
    let mut before = 0.0;
    for (line, t) in marks {
        *out.entry(line).or_insert(0.0) += t - before;
        before = t;
    }
    out
}

/// Lines that stay the slicer's whatever the texture does: everything but extrusion moves,
/// progress lines and the statistics footer.
fn untouched(text: &[u8]) -> Vec<&[u8]> {
    text.split(|&b| b == b'\n')
        .filter(|l| {
            let extrusion =
                (l.starts_with(b"G1 ") || l.starts_with(b"G2 ") || l.starts_with(b"G3 "))
                    && l.split(|&b| b == b';').next().unwrap().contains(&b'E');
            let footer = l.starts_with(b"; filament used")
                || l.starts_with(b"; total filament")
                || l.starts_with(b"; estimated printing time");
            // `G92 E` lines: the texture puts an absolute E counter back in step with one
            // (the Cura test checks that the slicer's own stay where they were).
            !(extrusion || l.starts_with(b"M73 ") || l.starts_with(b"G92 E") || footer)
        })
        .collect()
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    sab / (saa * sbb).sqrt()
}

/// Textures `text` through the library and checks every claim of the module doc.
fn judge(what: &str, text: &[u8], spec: &printonair::texture::Spec) {
    let config = SlicerConfig::parse(text);
    let totals = printonair::progress::Totals::of(&config);
    let t = printonair::texture::texture_text(text, &config, spec, totals).expect(what);
    let out = &t.text;
    // 1. E per second of every textured external perimeter, timed by the estimator on the
    //    output, within 2 % of the slicer's.
    let before = perimeters(text);
    let after = perimeters(out);
    assert_eq!(before.len(), after.len(), "{what}: external perimeters");
    let times = line_durations(out);
    let mut worst: f64 = 0.0;
    for (b, a) in before.iter().zip(&after) {
        let time: f64 =
            a.0.iter()
                .collect::<std::collections::BTreeSet<_>>()
                .iter()
                .map(|l| times.get(l).copied().unwrap_or(0.0))
                .sum();
        if time <= 0.0 || b.2 < 2.0 {
            continue;
        }
        worst = worst.max((a.1 / time / b.3 - 1.0).abs());
    }
    assert!(
        worst <= 0.02,
        "{what}: E per second off the slicer's by {:.1} %",
        100.0 * worst
    );
    // 2. Nothing else changed.
    let (a, b) = (untouched(text), untouched(out));
    if let Some(k) = (0..a.len().max(b.len())).find(|&k| a.get(k) != b.get(k)) {
        panic!(
            "{what}: a line outside the texture changed: {:?} became {:?}",
            a.get(k).map(|l| String::from_utf8_lossy(l)),
            b.get(k).map(|l| String::from_utf8_lossy(l))
        );
    }
    // 3. Commanded speeds within the range.
    for p in &t.pieces {
        assert!(
            p.target >= spec.speeds[0] - 1e-9 && p.target <= spec.speeds[1] + 1e-9,
            "{what}: {}",
            p.target
        );
    }
    // 4. The bead widths follow the picture where texels are longer than the smallest the
    //    acceleration renders: pieces at least that far from a change of the picture.
    let fa = printonair::layers::filament_area(config.filament_diameter());
    let texel = t.min_texel(spec.speeds);
    let (mut dark, mut width) = (Vec::new(), Vec::new());
    for k in 0..t.pieces.len() {
        let p = &t.pieces[k];
        let steady = (k.saturating_sub(8)..(k + 8).min(t.pieces.len())).all(|j| {
            let q = &t.pieces[j];
            (q.darkness - p.darkness).abs() < 0.05
                || ((q.to[0] - p.to[0]).hypot(q.to[1] - p.to[1]) > texel + 2.0 * t.piece_len)
                || (q.to[2] - p.to[2]).abs() > 1e-6
        });
        if steady {
            dark.push(p.darkness);
            width.push(t.width(k, spec.mode, fa));
        }
    }
    let r = pearson(&dark, &width);
    assert!(
        dark.len() > 500 && r >= 0.9,
        "{what}: widths correlate {r:.3} with the picture over {} pieces",
        dark.len()
    );
    println!(
        "{what}: {} pieces, E/s within {:.2} %, width~picture r = {r:.3}",
        t.pieces.len(),
        100.0 * worst
    );
}

fn spec(source: printonair::texture::Source, mapping: &str) -> printonair::texture::Spec {
    printonair::texture::Spec {
        source,
        mapping: printonair::texture::Mapping::parse(mapping).unwrap(),
        size: Some([10.0, 6.0]),
        offset: [0.0, 0.0],
        speeds: [15.0, 40.0],
        roles: vec![Role::ExternalPerimeter],
        invert: false,
        mode: printonair::texture::Mode::Constant,
        max_flow: None,
        center: None,
    }
}

#[test]
fn a_cylinder_and_a_box_keep_the_slicers_extrusion_rate_under_a_texture() {
    use printonair::texture::Source;
    if let Some(cyl) = slice_stl(&part("vase_cylinder"), &[]) {
        judge(
            "cylinder, stripes",
            &cyl,
            &spec(Source::Stripes, "cylindrical"),
        );
        judge(
            "cylinder, checker",
            &cyl,
            &spec(Source::Checker, "cylindrical"),
        );
    }
    let mut mesh = Mesh::default();
    mesh.cuboid([0.0, 0.0, 0.0], [25.0, 15.0, 10.0]);
    if let Some(boxy) = slice_mesh(&mesh, &["--center", "125,105"]) {
        judge(
            "box, checker wrapped",
            &boxy,
            &spec(Source::Checker, "wrap"),
        );
        judge(
            "box, stripes planar",
            &boxy,
            &spec(Source::Stripes, "planar-x"),
        );
    }
}

/// A PNG file with this header and pixels (8-bit grey), or with no pixel data at all.
fn png_file(path: &Path, w: u32, h: u32, pixels: Option<&[u8]>) {
    match pixels {
        Some(px) => {
            let f = std::fs::File::create(path).unwrap();
            let mut enc = png::Encoder::new(std::io::BufWriter::new(f), w, h);
            enc.set_color(png::ColorType::Grayscale);
            enc.set_depth(png::BitDepth::Eight);
            enc.write_header().unwrap().write_image_data(px).unwrap();
        }
        None => {
            // Signature and an IHDR claiming w x h, then the end: what a hostile file holds.
            let chunk = |kind: &[u8], data: &[u8]| {
                let mut c = (data.len() as u32).to_be_bytes().to_vec();
                c.extend_from_slice(kind);
                c.extend_from_slice(data);
                let mut h = crc32fast::Hasher::new();
                h.update(kind);
                h.update(data);
                c.extend_from_slice(&h.finalize().to_be_bytes());
                c
            };
            let mut ihdr = w.to_be_bytes().to_vec();
            ihdr.extend_from_slice(&h.to_be_bytes());
            ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
            let mut f = b"\x89PNG\r\n\x1a\n".to_vec();
            f.extend(chunk(b"IHDR", &ihdr));
            f.extend(chunk(b"IEND", &[]));
            std::fs::write(path, f).unwrap();
        }
    }
}

#[test]
fn a_picture_is_printed_and_the_report_is_the_hand_calculation() {
    let Some(cyl) = slice_stl(&part("vase_cylinder"), &[]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cyl.gcode");
    std::fs::write(&input, &cyl).unwrap();
    // A picture: dark left half, light right half, 32 x 16 pixels.
    let pic = dir.path().join("half.png");
    let px: Vec<u8> = (0..16 * 32)
        .map(|i| if i % 32 < 16 { 0 } else { 255 })
        .collect();
    png_file(&pic, 32, 16, Some(&px));
    let out = dir.path().join("out.gcode");
    let prev = dir.path().join("prev");
    let o = poa_to(
        "texture",
        &input,
        &out,
        &[
            "--image",
            pic.to_str().unwrap(),
            "--size",
            "12,6",
            "--speed-range",
            "15,40",
            "--preview",
            prev.to_str().unwrap(),
        ],
    );
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // (40^2 - 15^2) / (2 x a), with a the file's extruding acceleration.
    let config = SlicerConfig::parse(&cyl);
    let a = Limits::from_config(&config).extruding;
    let want = (40.0f64.powi(2) - 15.0f64.powi(2)) / (2.0 * a);
    assert!(
        said.contains(&format!("needs {want:.2} mm at {a:.0} mm/s2")),
        "{said} (want {want:.2} at {a})"
    );
    let page = std::fs::read_to_string(prev.join("index.html")).unwrap();
    assert!(page.matches("<svg").count() == 3 && page.contains("bead width"));
    assert!(page.contains("layer 38 at Z") || page.contains("a layer of the output"));
    // poa check: nothing in air that the slice did not have.
    let c = poa().arg("check").arg("--json").arg(&out).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&c.stdout).unwrap();
    assert!(v["in_air_mm"].as_f64().unwrap() < 1.0, "{v}");
}

#[test]
fn bad_pictures_roles_ranges_and_files_get_one_line_and_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("rect_overhang_prusa_rel.gcode");
    let out = dir.path().join("out.gcode");
    let empty = dir.path().join("empty.png");
    png_file(&empty, 0, 0, None);
    let huge = dir.path().join("huge.png");
    png_file(&huge, 100_000, 100_000, None);
    let text = dir.path().join("text.png");
    std::fs::write(&text, "not a picture").unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["--image".into(), "/no/such.png".into()], "such.png"),
        (vec!["--image".into(), s(&text)], "not a PNG"),
        (vec!["--image".into(), s(&empty)], "0 x 0"),
        (vec!["--image".into(), s(&huge)], "100000 x 100000"),
        (
            vec![
                "--pattern".into(),
                "checker".into(),
                "--roles".into(),
                "".into(),
            ],
            "--roles is empty",
        ),
        (
            vec![
                "--pattern".into(),
                "checker".into(),
                "--speed-range".into(),
                "40,15".into(),
            ],
            "LOW <= HIGH",
        ),
        (vec!["--pattern".into(), "text:a~b".into()], "no `~`"),
    ];
    for (args, want) in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = poa_to("texture", &input, &out, &args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(want), "{args:?}: {err}");
        assert!(err.trim().lines().count() <= 2, "{err}");
        assert!(!out.exists(), "{args:?} wrote a file");
    }
    // A file without external perimeters (only solid infill): said, nothing written.
    let infill = dir.path().join("infill.gcode");
    std::fs::write(
        &infill,
        ";LAYER_CHANGE\n;Z:0.2\n;HEIGHT:0.2\nM83\nG1 Z0.2 F600\n;TYPE:Solid infill\n;WIDTH:0.45\nG1 X10 Y10 F3000\nG1 X30 Y10 E0.7 F1500\nG1 X30 Y10.4 E0.02\nG1 X10 Y10.4 E0.7\n",
    )
    .unwrap();
    let o = poa_to("texture", &infill, &out, &["--pattern", "checker"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("no external perimeter"),
        "{err}"
    );
    assert!(!out.exists());
    // The input is never the output.
    let copy = dir.path().join("copy.gcode");
    std::fs::write(&copy, read(&input)).unwrap();
    let o = poa_to("texture", &copy, &copy, &["--pattern", "checker"]);
    assert!(!o.status.success());
    assert_eq!(read(&copy), read(&input));
}

#[test]
fn slicer_mode_rewrites_and_textures_in_one_run_or_leaves_the_file_alone() {
    let dir = tempfile::tempdir().unwrap();
    let original = read(&sample("circ_overhang_prusa_rel.gcode"));
    let file = dir.path().join("part.gcode");
    std::fs::write(&file, &original).unwrap();
    let o = poa()
        .args(["--texture", "checker", "--texture-size", "8,4"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let both = read(&file);
    // Print-on-Air's block is there, and the external perimeters are cut into texels.
    assert!(both.windows(11).any(|w| w == b";POA_BEGIN "));
    let pieces = |t: &[u8]| perimeters(t).iter().map(|p| p.0.len()).sum::<usize>();
    assert!(pieces(&both) > 2 * pieces(&original), "not textured");
    // The same as the rewrite alone, less nothing in air.
    let alone = dir.path().join("alone.gcode");
    assert!(poa_to(
        "process",
        &sample("circ_overhang_prusa_rel.gcode"),
        &alone,
        &[]
    )
    .status
    .success());
    let air = |p: &Path| {
        let c = poa().arg("check").arg("--json").arg(p).output().unwrap();
        serde_json::from_slice::<serde_json::Value>(&c.stdout).unwrap()["in_air_mm"]
            .as_f64()
            .unwrap()
    };
    assert!(
        air(&file) <= air(&alone) + 0.5,
        "{} vs {}",
        air(&file),
        air(&alone)
    );
    // A texture that cannot be made leaves the file as the slicer wrote it.
    std::fs::write(&file, &original).unwrap();
    let o = poa()
        .args(["--texture", "text:~"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert_eq!(read(&file), original);
}

#[test]
fn without_role_comments_each_islands_outer_loop_is_textured() {
    use printonair::texture::Source;
    // The same slice with and without its comments: the outermost loops found in the plain
    // file are (nearly) the external perimeters the comments name, never the skirt.
    let with = read(&sample("rect_overhang_prusa_rel.gcode"));
    let plain = read(&sample("rect_overhang_nocomments.gcode"));
    let ends = |text: &[u8]| -> std::collections::HashSet<(i64, i64, i64)> {
        let config = SlicerConfig::parse(text);
        let totals = printonair::progress::Totals::of(&config);
        let t = printonair::texture::texture_text(
            text,
            &config,
            &spec(Source::Checker, "wrap"),
            totals,
        )
        .unwrap();
        t.pieces
            .iter()
            .map(|p| {
                (
                    (p.to[0] * 100.0).round() as i64,
                    (p.to[1] * 100.0).round() as i64,
                    (p.to[2] * 100.0).round() as i64,
                )
            })
            .collect()
    };
    let (a, b) = (ends(&with), ends(&plain));
    // The first layer (where a skirt of two loops surrounds the part) is left alone.
    assert!(
        b.iter().all(|p| p.2 > 30),
        "a first-layer loop was textured"
    );
    let a: std::collections::HashSet<_> = a.into_iter().filter(|p| p.2 > 30).collect();
    let common = a.intersection(&b).count() as f64;
    assert!(
        common >= 0.9 * a.len() as f64,
        "{common} of {} perimeter pieces found",
        a.len()
    );
    assert!(
        common >= 0.85 * b.len() as f64,
        "{} pieces textured, {common} on perimeters",
        b.len()
    );
}

#[test]
fn a_cura_slice_in_absolute_e_keeps_every_other_line_byte_for_byte() {
    use printonair::texture::Source;
    let Some(cura) = crate::common::slice_cura(&part("vase_cylinder"), "creality_ender3", &[])
    else {
        return;
    };
    assert!(
        cura.windows(4).any(|w| w == b"\nM82"),
        "Cura writes absolute E"
    );
    judge(
        "cura cylinder, stripes",
        &cura,
        &spec(Source::Stripes, "cylindrical"),
    );
    // Every input line but the textured moves (and progress lines) is in the output, in
    // order: the E counter is put back with one `G92 E` after each textured stretch, so no
    // later move is rewritten for its E.
    let config = SlicerConfig::parse(&cura);
    let totals = printonair::progress::Totals::of(&config);
    let t = printonair::texture::texture_text(
        &cura,
        &config,
        &spec(Source::Stripes, "cylindrical"),
        totals,
    )
    .unwrap();
    let textured: std::collections::HashSet<u64> =
        perimeters(&cura).into_iter().flat_map(|p| p.0).collect();
    let out: Vec<&[u8]> = t.text.split(|&b| b == b'\n').collect();
    let mut k = 0usize;
    let mut resets = 0usize;
    for (i, line) in cura.split(|&b| b == b'\n').enumerate() {
        if textured.contains(&(i as u64 + 1)) || line.starts_with(b"M73 ") {
            continue;
        }
        while k < out.len() && out[k] != line {
            resets += usize::from(out[k].starts_with(b"G92 E"));
            k += 1;
        }
        assert!(
            k < out.len(),
            "input line {} missing or changed: {}",
            i + 1,
            String::from_utf8_lossy(line)
        );
        k += 1;
    }
    assert!(
        resets > 0 && resets <= 2 * perimeters(&cura).len(),
        "{resets} E resets"
    );
}
