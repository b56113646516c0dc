//! The paper's slicer for swept parts: a cross-section carried along a structural line, cut
//! by planes normal to the line every `h` (measured on the line), each layer printed as its
//! outer contour then a zigzag infill, layers joined end to start into one continuous path,
//! even layers starting at the contour's middle segmentation point N (starts alternate sides).
//!
//! Input: a [`Curve`] (arc, S-curve, or a polyline from CSV), a [`Section`] (circle or
//! rectangle), bead width `w` and layer step `h`. Output: the workpiece path: points with the
//! direction material is laid along (the line's tangent: the layer normal) and E per segment.
//!
//! On the inside of a bend the planes converge: a point `a` mm from the line towards the
//! bend's centre (radius R) lies between planes `h (1 - a / R)` apart, on the outside
//! `h (1 + a / R)`; E of each segment is Slic3r's bead `(w - t) t + pi t^2 / 4` of that
//! local thickness `t`. The spread is capped:
//! a section reaching more than half the radius from the line (thickness under 0.5 h inside or
//! over 1.5 h outside) is refused, as is a curve bending sharper than that anywhere.

use crate::error::Error;
use crate::fiveaxis::kinematics::{unit, V3};

/// One point of the workpiece path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    pub p: V3,
    /// Direction material is laid along (unit): the layer's normal.
    pub n: V3,
    /// Filament (mm) pushed on the segment that ends here (0 for the first point).
    pub e: f64,
    pub layer: usize,
}

/// The structural line, sampled densely as a polyline from the origin, first going +Z.
#[derive(Debug, Clone)]
pub struct Curve {
    pub points: Vec<V3>,
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V3, k: f64) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

impl Curve {
    /// An arc of radius `r` (mm) turning `angle` (deg) from +Z towards +X.
    pub fn arc(r: f64, angle: f64) -> Result<Curve, Error> {
        Self::arcs(&[(r, angle)])
    }

    /// Arcs in turn, each bending in the plane XZ (a negative angle bends towards -X).
    fn arcs(parts: &[(f64, f64)]) -> Result<Curve, Error> {
        let mut pts = vec![[0.0, 0.0, 0.0]];
        let mut heading = 0.0f64; // angle from +Z towards +X
        for &(r, angle) in parts {
            if !(r.is_finite() && (1.0..=10_000.0).contains(&r)) {
                return Err(Error::Invalid(format!(
                    "arc radius {r} mm: between 1 and 10000"
                )));
            }
            if !(angle.is_finite() && angle.abs() <= 180.0 && angle != 0.0) {
                return Err(Error::Invalid(format!(
                    "arc angle {angle} deg: between -180 and 180, not 0"
                )));
            }
            let sweep = angle.to_radians();
            let n = ((r * sweep.abs()) / 0.05).ceil().max(8.0) as usize;
            let start = *pts.last().unwrap();
            let side = sweep.signum();
            // Centre of the bend: to the side the line turns to.
            let c = add(start, scale([heading.cos(), 0.0, -heading.sin()], side * r));
            for i in 1..=n {
                let t = heading + sweep * i as f64 / n as f64;
                let p = add(c, scale([-t.cos(), 0.0, t.sin()], side * r));
                pts.push(p);
            }
            heading += sweep;
        }
        Ok(Curve { points: pts })
    }

    /// A preset: `arc:R,ANGLE` or `s-curve:R,ANGLE` (two opposite arcs).
    pub fn preset(text: &str) -> Result<Curve, Error> {
        let (kind, args) = text.split_once(':').unwrap_or((text, ""));
        let nums: Vec<f64> = args
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| Error::Invalid(format!("--preset {text}: give R,ANGLE (mm, deg)")))?;
        if nums.len() != 2 {
            return Err(Error::Invalid(format!(
                "--preset {text}: give R,ANGLE (mm, deg)"
            )));
        }
        match kind {
            "arc" => Curve::arc(nums[0], nums[1]),
            "s-curve" => Curve::arcs(&[(nums[0], nums[1]), (nums[0], -nums[1])]),
            _ => Err(Error::Invalid(format!(
                "--preset {kind}: the presets are arc:R,ANGLE and s-curve:R,ANGLE"
            ))),
        }
    }

    /// A polyline from CSV lines `x,y,z` (mm); `#` lines and a header are skipped.
    pub fn csv(text: &str) -> Result<Curve, Error> {
        let mut pts = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let v: Result<Vec<f64>, _> = line.split(',').map(|x| x.trim().parse::<f64>()).collect();
            match v {
                Ok(v) if v.len() == 3 && v.iter().all(|x| x.is_finite()) => {
                    pts.push([v[0], v[1], v[2]])
                }
                _ if pts.is_empty() && i == 0 => continue,
                _ => {
                    return Err(Error::Invalid(format!(
                        "--curve line {}: `{line}` is not x,y,z",
                        i + 1
                    )))
                }
            }
            if pts.len() > 1_000_000 {
                return Err(Error::Invalid("--curve: more than a million points".into()));
            }
        }
        pts.dedup_by(|a, b| norm(sub(*a, *b)) < 1e-9);
        if pts.len() < 2 {
            return Err(Error::Invalid(
                "--curve: needs at least two distinct points".into(),
            ));
        }
        Curve::smooth(&pts)
    }

    /// The Catmull-Rom spline through `pts`, sampled about every 0.05 mm: a line given every
    /// millimetre or so is the smooth line it stands for, while a real kink stays a tight
    /// bend that the spread cap refuses.
    fn smooth(pts: &[V3]) -> Result<Curve, Error> {
        let length: f64 = pts.windows(2).map(|w| norm(sub(w[1], w[0]))).sum();
        if length / 0.05 > 2_000_000.0 {
            return Err(Error::Invalid(format!(
                "--curve: {length:.0} mm long, more than 100 m"
            )));
        }
        let at = |i: isize| pts[i.clamp(0, pts.len() as isize - 1) as usize];
        let mut out = vec![pts[0]];
        for i in 0..pts.len() - 1 {
            let i = i as isize;
            let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
            let n = ((norm(sub(p2, p1)) / 0.05).ceil() as usize).max(1);
            for k in 1..=n {
                let t = k as f64 / n as f64;
                let (t2, t3) = (t * t, t * t * t);
                let c = |j: usize| {
                    0.5 * (2.0 * p1[j]
                        + (p2[j] - p0[j]) * t
                        + (2.0 * p0[j] - 5.0 * p1[j] + 4.0 * p2[j] - p3[j]) * t2
                        + (3.0 * p1[j] - p0[j] - 3.0 * p2[j] + p3[j]) * t3)
                };
                out.push([c(0), c(1), c(2)]);
            }
        }
        Ok(Curve { points: out })
    }

    pub fn length(&self) -> f64 {
        self.points.windows(2).map(|w| norm(sub(w[1], w[0]))).sum()
    }
}

/// The cross-section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Section {
    Circle { d: f64 },
    Rect { w: f64, h: f64 },
}

impl Section {
    pub fn parse(text: &str) -> Result<Section, Error> {
        let bad = || Error::Invalid(format!("--section {text}: give circle:D or rect:W,H (mm)"));
        let (kind, args) = text.split_once(':').ok_or_else(bad)?;
        let nums: Vec<f64> = args
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad())?;
        let ok = |v: f64| v.is_finite() && (0.5..=1000.0).contains(&v);
        match (kind, nums.as_slice()) {
            ("circle", [d]) if ok(*d) => Ok(Section::Circle { d: *d }),
            ("rect", [w, h]) if ok(*w) && ok(*h) => Ok(Section::Rect { w: *w, h: *h }),
            _ => Err(bad()),
        }
    }

    /// Farthest reach from the line (mm).
    fn reach(&self) -> f64 {
        match *self {
            Section::Circle { d } => d / 2.0,
            Section::Rect { w, h } => w.hypot(h) / 2.0,
        }
    }

    /// The contour of the section inset by `inset`, as points (a, b) in the plane, closed,
    /// counter-clockwise, about every `step` mm.
    fn contour(&self, inset: f64, step: f64) -> Vec<[f64; 2]> {
        match *self {
            Section::Circle { d } => {
                let r = (d / 2.0 - inset).max(0.0);
                let n = ((std::f64::consts::TAU * r / step).ceil() as usize).max(12);
                (0..=n)
                    .map(|i| {
                        let t = std::f64::consts::TAU * i as f64 / n as f64;
                        [r * t.cos(), r * t.sin()]
                    })
                    .collect()
            }
            Section::Rect { w, h } => {
                let (x, y) = ((w / 2.0 - inset).max(0.0), (h / 2.0 - inset).max(0.0));
                vec![[-x, -y], [x, -y], [x, y], [-x, y], [-x, -y]]
            }
        }
    }

    /// Whether (a, b) lies inside the section inset by `inset`.
    fn inside(&self, a: f64, b: f64, inset: f64) -> bool {
        match *self {
            Section::Circle { d } => a.hypot(b) <= d / 2.0 - inset + 1e-9,
            Section::Rect { w, h } => {
                a.abs() <= w / 2.0 - inset + 1e-9 && b.abs() <= h / 2.0 - inset + 1e-9
            }
        }
    }

    /// Zigzag infill inside the section inset by `inset`, lines `spacing` apart along `a`
    /// (or along `b` when `across`), joined end to end.
    fn zigzag(&self, inset: f64, spacing: f64, across: bool) -> Vec<[f64; 2]> {
        let half = self.reach() + spacing;
        let mut out = Vec::new();
        let mut k = 0usize;
        let mut c = -half;
        while c <= half {
            // The chord of the inset section at this line.
            let (lo, hi) = {
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                let n = 400;
                for i in 0..=n {
                    let t = -half + 2.0 * half * i as f64 / n as f64;
                    let (a, b) = if across { (t, c) } else { (c, t) };
                    if self.inside(a, b, inset) {
                        lo = lo.min(t);
                        hi = hi.max(t);
                    }
                }
                (lo, hi)
            };
            if lo.is_finite() && hi - lo > 1e-6 {
                let (s, e) = if k % 2 == 0 { (lo, hi) } else { (hi, lo) };
                for t in [s, e] {
                    out.push(if across { [t, c] } else { [c, t] });
                }
                k += 1;
            }
            c += spacing;
        }
        out
    }
}

/// A frame along the curve: point, tangent, and a side vector `u` (towards the outside of the
/// bend where it bends), transported without twist.
struct Frame {
    p: V3,
    t: V3,
    u: V3,
    /// Curvature (1/mm) towards -u.
    kappa: f64,
}

fn frames(curve: &Curve) -> Vec<(f64, Frame)> {
    let pts = &curve.points;
    let mut out = Vec::with_capacity(pts.len());
    let mut s = 0.0;
    let mut u: V3 = [1.0, 0.0, 0.0];
    for i in 0..pts.len() {
        let t = if i + 1 < pts.len() {
            unit(sub(pts[i + 1], pts[i]))
        } else {
            unit(sub(pts[i], pts[i - 1]))
        }
        .unwrap_or([0.0, 0.0, 1.0]);
        // Parallel transport: u made perpendicular to t again.
        let proj = sub(u, scale(t, dot(u, t)));
        u = unit(proj)
            .unwrap_or_else(|| unit(cross(t, [0.0, 1.0, 0.0])).unwrap_or([1.0, 0.0, 0.0]));
        let kappa = if i > 0 && i + 1 < pts.len() {
            let a = unit(sub(pts[i], pts[i - 1])).unwrap_or(t);
            let b = t;
            let turn = dot(a, b).clamp(-1.0, 1.0).acos();
            let l = (norm(sub(pts[i + 1], pts[i])) + norm(sub(pts[i], pts[i - 1]))) / 2.0;
            // Signed along u: the bend's centre lies on the side the tangent turns to.
            let dir = sub(b, a);
            let sign = if dot(dir, u) > 0.0 { -1.0 } else { 1.0 };
            sign * turn / l.max(1e-9)
        } else {
            0.0
        };
        if i > 0 {
            s += norm(sub(pts[i], pts[i - 1]));
        }
        out.push((
            s,
            Frame {
                p: pts[i],
                t,
                u,
                kappa,
            },
        ));
    }
    out
}

/// The frame at arc length `s` (linear between samples).
fn frame_at(fr: &[(f64, Frame)], s: f64) -> Frame {
    let i = fr.partition_point(|(x, _)| *x < s).clamp(1, fr.len() - 1);
    let (s0, a) = (&fr[i - 1].0, &fr[i - 1].1);
    let (s1, b) = (&fr[i].0, &fr[i].1);
    let f = if s1 > s0 {
        ((s - s0) / (s1 - s0)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let lerp = |x: V3, y: V3| add(x, scale(sub(y, x), f));
    let t = unit(lerp(a.t, b.t)).unwrap_or(a.t);
    let u = unit(sub(lerp(a.u, b.u), scale(t, dot(lerp(a.u, b.u), t)))).unwrap_or(a.u);
    Frame {
        p: lerp(a.p, b.p),
        t,
        u,
        kappa: a.kappa + (b.kappa - a.kappa) * f,
    }
}

/// Settings of a sweep.
#[derive(Debug, Clone, Copy)]
pub struct SweepSettings {
    /// Bead width (mm).
    pub width: f64,
    /// Layer step along the line (mm).
    pub height: f64,
    pub filament_area: f64,
    /// Where the line starts on the bed (mm).
    pub at: [f64; 2],
}

/// The swept part's workpiece path (see the module doc).
pub fn sweep(
    curve: &Curve,
    section: Section,
    set: &SweepSettings,
) -> Result<Vec<PathPoint>, Error> {
    let (w, h) = (set.width, set.height);
    let ok = w.is_finite() && (0.1..=3.0).contains(&w) && h.is_finite() && (0.02..=w).contains(&h);
    if !ok {
        return Err(Error::Invalid(format!(
            "width {w} and layer step {h}: width 0.1-3 mm, step 0.02 mm up to the width"
        )));
    }
    let fr = frames(curve);
    let reach = section.reach();
    // The spread cap: thickness within 0.5-1.5 h everywhere.
    if let Some((s, f)) = fr.iter().find(|(_, f)| f.kappa.abs() * reach > 0.5) {
        return Err(Error::Invalid(format!(
            "the line bends with radius {:.2} mm at {:.1} mm along it (point {:.2} {:.2} {:.2}): the section reaches {reach:.2} mm from the line, more than half the radius, so layers would be thinner than half the step inside the bend; use a smaller section or a gentler curve",
            1.0 / f.kappa.abs(),
            s,
            f.p[0],
            f.p[1],
            f.p[2]
        )));
    }
    let length = curve.length();
    let layers = (length / h).floor() as usize;
    let contour = section.contour(w / 2.0, 0.5);
    let per_layer = contour.len() as f64 + 2.0 * (2.0 * section.reach() / w + 2.0);
    if layers as f64 * per_layer > 20e6 {
        return Err(Error::Invalid(format!(
            "{layers} layers of about {per_layer:.0} points: more than 20 million; use a thicker step, a smaller section or a shorter line"
        )));
    }
    if layers == 0 {
        return Err(Error::Invalid(format!(
            "the line is {length:.2} mm long, shorter than one step"
        )));
    }
    let base = [set.at[0], set.at[1], 0.0];
    let mut out: Vec<PathPoint> = Vec::new();
    let m = contour.len() - 1;
    for k in 0..layers {
        let s = (k as f64 + 1.0) * h;
        let f = frame_at(&fr, s);
        let v = cross(f.t, f.u);
        let place = |ab: [f64; 2]| add(base, add(f.p, add(scale(f.u, ab[0]), scale(v, ab[1]))));
        // Local thickness at offset a along u: h (1 + kappa_signed a), kappa > 0 bending
        // towards -u (the inside is at negative a).
        let thick = |ab: [f64; 2]| h * (1.0 + f.kappa * ab[0]);
        // Even layers (2nd, 4th, ... counted from 1) start at the middle segmentation point N.
        let start = if k % 2 == 1 { m / 2 } else { 0 };
        let mut pts: Vec<[f64; 2]> = (0..=m).map(|i| contour[(start + i) % m]).collect();
        pts.extend(section.zigzag(w, w, k % 2 == 1));
        for ab in pts {
            let p = place(ab);
            let e = match out.last() {
                Some(prev) => {
                    let len = norm(sub(p, prev.p));
                    // Slic3r's bead of the local thickness (the flow model poa uses).
                    let t = thick(ab).min(w);
                    ((w - t) * t + std::f64::consts::PI * t * t / 4.0) * len / set.filament_area
                }
                None => 0.0,
            };
            out.push(PathPoint {
                p,
                n: f.t,
                e,
                layer: k,
            });
        }
    }
    Ok(out)
}

/// The swept part as an ASCII STL (rings of the section every half millimetre along the
/// line, closed by fans at both ends): for slicing it the three-axis way to compare.
pub fn stl(curve: &Curve, section: Section, at: [f64; 2]) -> String {
    use std::fmt::Write as _;
    let fr = frames(curve);
    let length = curve.length();
    let steps = ((length / 0.5).ceil() as usize).max(1);
    let ring = section.contour(0.0, 0.5);
    let m = ring.len() - 1;
    let base = [at[0], at[1], 0.0];
    let rings: Vec<Vec<V3>> = (0..=steps)
        .map(|i| {
            let f = frame_at(&fr, length * i as f64 / steps as f64);
            let v = cross(f.t, f.u);
            ring[..m]
                .iter()
                .map(|ab| add(base, add(f.p, add(scale(f.u, ab[0]), scale(v, ab[1])))))
                .collect()
        })
        .collect();
    let mut s = String::from("solid poa_sweep\n");
    let mut tri = |a: V3, b: V3, c: V3| {
        let n = unit(cross(sub(b, a), sub(c, a))).unwrap_or([0.0, 0.0, 1.0]);
        let _ = writeln!(
            s,
            "facet normal {:.6} {:.6} {:.6}\n outer loop\n  vertex {:.5} {:.5} {:.5}\n  vertex {:.5} {:.5} {:.5}\n  vertex {:.5} {:.5} {:.5}\n endloop\nendfacet",
            n[0], n[1], n[2], a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]
        );
    };
    for w in rings.windows(2) {
        for k in 0..m {
            let (a, b) = (w[0][k], w[0][(k + 1) % m]);
            let (c, d) = (w[1][k], w[1][(k + 1) % m]);
            tri(a, b, d);
            tri(a, d, c);
        }
    }
    let centre = |r: &Vec<V3>| {
        let n = r.len() as f64;
        r.iter()
            .fold([0.0; 3], |acc, p| add(acc, scale(*p, 1.0 / n)))
    };
    let (first, last) = (&rings[0], &rings[steps]);
    let (c0, c1) = (centre(first), centre(last));
    for k in 0..m {
        tri(c0, first[(k + 1) % m], first[k]);
        tri(c1, last[k], last[(k + 1) % m]);
    }
    s.push_str("endsolid poa_sweep\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_arc_is_as_long_as_its_angle_and_ends_where_it_should() {
        let c = Curve::arc(30.0, 90.0).unwrap();
        assert!((c.length() - 30.0 * std::f64::consts::FRAC_PI_2).abs() < 0.01);
        let end = *c.points.last().unwrap();
        assert!(
            (end[0] - 30.0).abs() < 1e-6 && (end[2] - 30.0).abs() < 1e-6,
            "{end:?}"
        );
    }

    #[test]
    fn sections_and_presets_are_read_or_refused() {
        assert_eq!(
            Section::parse("circle:12").unwrap(),
            Section::Circle { d: 12.0 }
        );
        assert!(Section::parse("circle:0").is_err());
        assert!(Section::parse("hex:3").is_err());
        assert!(Curve::preset("arc:30").is_err());
        assert!(Curve::preset("spiral:3,4").is_err());
        assert!(Curve::csv("x,y,z\n0,0,0\n0,0,5\n").is_ok());
        assert!(Curve::csv("0,0,0\n0,0,oops\n")
            .unwrap_err()
            .to_string()
            .contains("line 2"));
    }
}
