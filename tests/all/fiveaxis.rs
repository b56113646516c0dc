//! Five-axis printing along a structural line: the paper's 90 degree arc tube (12 mm
//! section, 46 mm long) and an S-curve, sliced by `poa sweep`, turned into joint G-code for
//! the built-in machines, and checked: the joint file replayed through the forward
//! kinematics gives back the workpiece path; the path is continuous with starts alternating;
//! every layer rests on the one before; joints stay within limits; bad inputs are refused.

use printonair::fiveaxis::kinematics::{Joints, Machine, V3};
use printonair::fiveaxis::sweep::{sweep, Curve, PathPoint, Section, SweepSettings};
use printonair::fiveaxis::{convert, replay, to_segment, Convert, Feed};

use crate::common::{poa, poa_to};

fn dist(a: V3, b: V3) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

const SET: SweepSettings = SweepSettings {
    width: 0.6,
    height: 0.2,
    filament_area: std::f64::consts::PI * 1.75 * 1.75 / 4.0,
    at: [125.0, 105.0],
};

/// Checks a swept part's path and its joint G-code on `machine`.
fn judge(what: &str, path: &[PathPoint], machine: &str) {
    // Continuous: every move after the first extrudes (no travel between layers).
    assert!(
        path.iter().skip(1).all(|p| p.e > 0.0),
        "{what}: a travel in the path"
    );
    let layers = path.last().unwrap().layer + 1;
    assert!(layers > 50, "{what}: {layers} layers");
    let starts: Vec<&PathPoint> = (0..layers)
        .map(|k| path.iter().find(|p| p.layer == k).unwrap())
        .collect();
    // Starts alternate sides: consecutive layers start far apart, every other one close.
    for k in 2..layers {
        let (a, b, c) = (starts[k - 2].p, starts[k - 1].p, starts[k].p);
        assert!(
            dist(b, c) > 3.0 && dist(a, c) < 1.5,
            "{what}: layer {k} starts"
        );
    }
    // Every point of a layer rests on the layer before: a point of it within the local step
    // (at most 1.5 h) plus half a width.
    let mut by_layer: Vec<Vec<V3>> = vec![Vec::new(); layers];
    for p in path {
        by_layer[p.layer].push(p.p);
    }
    for k in 1..layers {
        for (i, p) in by_layer[k].iter().enumerate().step_by(7) {
            let below = &by_layer[k - 1];
            let d = below
                .windows(2)
                .map(|w| to_segment(*p, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(
                d <= 1.5 * SET.height + SET.width / 2.0,
                "{what}: layer {k} point {i} {d:.3} mm from the layer below"
            );
        }
    }
    // Joint G-code, replayed through the forward kinematics: within 0.01 mm of the path.
    let m = Machine::load(machine).unwrap();
    let set = Convert {
        speed: 12.0,
        feed: Feed::Tip,
        tolerance: 0.01,
    };
    let c = convert(path, &m, &set).unwrap();
    let poses: Vec<Joints> = replay(&c.text, &m);
    assert_eq!(poses.len(), c.moves + 1);
    let mut k = 1usize;
    let mut worst: f64 = 0.0;
    for w in poses.windows(2) {
        for q in 0..=4 {
            let f = q as f64 / 4.0;
            let j = Joints {
                xyz: [0, 1, 2].map(|i| w[0].xyz[i] + (w[1].xyz[i] - w[0].xyz[i]) * f),
                tilt: w[0].tilt + (w[1].tilt - w[0].tilt) * f,
                turn: w[0].turn + (w[1].turn - w[0].turn) * f,
            };
            let p = m.forward(&j).0;
            // The workpiece segment this joint move belongs to: the path advances as the
            // replayed end points pass its points.
            while k + 1 < path.len() && dist(m.forward(&w[1]).0, path[k].p) < 1e-2 && q == 4 {
                k += 1;
            }
            let near = (k.saturating_sub(1)..(k + 2).min(path.len()))
                .filter(|&i| i >= 1)
                .map(|i| to_segment(p, path[i - 1].p, path[i].p))
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(near);
        }
    }
    // The written digits (0.001 mm, 0.0001 deg) on top of the tolerance.
    assert!(
        worst <= 0.01 + 0.003,
        "{what}: replayed tip {worst:.4} mm off the path"
    );
    // At every written pose the nozzle is on the point it was made for and lays material
    // along the layer normal (the line's tangent), within 1 degree.
    for (j, p, n) in &c.poses {
        let (q, d) = m.forward(j);
        assert!(
            dist(*p, q) < 1e-6,
            "{what}: pose off its point by {} at {p:?} vs {q:?} {j:?}",
            dist(*p, q)
        );
        let cos = (d[0] * n[0] + d[1] * n[1] + d[2] * n[2]).clamp(-1.0, 1.0);
        assert!(
            cos.acos().to_degrees() < 1.0,
            "{what}: direction {d:?} vs {n:?}"
        );
    }
    // Joints within the machine's limits.
    for (j, _, _) in &c.poses {
        let (t, turn) = m.written(j);
        assert!(
            t >= m.limit_tilt[0] && t <= m.limit_tilt[1],
            "{what}: tilt {t}"
        );
        assert!(turn >= m.limit_turn[0] && turn <= m.limit_turn[1]);
        for (i, l) in [m.limit_x, m.limit_y, m.limit_z].iter().enumerate() {
            assert!(
                j.xyz[i] >= l[0] - 1e-6 && j.xyz[i] <= l[1] + 1e-6,
                "{what}: axis {i} {}",
                j.xyz[i]
            );
        }
    }
    println!("{what} on {machine}: {layers} layers, {} moves, {:.0} s, {:.0} mm filament, replay within {worst:.4} mm", c.moves, c.time_s, c.filament_mm);
}

#[test]
fn the_papers_arc_tube_and_an_s_curve_print_as_one_supported_path() {
    // 90 degrees over the paper's 46 mm: radius 46 / (pi / 2).
    let r = 46.0 / std::f64::consts::FRAC_PI_2;
    let arc = Curve::arc(r, 90.0).unwrap();
    let tube = sweep(&arc, Section::Circle { d: 12.0 }, &SET).unwrap();
    judge("arc tube", &tube, "sfam");
    // The deposition direction at each point is the line's tangent: the last layer's is
    // horizontal (the tube ends pointing along +X).
    let last = tube.last().unwrap().n;
    assert!(
        (last[0] - 1.0).abs() < 0.01 && last[2].abs() < 0.02,
        "{last:?}"
    );
    let s = Curve::preset("s-curve:40,45").unwrap();
    let part = sweep(&s, Section::Rect { w: 8.0, h: 6.0 }, &SET).unwrap();
    judge("s-curve", &part, "sfam");
    judge("s-curve", &part, "ac-demo");
}

#[test]
fn the_cli_slices_converts_and_refuses_bad_inputs_naming_the_value() {
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path().join("arc.gcode");
    let joints = dir.path().join("arc-joints.gcode");
    let o = poa()
        .args([
            "sweep",
            "--preset",
            "arc:29.3,90",
            "--section",
            "circle:12",
            "-o",
        ])
        .arg(&work)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = poa_to("five-axis", &work, &joints, &["--machine", "sfam"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&joints).unwrap();
    assert!(
        text.contains("M584") && text.lines().filter(|l| l.starts_with("G1 ")).count() > 10_000
    );
    // G93 inverse time: F = 1 / minutes, and G94 at the end.
    let inv = dir.path().join("inv.gcode");
    let o = poa_to(
        "five-axis",
        &work,
        &inv,
        &["--machine", "sfam", "--feed", "inverse-time"],
    );
    assert!(o.status.success());
    let t = std::fs::read_to_string(&inv).unwrap();
    assert!(
        t.contains("G93")
            && t.trim_end()
                .ends_with("G94 ; feed back to units per minute")
    );
    // A machine file printed by `poa machines` is read back.
    let yaml = poa().args(["machines", "ac-demo"]).output().unwrap().stdout;
    let file = dir.path().join("m.yaml");
    std::fs::write(&file, &yaml).unwrap();
    let o = poa_to(
        "five-axis",
        &work,
        &dir.path().join("ac.gcode"),
        &["--machine", file.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Refusals: one line naming the value, nothing written.
    let bad_yaml = dir.path().join("bad.yaml");
    std::fs::write(
        &bad_yaml,
        String::from_utf8_lossy(&yaml)
            .replace("limit_tilt: [-95.0, 95.0]", "limit_tilt: [0.0, 0.0]"),
    )
    .unwrap();
    let out = dir.path().join("never.gcode");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["sweep", "--preset", "arc:10,90", "--section", "circle:12"],
            "radius 10.00",
        ),
        (
            vec!["sweep", "--preset", "arc:30,90", "--section", "circle:0"],
            "circle:0",
        ),
        (
            vec!["sweep", "--preset", "twist:3,3", "--section", "circle:5"],
            "twist",
        ),
        (
            vec![
                "five-axis",
                work.to_str().unwrap(),
                "--machine",
                bad_yaml.to_str().unwrap(),
            ],
            "limit_tilt: [0, 0]",
        ),
        (
            vec!["five-axis", work.to_str().unwrap(), "--machine", "nope"],
            "built-in machines",
        ),
        // A short tight bend tilts the bed 53 degrees 6.5 mm above it: into the hot end.
        (
            vec![
                "sweep",
                "--preset",
                "arc:10,90",
                "--section",
                "circle:4",
                "--machine",
                "sfam",
            ],
            "meet the hot end",
        ),
    ];
    for (args, want) in cases {
        let o = poa().args(&args).arg("-o").arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(want), "{args:?}: {err}");
        assert!(err.trim().lines().count() <= 2, "{err}");
        assert!(!out.exists());
    }
    // A curve with a kink sharper than the section allows.
    let kink = dir.path().join("kink.csv");
    std::fs::write(&kink, "x,y,z\n0,0,0\n0,0,10\n10,0,10\n").unwrap();
    let o = poa()
        .args([
            "sweep",
            "--curve",
            kink.to_str().unwrap(),
            "--section",
            "circle:4",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("bends with radius"),
        "{err}"
    );
    assert!(!out.exists());
    // A joint limit crossed names the point: a tilt of 100 deg past the A/C demo's 95.
    let csv = dir.path().join("steep.csv");
    std::fs::write(
        &csv,
        "x,y,z,i,j,k,e\n110,110,5,0,0,1,0\n111,110,5,0,0.98,-0.2,0.1\n",
    )
    .unwrap();
    let o = poa_to("five-axis", &csv, &out, &["--machine", "ac-demo"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("point 2") && err.contains("limit_tilt"),
        "{err}"
    );
    assert!(!out.exists());
}

/// The paper's comparison: the same part sliced the three-axis way with supports, with the
/// same bead (0.6 x 0.2 mm), the same speed (12 mm/s) and a solid section. Returns (time s,
/// filament mm) of three-axis and of five-axis; `None` without PrusaSlicer.
fn against_three_axis(preset: &str, section: &str) -> Option<([f64; 2], [f64; 2])> {
    if !crate::common::have_prusaslicer() {
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("part.stl");
    let joints = dir.path().join("part.gcode");
    let o = poa()
        .args([
            "sweep",
            "--preset",
            preset,
            "--section",
            section,
            "--width",
            "0.6",
        ])
        .args(["--speed", "12", "--machine", "sfam", "--stl"])
        .arg(&stl)
        .arg("-o")
        .arg(&joints)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut args: Vec<String> = [
        "--support-material",
        "--support-material-auto",
        "--extrusion-width",
        "0.6",
        "--fill-density",
        "100%",
        "--fill-pattern",
        "rectilinear",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for s in [
        "perimeter",
        "external-perimeter",
        "infill",
        "solid-infill",
        "top-solid-infill",
        "support-material",
        "support-material-interface",
        "bridge",
        "gap-fill",
        "first-layer",
        "small-perimeter",
    ] {
        args.push(format!("--{s}-speed"));
        args.push("12".into());
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let three = crate::common::slice_stl(&stl, &args)?;
    let config = printonair::layers::SlicerConfig::parse(&three);
    let t3 = printonair::estimate::estimate_text(&three, &config);
    let f3: f64 = crate::common::all_layers(&three)
        .iter()
        .flat_map(|l| l.paths.iter())
        .flat_map(|p| p.seg_e.iter())
        .sum();
    // Five-axis: E as written, time as the conversion plans it.
    let text = std::fs::read_to_string(&joints).unwrap();
    let f5: f64 = text
        .lines()
        .filter_map(|l| l.split(" E").nth(1))
        .filter_map(|e| e.split_whitespace().next()?.parse::<f64>().ok())
        .sum();
    let m = Machine::load("sfam").unwrap();
    let path = sweep(
        &Curve::preset(preset).unwrap(),
        Section::parse(section).unwrap(),
        &SweepSettings { width: 0.6, ..SET },
    )
    .unwrap();
    let set = Convert {
        speed: 12.0,
        feed: Feed::Tip,
        tolerance: 0.01,
    };
    let t5 = convert(&path, &m, &set).unwrap().time_s;
    println!(
        "{preset} {section}: three-axis with supports {:.0} min, {f3:.0} mm; five-axis {:.0} min, {f5:.0} mm: time {:+.1} %, filament {:+.1} % (paper: -23.58 %, -33.06 %)",
        t3 / 60.0,
        t5 / 60.0,
        100.0 * (t5 / t3 - 1.0),
        100.0 * (f5 / f3 - 1.0)
    );
    Some(([t3, f3], [t5, f5]))
}

#[test]
fn five_axis_beats_three_axis_with_supports_as_in_the_paper() {
    for (preset, section) in [("arc:29.28,90", "circle:12"), ("s-curve:40,45", "rect:8,6")] {
        let Some((three, five)) = against_three_axis(preset, section) else {
            return;
        };
        assert!(
            five[0] < three[0] && five[1] < three[1],
            "{preset}: five-axis {five:?}, three-axis {three:?} (s, mm)"
        );
    }
}
