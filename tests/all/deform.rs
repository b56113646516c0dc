//! `poa deform` (layer-less helical printing): geometry of each preset measured from the
//! output's points, E per mm against the cross-section rule, every point within the chord
//! tolerance of the mapping, the printability check, and inputs from PrusaSlicer, Cura and
//! a file without comments.

use std::path::Path;

use printonair::helix::{self, deform::Deform, deform::Frame, deform::Spec};
use printonair::layers::SlicerConfig;

use crate::common::{poa, poa_to, read, sample, slice_cura, strip_comments};
use printonair::fiveaxis::to_segment;

/// The extrusion moves of `text` with line numbers: (from, to, e).
fn extrusions(text: &[u8]) -> Vec<(u64, [f64; 3], [f64; 3], f64)> {
    let mut v = Vec::new();
    helix::moves(text, |m, _| {
        if m.is_extrusion() {
            v.push((m.line, m.from, m.to, m.e));
        }
    });
    v
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

struct Run {
    input: Vec<u8>,
    output: Vec<u8>,
    helix: helix::Helix,
    map: Deform,
}

fn deform(input: Vec<u8>, spec: &Spec) -> Run {
    let config = SlicerConfig::parse(&input);
    let d = helix::deform_text(&input, &config, spec, false).expect("deformed");
    let fa = printonair::layers::filament_area(config.filament_diameter());
    let map = Deform::new(spec, &d.helix, fa).unwrap();
    assert!(d.check.ok(), "{:?}", d.check.first);
    assert!(d.check.points > 10_000);
    Run {
        input,
        output: d.text,
        helix: d.helix,
        map,
    }
}

/// Every output helix point within the chord tolerance (+ the 0.001 mm of the written
/// digits) of the mapped input path, and the mapped input path within it of the output.
fn follows_the_mapping(run: &Run) {
    let h = &run.helix;
    let out = extrusions(&run.output);
    let inp: Vec<_> = extrusions(&run.input)
        .into_iter()
        .filter(|m| m.0 >= h.first_line && m.0 <= h.last_line)
        .collect();
    // Mapped input points, densely, each must lie on the output path.
    let out_h = helix::find(&run.output).unwrap();
    // All output extrusions: where the output's own helix starts may differ by a few
    // moves (Z written to 0.001 mm makes the first pieces of a slow rise flat).
    let segs: Vec<_> = out.iter().collect();
    let mut k: usize = 0;
    let mut worst: f64 = 0.0;
    for m in &inp {
        for i in 0..=4 {
            let f = i as f64 / 4.0;
            let p = run
                .map
                .point([0, 1, 2].map(|j| m.1[j] + (m.2[j] - m.1[j]) * f));
            // The output runs in the same order: search near the last match.
            let lo = k.saturating_sub(50);
            let hi = (k + 200).min(segs.len());
            let nearest = |r: std::ops::Range<usize>| {
                r.map(|s| (to_segment(p, segs[s].1, segs[s].2), s))
                    .fold((f64::INFINITY, k), |a, b| if b.0 < a.0 { b } else { a })
            };
            let mut found = nearest(lo..hi);
            if found.0 > 0.05 {
                // Lost the place (a slicer's flat piece, a travel): search everywhere.
                found = nearest(0..segs.len());
            }
            let (best, at) = found;
            k = at;
            if best > 0.05 && worst <= 0.05 {
                eprintln!(
                    "first miss: input line {} at {:?}: {best} mm (output helix lines {}..{})",
                    m.0, p, out_h.first_line, out_h.last_line
                );
            }
            worst = worst.max(best);
        }
    }
    assert!(
        worst <= 0.01 + 0.0015,
        "mapped input up to {worst} mm from the output"
    );
}

#[test]
fn the_dish_leans_at_74_degrees_and_keeps_the_bead() {
    let input = read(&sample("vase_cylinder_prusa.gcode"));
    let run = deform(input, &Spec::preset("dish", &[]).unwrap());
    let h = &run.helix;
    // Wall angle from the vertical, from the output's points: radius and height of the
    // output helix at turns 10 and 60.
    let out_h = helix::find(&run.output).unwrap();
    let pts: Vec<[f64; 3]> = extrusions(&run.output)
        .into_iter()
        .filter(|m| m.0 >= out_h.first_line && m.0 <= out_h.last_line)
        .map(|m| m.2)
        .collect();
    let r = |p: [f64; 3]| (p[0] - h.center[0]).hypot(p[1] - h.center[1]);
    let n = pts.len();
    let (a, b) = (pts[n / 7], pts[6 * n / 7]);
    let angle = (r(b) - r(a)).atan2(b[2] - a[2]).to_degrees();
    let want = (1.05f64).atan2(0.3).to_degrees();
    assert!(
        (angle - want).abs() < 0.5,
        "wall at {angle:.2} deg, want {want:.2}"
    );
    // E per mm of the deformed helix = E per mm as sliced (the default cross-section
    // rule), within 1 %.
    let per_mm = |text: &[u8], first: u64, last: u64, skip_first_turn: f64| {
        let (mut e, mut l) = (0.0, 0.0);
        for m in extrusions(text) {
            if m.0 >= first && m.0 <= last && m.1[2] > skip_first_turn {
                e += m.3;
                l += dist(m.1, m.2);
            }
        }
        e / l
    };
    let z1 = h.z0 + h.pitch + 0.01;
    let before = per_mm(&run.input, h.first_line, h.last_line, z1);
    let after = per_mm(&run.output, out_h.first_line, out_h.last_line, z1);
    assert!(
        (after / before - 1.0).abs() < 0.01,
        "{before} -> {after} E/mm"
    );
    follows_the_mapping(&run);
}

#[test]
fn the_vase_follows_its_radius_profile() {
    let input = read(&sample("vase_cylinder_prusa.gcode"));
    let run = deform(input, &Spec::preset("vase", &[]).unwrap());
    let h = &run.helix;
    let out_h = helix::find(&run.output).unwrap();
    let base = h.z0 + h.pitch;
    let (a, b, w, ph) = (0.8f64, 0.4f64, 8.0f64, 6.5f64);
    let mut worst: f64 = 0.0;
    for m in extrusions(&run.output) {
        if m.0 < out_h.first_line || m.0 > out_h.last_line || m.2[2] < base + 0.01 {
            continue;
        }
        // Height above the first turn is kept; the radius scales by the profile.
        let z = m.2[2] - base;
        let want = h.r0 * (a + b * (z / w + ph).sin()) / (a + b * ph.sin());
        let got = (m.2[0] - h.center[0]).hypot(m.2[1] - h.center[1]);
        worst = worst.max((got - want).abs());
    }
    // The sliced cylinder is a 180-gon of radius 15 (r0 is the mean of its vertices).
    assert!(worst < 0.02 + 0.01, "radius off the profile by {worst} mm");
    follows_the_mapping(&run);
}

#[test]
fn the_sphere_keeps_turn_spacing_on_its_surface() {
    let input = read(&sample("vase_cylinder_prusa.gcode"));
    let run = deform(input, &Spec::preset("sphere", &[]).unwrap());
    follows_the_mapping(&run);
    // Output points lie on the sphere: distance from its centre = R.
    let h = &run.helix;
    let height = h.z_top - h.z0 - h.pitch;
    let top = 150f64.to_radians();
    let arc = |big: f64| big * (top - (h.r0 / big).min(1.0).asin());
    let big = if arc(h.r0) >= height {
        h.r0
    } else {
        panic!("taller part")
    };
    let phi0 = (h.r0 / big).asin();
    let c = [h.center[0], h.center[1], h.z0 + h.pitch + big * phi0.cos()];
    let out_h = helix::find(&run.output).unwrap();
    for m in extrusions(&run.output) {
        if m.0 >= out_h.first_line && m.0 <= out_h.last_line && m.2[2] > h.z0 + h.pitch + 0.01 {
            let d = dist(m.2, c);
            assert!(
                (d - big).abs() < 0.05,
                "{:?} at {d} from the centre, R {big}",
                m.2
            );
        }
    }
}

#[test]
fn a_turn_set_off_the_one_below_is_refused_with_its_point() {
    let input = read(&sample("vase_cylinder_prusa.gcode"));
    let config = SlicerConfig::parse(&input);
    let spec = Spec::expressions(Frame::Cylindrical, "r + 3*z; theta; 0.3*z", &[]).unwrap();
    let e = helix::deform_text(&input, &config, &spec, false)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("not printable") && e.contains("turn ") && e.contains(" x "),
        "{e}"
    );
    assert!(e.contains("in air"), "{e}");
    // With --force it is written, and poa check finds the same fault on its own.
    let d = helix::deform_text(&input, &config, &spec, true).unwrap();
    let h = helix::find(&d.text).unwrap();
    let again = helix::printable::check(&d.text, &h, helix::bead_of(&config, &h), 0);
    assert!(again.unsupported > 0);
}

fn cli_deform(input: &Path, out: &Path, args: &[&str]) -> std::process::Output {
    poa_to("deform", input, out, args)
}

#[test]
fn the_cli_writes_each_preset_and_poa_check_finds_nothing_in_air() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("vase_cylinder_prusa.gcode");
    for preset in ["dish", "vase", "sphere"] {
        let out = dir.path().join(format!("{preset}.gcode"));
        let prev = dir.path().join(format!("prev_{preset}"));
        let o = cli_deform(
            &input,
            &out,
            &["--preset", preset, "--preview", prev.to_str().unwrap()],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let page = std::fs::read_to_string(prev.join("index.html")).unwrap();
        assert!(
            page.contains("<svg") && page.contains("every point rests"),
            "{preset}"
        );
        let c = poa().arg("check").arg("--json").arg(&out).output().unwrap();
        let v: serde_json::Value = serde_json::from_slice(&c.stdout).unwrap();
        assert_eq!(v["layerless"], true);
        assert_eq!(v["report"]["unsupported"], 0, "{preset}: {v}");
        assert_eq!(v["report"]["collisions"], 0, "{preset}: {v}");
        // The progress lines count down to the new total.
        let text = read(&out);
        let m73: Vec<&[u8]> = text
            .split(|&b| b == b'\n')
            .filter(|l| l.starts_with(b"M73 P"))
            .collect();
        assert!(m73.first().unwrap().starts_with(b"M73 P0 R"), "{preset}");
    }
}

#[test]
fn bad_expressions_and_layered_inputs_get_one_line_and_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("vase_cylinder_prusa.gcode");
    let out = dir.path().join("out.gcode");
    let cases: &[(&[&str], &str)] = &[
        (&["--cylindrical", "r + zz; theta; z"], "column 5"),
        (
            &["--cylindrical", "r * sni(theta); theta; z"],
            "did you mean `sin`",
        ),
        (&["--cartesian", "x; y"], "three expressions"),
        (&["--cylindrical", "r; theta; -z^2"], "-(a^b)"),
        (
            &["--preset", "dish", "--param", "kk=2"],
            "no parameter `kk`",
        ),
        (
            &["--speed", "v*2", "--preset", "dish", "--param", "k"],
            "NAME=VALUE",
        ),
        (&["--cylindrical", "r; theta; 0*z"], "does not rise"),
    ];
    for (args, want) in cases {
        let o = cli_deform(&input, &out, args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(want), "{args:?}: {err}");
        assert!(err.trim().lines().count() <= 2, "{err}");
        assert!(!out.exists(), "{args:?} wrote a file");
    }
    let o = cli_deform(
        &sample("rect_overhang_prusa_rel.gcode"),
        &out,
        &["--preset", "dish"],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("vase mode"), "{err}");
    assert!(!out.exists());
}

#[test]
fn cura_and_comment_less_vases_are_deformed() {
    let plain = strip_comments(&read(&sample("vase_cylinder_prusa.gcode")));
    let run = deform(plain, &Spec::preset("dish", &[]).unwrap());
    follows_the_mapping(&run);
    let stl = crate::common::part("vase_cylinder");
    let settings = [
        "magic_spiralize=true",
        "initial_bottom_layers=3",
        "bottom_layers=3",
        "top_layers=0",
        "wall_line_count=1",
        "infill_sparse_density=0",
    ];
    let Some(cura) = slice_cura(&stl, "creality_ender3", &settings) else {
        return;
    };
    for preset in ["dish", "vase", "sphere"] {
        let run = deform(cura.clone(), &Spec::preset(preset, &[]).unwrap());
        follows_the_mapping(&run);
    }
}

#[test]
fn poa_preview_draws_a_layerless_file_with_its_unsupported_points_red() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("vase_cylinder_prusa.gcode");
    // A printable dish: the page says so and has no red point.
    let dish = dir.path().join("dish.gcode");
    assert!(cli_deform(&input, &dish, &["--preset", "dish"])
        .status
        .success());
    let folder = dir.path().join("dish_preview");
    let o = poa()
        .arg("preview")
        .arg(&dish)
        .arg("-o")
        .arg(&folder)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = std::fs::read_to_string(folder.join("index.html")).unwrap();
    assert!(page.contains("every point rests"), "{page}");
    assert!(
        !page.contains("#d62728"),
        "a printable dish drawn with red points"
    );
    for svg in ["profile.svg", "top.svg"] {
        let s = std::fs::read_to_string(folder.join(svg)).unwrap();
        assert!(
            s.starts_with("<svg") && s.matches("<ellipse").count() > 1000,
            "{svg}"
        );
    }
    // A deformation lifted off the turn below (written with --force): red points, and the
    // profile alone as one SVG file.
    let bad = dir.path().join("bad.gcode");
    let o = cli_deform(
        &input,
        &bad,
        &["--cylindrical", "r + 3*z; theta; 0.3*z", "--force"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let svg = dir.path().join("bad.svg");
    let o = poa()
        .arg("preview")
        .arg(&bad)
        .arg("-o")
        .arg(&svg)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = std::fs::read_to_string(&svg).unwrap();
    assert!(s.contains("side profile") && s.contains("#d62728"));
    // A layered file without --layer or --regions: told what to give, nothing written.
    let none = dir.path().join("none.svg");
    let o = poa()
        .arg("preview")
        .arg(sample("rect_overhang_prusa_rel.gcode"))
        .arg("-o")
        .arg(&none)
        .output()
        .unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--layer N"));
    assert!(!none.exists());
}
