//! Five-axis support-free printing (Wang et al., SFAM): a workpiece-frame tool path whose
//! points carry the direction material is laid along, turned into joint G-code for a
//! table-tilting printer.
//!
//! Input: a workpiece path ([`sweep::PathPoint`]s: from [`sweep::sweep`], a CSV of
//! `x,y,z,i,j,k,e`, or G-code with a `; NORMAL i j k` comment before a move) and a
//! [`kinematics::Machine`]. Output: G-code moving X, Y, Z and the two rotary axes, E from the
//! workpiece length, F for the tip's speed (or inverse time, G93).
//!
//! Invariants: every segment is cut until the tip's path (joints interpolated linearly, the
//! way the firmware moves) stays within `tolerance` of the straight workpiece segment at the
//! midpoints of its pieces; a joint limit crossed refuses the whole file naming the point.

pub mod kinematics;
pub mod sweep;

use crate::error::Error;
use crate::writer::{fmt_e, fmt_mm, fmt_num};
use kinematics::{unit, Flavour, Joints, Machine, V3};
use sweep::PathPoint;

/// Halvings of one segment at most (65,536 pieces): past that the tip's deviation comes from
/// a flip of the joints, not from the segment's length, and more pieces would not help.
const MAX_DEPTH: usize = 16;
/// Most joint moves a conversion writes (the file is made in memory).
pub const MAX_MOVES: usize = 10_000_000;

/// How F is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feed {
    /// F for the linear axes' distance so that the tip moves at the speed asked (rotary-only
    /// moves: degrees per minute for the same time).
    Tip,
    /// G93: F = 1 / minutes of the move.
    InverseTime,
}

/// Settings of a conversion.
#[derive(Debug, Clone, Copy)]
pub struct Convert {
    /// Tip speed along the workpiece (mm/s).
    pub speed: f64,
    pub feed: Feed,
    /// Largest distance (mm) of the tip's path from the workpiece segment.
    pub tolerance: f64,
}

/// What a conversion made.
pub struct Converted {
    pub text: String,
    /// The joint poses written, in order, with the workpiece point and direction each was
    /// made for.
    pub poses: Vec<(Joints, V3, V3)>,
    pub moves: usize,
    pub time_s: f64,
    pub filament_mm: f64,
    /// For each move: end time (s), tilt and turn as written (deg), tip speed (mm/s).
    pub timeline: Vec<[f64; 4]>,
}

fn lerp3(a: V3, b: V3, f: f64) -> V3 {
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
    ]
}

fn dist(a: V3, b: V3) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn lerp_joints(a: &Joints, b: &Joints, f: f64) -> Joints {
    Joints {
        xyz: lerp3(a.xyz, b.xyz, f),
        tilt: a.tilt + (b.tilt - a.tilt) * f,
        turn: a.turn + (b.turn - a.turn) * f,
    }
}

/// Distance of `p` from segment a-b (3D).
pub fn to_segment(p: V3, a: V3, b: V3) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let t = if l2 > 0.0 {
        (((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1] + (p[2] - a[2]) * ab[2]) / l2)
            .clamp(0.0, 1.0)
    } else {
        0.0
    };
    dist(p, lerp3(a, b, t))
}

/// The comment block a flavour needs (what the firmware must be told about the rotary axes).
fn preamble(m: &Machine, feed: Feed) -> String {
    let (t, c) = (m.tilt_letter, m.turn_letter);
    let mut s = format!(
        "; poa five-axis: joint G-code for the table-tilting machine `{}` ({:?} layout)\n; tilt {t}: sign {}, zero {} deg, pivot {:?}; turn {c}: sign {}, zero {} deg, pivot {:?}\n",
        m.name, m.layout, m.tilt_sign, m.tilt_zero, m.pivot_tilt, m.turn_sign, m.turn_zero, m.pivot_turn
    );
    s.push_str(match m.flavour {
        Flavour::Reprapfirmware => {
            "; RepRapFirmware needs the rotary axes declared in config.g, e.g.:\n;   M584 X0 Y1 Z2 E3 B4 C5 R1 S1   ; B and C rotational (R1), not moved as linear\n;   M669 K0                        ; Cartesian kinematics: poa does the five-axis transform\n;   M92 B.. C..  M203 B.. C..  M566 B.. C..  M201 B.. C..   ; steps per degree and limits\n"
        }
        Flavour::Marlin => {
            "; Marlin 2.1 needs AXIS4_NAME/AXIS5_NAME set to the rotary letters with\n; AXIS4_ROTATES and AXIS5_ROTATES, and steps per degree for them\n"
        }
        Flavour::Klipper => {
            "; Klipper moves extra axes only as manual steppers or with a rotary-axis extension:\n; map the two letters to them (poa does the five-axis transform)\n"
        }
    });
    s.push_str("G90 ; absolute axes\nM83 ; relative extrusion\n");
    if feed == Feed::InverseTime {
        s.push_str("G93 ; inverse-time feed: F = 1 / minutes of each move\n");
    }
    s
}

/// Turns the workpiece path into joint G-code for `m`.
///
/// Long by design: one walk over the path that cuts each segment, checks limits, and writes
/// the move with its feed and extrusion, the joint state carried from move to move.
pub fn convert(path: &[PathPoint], m: &Machine, set: &Convert) -> Result<Converted, Error> {
    if !(set.speed.is_finite() && (0.5..=1000.0).contains(&set.speed)) {
        return Err(Error::Invalid(format!(
            "--speed {}: 0.5 to 1000 mm/s",
            set.speed
        )));
    }
    if !(set.tolerance.is_finite() && (1e-4..=1.0).contains(&set.tolerance)) {
        return Err(Error::Invalid(format!(
            "--tolerance {}: 0.0001 to 1 mm",
            set.tolerance
        )));
    }
    let Some(first) = path.first() else {
        return Err(Error::Invalid("the tool path is empty".into()));
    };
    let at = |i: usize, e: Error| match e {
        Error::Refused(msg) | Error::Invalid(msg) => Error::Refused(format!(
            "point {} ({:.3} {:.3} {:.3}): {msg}; nothing written",
            i + 1,
            path[i].p[0],
            path[i].p[1],
            path[i].p[2]
        )),
        other => other,
    };
    let mut text = preamble(m, set.feed);
    let mut j = m.inverse(first.p, first.n, None).map_err(|e| at(0, e))?;
    let mut poses = vec![(j, first.p, first.n)];
    let word = |j: &Joints| {
        let (t, c) = m.written(j);
        format!(
            "X{} Y{} Z{} {}{} {}{}",
            fmt_mm(j.xyz[0]),
            fmt_mm(j.xyz[1]),
            fmt_mm(j.xyz[2]),
            m.tilt_letter,
            fmt_num(t, 4),
            m.turn_letter,
            fmt_num(c, 4)
        )
    };
    // Get there first: up, over, down would need the machine's clearances; the user's start
    // G-code parks above the bed, so a plain move to the first pose.
    text.push_str(&format!(
        "G1 {} F{}\n",
        word(&j),
        fmt_num(60.0 * set.speed, 0)
    ));
    let (mut moves, mut time, mut filament) = (0usize, 0.0, 0.0);
    let mut timeline = Vec::new();
    for i in 1..path.len() {
        let (a, b) = (&path[i - 1], &path[i]);
        let len = dist(a.p, b.p);
        if len < 1e-9 {
            continue;
        }
        // Pieces of the workpiece segment: (share from, share to), cut until the tip's
        // path is within tolerance of the segment at each piece's quarter points.
        let mut stack = vec![(0.0f64, 1.0f64, 0usize)];
        let mut pieces: Vec<(f64, Joints, f64)> = Vec::new();
        let pose = |f: f64, prev: &Joints| -> Result<Joints, Error> {
            let n = unit(lerp3(a.n, b.n, f)).unwrap_or(b.n);
            m.inverse(lerp3(a.p, b.p, f), n, Some(prev))
        };
        let mut cur = j;
        while let Some((f0, f1, depth)) = stack.pop() {
            let end = pose(f1, &cur).map_err(|e| at(i, e))?;
            let off = [0.25, 0.5, 0.75]
                .iter()
                .map(|q| to_segment(m.forward(&lerp_joints(&cur, &end, *q)).0, a.p, b.p))
                .fold(0.0f64, f64::max);
            if off > set.tolerance && depth < MAX_DEPTH {
                let mid = (f0 + f1) / 2.0;
                stack.push((mid, f1, depth + 1));
                stack.push((f0, mid, depth + 1));
                continue;
            }
            pieces.push((f1 - f0, end, f1));
            cur = end;
        }
        if moves + pieces.len() > MAX_MOVES {
            return Err(Error::Refused(format!(
                "more than {MAX_MOVES} joint moves: the path is too long or the tolerance too fine; nothing written"
            )));
        }
        for (share, next, at_share) in pieces {
            let p = lerp3(a.p, b.p, at_share);
            let room = m.clearance(p, next.tilt);
            if room < 0.0 {
                return Err(at(
                    i,
                    Error::Refused(format!(
                        "at a tilt of {:.1} deg the bed would meet the hot end ({:.1} mm short; hotend_radius {} mm, hotend_height {} mm)",
                        next.tilt.to_degrees(),
                        -room,
                        m.hotend_radius,
                        m.hotend_height
                    )),
                ));
            }
            let tip = len * share;
            let secs = (tip / set.speed).max(
                // The rotary axes' own speed limit.
                ((next.tilt - j.tilt).abs().max((next.turn - j.turn).abs())).to_degrees()
                    / m.max_angular_speed,
            );
            let e = b.e * share;
            let feed = match set.feed {
                Feed::InverseTime => 60.0 / secs.max(1e-6),
                Feed::Tip => {
                    let linear = dist(j.xyz, next.xyz);
                    if linear > 1e-6 {
                        60.0 * linear / secs.max(1e-6)
                    } else {
                        let deg = (next.tilt - j.tilt)
                            .abs()
                            .hypot((next.turn - j.turn).abs())
                            .to_degrees();
                        60.0 * deg / secs.max(1e-6)
                    }
                }
            };
            let e_word = if e > 0.0 {
                format!(" E{}", fmt_e(e))
            } else {
                String::new()
            };
            text.push_str(&format!(
                "G1 {}{e_word} F{}\n",
                word(&next),
                fmt_num(feed, 3)
            ));
            poses.push((next, p, unit(lerp3(a.n, b.n, at_share)).unwrap_or(b.n)));
            moves += 1;
            time += secs;
            filament += e;
            let (t_deg, c_deg) = m.written(&next);
            timeline.push([time, t_deg, c_deg, tip / secs.max(1e-9)]);
            j = next;
        }
    }
    if set.feed == Feed::InverseTime {
        text.push_str("G94 ; feed back to units per minute\n");
    }
    Ok(Converted {
        text,
        poses,
        moves,
        time_s: time,
        filament_mm: filament,
        timeline,
    })
}

/// A workpiece path from CSV lines `x,y,z,i,j,k,e` (`e`: filament of the segment ending at
/// the point; a header line and `#` lines skipped).
pub fn path_from_csv(text: &str) -> Result<Vec<PathPoint>, Error> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let v: Result<Vec<f64>, _> = line.split(',').map(|x| x.trim().parse::<f64>()).collect();
        let v = match v {
            Ok(v) if v.len() == 7 && v.iter().all(|x| x.is_finite()) => v,
            _ if out.is_empty() && i == 0 => continue,
            _ => {
                return Err(Error::Invalid(format!(
                    "line {}: `{line}` is not x,y,z,i,j,k,e",
                    i + 1
                )))
            }
        };
        let n = unit([v[3], v[4], v[5]])
            .ok_or_else(|| Error::Invalid(format!("line {}: direction of length 0", i + 1)))?;
        out.push(PathPoint {
            p: [v[0], v[1], v[2]],
            n,
            e: v[6].max(0.0),
            layer: 0,
        });
        if out.len() > 10_000_000 {
            return Err(Error::Invalid("more than ten million points".into()));
        }
    }
    Ok(out)
}

/// A workpiece path from G-code whose moves carry a direction: a `; NORMAL i j k` comment
/// before a move gives it (and the moves after it, until the next) its direction.
pub fn path_from_gcode(text: &[u8]) -> Result<Vec<PathPoint>, Error> {
    use crate::machine::{Action, Machine as Interp};
    let mut interp = Interp::new();
    let mut n: Option<V3> = None;
    let mut out: Vec<PathPoint> = Vec::new();
    for (i, raw) in crate::gcode::split_lines(text).enumerate() {
        let content = crate::gcode::strip_terminator(raw);
        let parsed = crate::gcode::parse_line(content);
        if let Some(c) = parsed.comment {
            let c = String::from_utf8_lossy(c);
            if let Some(rest) = c.trim().strip_prefix("NORMAL") {
                let v: Vec<f64> = rest
                    .split_whitespace()
                    .filter_map(|x| x.parse().ok())
                    .collect();
                n = Some(
                    (v.len() == 3)
                        .then(|| unit([v[0], v[1], v[2]]))
                        .flatten()
                        .ok_or_else(|| {
                            Error::Invalid(format!(
                                "line {}: `; NORMAL` takes i j k, not zero",
                                i + 1
                            ))
                        })?,
                );
            }
        }
        if let Action::Move(mv) = interp.step(&parsed, i as u64 + 1) {
            let Some(dir) = n else {
                continue;
            };
            if out.is_empty() || mv.e <= 0.0 {
                // A travel (or the first move) starts the path where it ends.
                if out.is_empty() {
                    out.push(PathPoint {
                        p: mv.to,
                        n: dir,
                        e: 0.0,
                        layer: 0,
                    });
                    continue;
                }
            }
            out.push(PathPoint {
                p: mv.to,
                n: dir,
                e: mv.e.max(0.0),
                layer: 0,
            });
        }
    }
    if out.is_empty() {
        return Err(Error::Invalid(
            "no move carries a direction: put `; NORMAL i j k` before the moves".into(),
        ));
    }
    Ok(out)
}

/// The workpiece path as G-code (what `poa sweep` writes without a machine): each layer's
/// direction as a `; NORMAL i j k` comment before its moves, E relative, F the tip speed.
/// [`path_from_gcode`] reads it back.
pub fn workpiece_gcode(path: &[PathPoint], speed: f64) -> String {
    let mut s = String::from(
        "; poa sweep: workpiece path (bed frame, rotary axes at zero); directions are the layer normals\nG90\nM83\n",
    );
    let mut last_n: Option<V3> = None;
    let mut layer = usize::MAX;
    for (i, p) in path.iter().enumerate() {
        if p.layer != layer {
            s.push_str(&format!(";LAYER:{}\n", p.layer));
            layer = p.layer;
        }
        if last_n != Some(p.n) {
            s.push_str(&format!(
                "; NORMAL {} {} {}\n",
                fmt_num(p.n[0], 9),
                fmt_num(p.n[1], 9),
                fmt_num(p.n[2], 9)
            ));
            last_n = Some(p.n);
        }
        let xyz = format!(
            "X{} Y{} Z{}",
            fmt_mm(p.p[0]),
            fmt_mm(p.p[1]),
            fmt_mm(p.p[2])
        );
        if i == 0 {
            s.push_str(&format!("G1 {xyz} F{}\n", fmt_num(60.0 * speed, 0)));
        } else {
            s.push_str(&format!("G1 {xyz} E{}\n", fmt_e(p.e)));
        }
    }
    s
}

/// Joint poses of joint G-code written for `m` (X Y Z and the rotary letters), in order:
/// what the machine will do, for replaying it in the workpiece frame.
pub fn replay(text: &str, m: &Machine) -> Vec<Joints> {
    let mut cur = [0.0f64; 5];
    let mut out = Vec::new();
    for line in text.lines() {
        let code = line.split(';').next().unwrap_or("").trim();
        if !code.starts_with("G1 ") && !code.starts_with("G0 ") {
            continue;
        }
        for word in code.split_whitespace().skip(1) {
            let (l, v) = word.split_at(1);
            let Ok(v) = v.parse::<f64>() else { continue };
            let l = l.chars().next().unwrap();
            match l {
                'X' => cur[0] = v,
                'Y' => cur[1] = v,
                'Z' => cur[2] = v,
                _ if l == m.tilt_letter => cur[3] = v,
                _ if l == m.turn_letter => cur[4] = v,
                _ => {}
            }
        }
        out.push(m.from_written([cur[0], cur[1], cur[2]], cur[3], cur[4]));
    }
    out
}

/// An HTML page with the workpiece path in 3D projection (layers coloured by index, the
/// deposition direction drawn every `every` layers) and, with joint G-code, the rotary axes
/// and the tip speed against time.
pub fn preview_page(
    path: &[PathPoint],
    conv: Option<(&Converted, &Machine)>,
    title: &str,
) -> String {
    use std::fmt::Write as _;
    // Orthographic view from the front-right, a little above.
    let (az, el) = (35f64.to_radians(), 20f64.to_radians());
    let view = |p: V3| {
        let x = p[0] * az.cos() + p[1] * az.sin();
        let y = -p[0] * az.sin() + p[1] * az.cos();
        [x, p[2] * el.cos() - y * el.sin()]
    };
    let pts: Vec<[f64; 2]> = path.iter().map(|p| view(p.p)).collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for q in &pts {
        for i in 0..2 {
            lo[i] = lo[i].min(q[i]);
            hi[i] = hi[i].max(q[i]);
        }
    }
    let size = 560.0;
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1.0) * 1.1;
    let k = size / span;
    let tx = |q: [f64; 2]| [(q[0] - lo[0]) * k + 20.0, size - (q[1] - lo[1]) * k + 20.0];
    let layers = path.last().map_or(1, |p| p.layer + 1).max(1);
    let mut body = String::new();
    let mut i = 0;
    while i < path.len() {
        let layer = path[i].layer;
        let mut d = String::new();
        while i < path.len() && path[i].layer == layer {
            let q = tx(pts[i]);
            let _ = write!(
                d,
                "{}{:.1} {:.1} ",
                if d.is_empty() { "M" } else { "L" },
                q[0],
                q[1]
            );
            i += 1;
        }
        let hue = 240.0 - 240.0 * layer as f64 / layers as f64;
        let _ = write!(
            body,
            r#"<path d="{d}" fill="none" stroke="hsl({hue:.0},70%,45%)" stroke-width="0.6"/>"#
        );
    }
    let every = (layers / 12).max(1);
    let mut drawn = usize::MAX;
    // One arrow at the first point of every `every`-th layer.
    for p in path.iter().filter(|p| p.layer % every == 0) {
        if p.layer == drawn {
            continue;
        }
        drawn = p.layer;
        let a = tx(view(p.p));
        let b = tx(view([
            p.p[0] + 4.0 * p.n[0],
            p.p[1] + 4.0 * p.n[1],
            p.p[2] + 4.0 * p.n[2],
        ]));
        let _ = write!(
            body,
            r##"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="#222" stroke-width="1.2"/><circle cx="{:.1}" cy="{:.1}" r="2" fill="#222"/>"##,
            a[0], a[1], b[0], b[1], b[0], b[1]
        );
    }
    let work = format!(
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="600" height="600" viewBox="0 0 600 600"><rect width="100%" height="100%" fill="#fff"/>{body}<text x="8" y="16" font-family="sans-serif" font-size="13">workpiece path: {layers} layers, blue first to red last; black: deposition direction every {every} layers</text></svg>"##
    );
    let joints = match conv {
        None => String::new(),
        Some((c, m)) => {
            let t_end = c.timeline.last().map_or(1.0, |x| x[0]).max(1e-9);
            let plot = |col: usize, label: &str, colour: &str| {
                let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
                for x in &c.timeline {
                    a = a.min(x[col]);
                    b = b.max(x[col]);
                }
                let span = (b - a).max(1e-9);
                let mut d = String::new();
                let stride = (c.timeline.len() / 2000).max(1);
                for x in c.timeline.iter().step_by(stride) {
                    let px = 50.0 + 540.0 * x[0] / t_end;
                    let py = 150.0 - 130.0 * (x[col] - a) / span;
                    let _ = write!(
                        d,
                        "{}{px:.1} {py:.1} ",
                        if d.is_empty() { "M" } else { "L" }
                    );
                }
                format!(
                    r##"<svg xmlns="http://www.w3.org/2000/svg" width="600" height="170" viewBox="0 0 600 170"><rect width="100%" height="100%" fill="#fff"/><path d="{d}" fill="none" stroke="{colour}" stroke-width="1"/><text x="4" y="14" font-family="sans-serif" font-size="12">{label}: {a:.1} to {b:.1} over {t_end:.0} s</text></svg>"##
                )
            };
            format!(
                "<h2>Joints against time</h2>\n{}<br>{}<br>{}\n",
                plot(1, &format!("{} (tilt, deg)", m.tilt_letter), "#1f77b4"),
                plot(2, &format!("{} (turn, deg)", m.turn_letter), "#d62728"),
                plot(3, "tip speed (mm/s)", "#2ca02c")
            )
        }
    };
    format!(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>{t}</title><style>body{{font-family:sans-serif;margin:1em}}</style></head><body>\n<h1>{t}</h1>\n{work}\n{joints}</body></html>\n",
        t = crate::preview::escape(title)
    )
}

/// What replaying joint G-code in the workpiece frame found (`poa check --machine`).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Replayed {
    pub moves: usize,
    /// Length printed, along the workpiece (mm).
    pub length_mm: f64,
    /// Points judged (every quarter width of printed path).
    pub points: usize,
    /// Of those, with no earlier material within reach and not on the bed.
    pub unsupported: usize,
    pub in_air_mm: f64,
    pub first_unsupported: Option<V3>,
    /// Tilt and turn as written (deg), smallest and largest.
    pub tilt_deg: [f64; 2],
    pub turn_deg: [f64; 2],
    /// Poses outside the machine's joint limits.
    pub outside_limits: usize,
}

/// Replays joint G-code written for `m` in the workpiece frame and judges it like a
/// layer-less print: each point of printed path must have earlier material within reach
/// (`max(1.5 x 1.05 h, 0.75 w)`: layers are up to 1.5 h thick outside a bend), its own last
/// four widths excluded, or lie on the bed (workpiece z within h).
pub fn check_joints(text: &str, m: &Machine, width: f64, height: f64) -> Replayed {
    use rustc_hash::FxHashMap;
    let reach = (1.5 * 1.05 * height).max(0.75 * width);
    let step = (width / 4.0).max(0.02);
    let guard = 4.0 * width;
    let key = |p: V3| {
        (
            (p[0] / reach).floor() as i64,
            (p[1] / reach).floor() as i64,
            (p[2] / reach).floor() as i64,
        )
    };
    let mut grid: FxHashMap<(i64, i64, i64), Vec<V3>> = FxHashMap::default();
    let mut pending: std::collections::VecDeque<(f64, V3)> = Default::default();
    let mut r = Replayed {
        tilt_deg: [f64::INFINITY, f64::NEG_INFINITY],
        turn_deg: [f64::INFINITY, f64::NEG_INFINITY],
        ..Default::default()
    };
    let mut cur = [0.0f64; 5];
    let mut prev: Option<Joints> = None;
    let mut along = 0.0;
    let mut absolute_e = false;
    let mut last_e = 0.0;
    for line in text.lines() {
        let code = line.split(';').next().unwrap_or("").trim();
        match code {
            "M82" => absolute_e = true,
            "M83" => absolute_e = false,
            _ => {}
        }
        if !code.starts_with("G1 ") && !code.starts_with("G0 ") {
            continue;
        }
        let mut e = 0.0;
        for word in code.split_whitespace().skip(1) {
            let (l, v) = word.split_at(1);
            let Ok(v) = v.parse::<f64>() else { continue };
            match l.chars().next().unwrap_or(' ') {
                'X' => cur[0] = v,
                'Y' => cur[1] = v,
                'Z' => cur[2] = v,
                'E' => {
                    e = if absolute_e { v - last_e } else { v };
                    if absolute_e {
                        last_e = v;
                    }
                }
                c if c == m.tilt_letter => cur[3] = v,
                c if c == m.turn_letter => cur[4] = v,
                _ => {}
            }
        }
        r.tilt_deg = [r.tilt_deg[0].min(cur[3]), r.tilt_deg[1].max(cur[3])];
        r.turn_deg = [r.turn_deg[0].min(cur[4]), r.turn_deg[1].max(cur[4])];
        let within = |v: f64, l: [f64; 2]| v >= l[0] - 1e-6 && v <= l[1] + 1e-6;
        if !(within(cur[0], m.limit_x)
            && within(cur[1], m.limit_y)
            && within(cur[2], m.limit_z)
            && within(cur[3], m.limit_tilt)
            && within(cur[4], m.limit_turn))
        {
            r.outside_limits += 1;
        }
        let j = m.from_written([cur[0], cur[1], cur[2]], cur[3], cur[4]);
        let Some(p0) = prev.replace(j) else {
            continue;
        };
        r.moves += 1;
        if e <= 0.0 {
            continue;
        }
        let (a, b) = (m.forward(&p0).0, m.forward(&j).0);
        let len = dist(a, b);
        r.length_mm += len;
        let n = ((len / step).ceil() as usize).clamp(1, 1_000_000);
        for i in 1..=n {
            let f = i as f64 / n as f64;
            let p = m.forward(&lerp_joints(&p0, &j, f)).0;
            along += len / n as f64;
            while pending.front().is_some_and(|(l, _)| *l < along - guard) {
                let (_, q) = pending.pop_front().unwrap();
                grid.entry(key(q)).or_default().push(q);
            }
            r.points += 1;
            let k = key(p);
            let mut supported = p[2] <= height + 0.05;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if supported {
                            break 'search;
                        }
                        if let Some(v) = grid.get(&(k.0 + dx, k.1 + dy, k.2 + dz)) {
                            supported = v.iter().any(|q| dist(*q, p) <= reach);
                        }
                    }
                }
            }
            if !supported {
                r.unsupported += 1;
                r.in_air_mm += len / n as f64;
                r.first_unsupported.get_or_insert(p);
            }
            pending.push_back((along, p));
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turning_segment_is_cut_until_the_tip_stays_on_it() {
        let m = Machine::load("sfam").unwrap();
        // A straight segment whose direction swings 40 degrees: joint-linear motion would
        // bow the tip away from it.
        let a = [125.0, 105.0, 10.0];
        let b = [135.0, 105.0, 10.0];
        let path = vec![
            PathPoint {
                p: a,
                n: [0.0, 0.0, 1.0],
                e: 0.0,
                layer: 0,
            },
            PathPoint {
                p: b,
                n: [0.7f64.sin(), 0.0, 0.7f64.cos()],
                e: 0.5,
                layer: 0,
            },
        ];
        let set = Convert {
            speed: 20.0,
            feed: Feed::Tip,
            tolerance: 0.01,
        };
        let c = convert(&path, &m, &set).unwrap();
        assert!(c.moves > 4, "{} moves", c.moves);
        // Replayed densely, the tip stays within the tolerance of the segment.
        let poses = replay(&c.text, &m);
        for w in poses.windows(2) {
            for q in 0..=10 {
                let p = m.forward(&lerp_joints(&w[0], &w[1], q as f64 / 10.0)).0;
                assert!(to_segment(p, a, b) <= 0.01 + 2e-3, "{p:?}");
            }
        }
        assert!((c.filament_mm - 0.5).abs() < 1e-9);
    }
}
