//! Printability of a layer-less (helical) print, judged in 3D: Kanada's condition that every
//! string rests on one printed before it.
//!
//! Input: G-code text and its [`Helix`]. Output: a [`Report`] with counts per rule, the first
//! failing point (turn, lean angle, x y z, rule) and sampled points for pictures.
//!
//! Model (stated in the README): extrusions are sampled every quarter bead width in file
//! order; everything before the helix is material that exists (it is not judged here: the
//! layered check covers it). A helix point is judged against all earlier material nearby,
//! except the last [`GUARD_WIDTHS`] widths of its own path (the bead it is part of):
//! - **support**: an earlier bead centre within `reach = max(1.05 h, 0.75 w)` of it in 3D (a
//!   bead lies on or beside one that overlaps it by at least a quarter of its width; plain
//!   stacking at the sliced pitch `h` passes);
//! - **collision**: no earlier material within the nozzle's radius (horizontally) higher than
//!   the nozzle tip (+0.03 mm);
//! - from the second turn on, against the nearest earlier point S when it is the helix's: **lift** `z - S.z` between
//!   5 % and 100 % of `h` (+0.03 mm), and **lean** (angle of P - S from the vertical) at most
//!   85 degrees.

use std::collections::VecDeque;

use rustc_hash::FxHashMap as HashMap;

use crate::helix::Helix;

/// Own-path length excluded from support, in bead widths.
pub const GUARD_WIDTHS: f64 = 4.0;
/// Lift per turn allowed, as shares of the sliced pitch.
pub const LIFT_MIN: f64 = 0.05;
pub const LIFT_MAX: f64 = 1.0;
/// Largest lean from the vertical (degrees).
pub const LEAN_MAX: f64 = 85.0;
/// Slack on heights (mm): slicers round Z to 0.001-0.01 mm.
const Z_SLACK: f64 = 0.03;

/// The bead and nozzle the check judges with.
#[derive(Debug, Clone, Copy)]
pub struct Bead {
    /// Bead width (mm).
    pub width: f64,
    /// Sliced pitch: the bead height (mm).
    pub height: f64,
    /// Nozzle radius (mm).
    pub nozzle_radius: f64,
}

impl Bead {
    pub fn reach(&self) -> f64 {
        (1.05 * self.height).max(0.75 * self.width)
    }
}

/// Which rule a point breaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rule {
    Support,
    Collision,
    Lift,
    Lean,
}

impl Rule {
    pub fn describe(self) -> &'static str {
        match self {
            Rule::Support => "no earlier material within reach (printed in air)",
            Rule::Collision => "the nozzle tip would be below material already printed",
            Rule::Lift => "lift over the turn below out of 5-100 % of the bead height",
            Rule::Lean => "leans more than 85 deg from the vertical over the turn below",
        }
    }
}

/// The first point that breaks a rule.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Finding {
    pub rule: Rule,
    pub turn: f64,
    pub lean_deg: f64,
    pub lift_mm: f64,
    pub point: [f64; 3],
    pub line: u64,
}

impl std::fmt::Display for Finding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "turn {:.2}, line {}, x {:.3} y {:.3} z {:.3}",
            self.turn, self.line, self.point[0], self.point[1], self.point[2]
        )?;
        if matches!(self.rule, Rule::Lift | Rule::Lean) {
            write!(
                f,
                ", lean {:.1} deg, lift {:.3} mm",
                self.lean_deg, self.lift_mm
            )?;
        }
        write!(f, ": {}", self.rule.describe())
    }
}

/// One judged point (for pictures).
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub p: [f64; 3],
    pub ok: bool,
}

/// What the check found.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Report {
    pub points: u64,
    pub unsupported: u64,
    pub collisions: u64,
    pub lift_out_of_range: u64,
    pub too_steep: u64,
    /// Largest lean over the turn below seen (degrees), from the second turn on.
    pub max_lean_deg: f64,
    pub turns: f64,
    pub first: Option<Finding>,
    /// Length of helix path printed without support (mm).
    pub in_air_mm: f64,
    #[serde(skip)]
    pub samples: Vec<Sample>,
}

impl Report {
    pub fn ok(&self) -> bool {
        self.first.is_none()
    }
}

type Key = (i32, i32, i32);

/// Most points judged along one move: a quarter width apart over 500 mm, longer than any
/// bed; a longer move is judged at points farther apart.
const MAX_MOVE_SAMPLES: usize = 5000;

struct Grid {
    cell: f64,
    cells: HashMap<Key, Vec<([f64; 3], bool)>>,
    /// Highest material per fine XY cell (for collisions). Bounded by the print's
    /// footprint, not its height.
    tops: HashMap<(i32, i32), f64>,
    fine: f64,
    /// Lowest Z key still held in `cells`: slabs the helix has risen past are dropped, so
    /// memory follows one band of turns, not the whole print.
    floor: i32,
    /// Highest material of all (a point below it by more than the slack can skip the
    /// collision search).
    max_top: f64,
}

impl Grid {
    fn key(&self, p: [f64; 3]) -> Key {
        (
            (p[0] / self.cell).floor() as i32,
            (p[1] / self.cell).floor() as i32,
            (p[2] / self.cell).floor() as i32,
        )
    }

    /// `helix`: material of the helix (the lift and lean rules judge against it only).
    fn insert(&mut self, p: [f64; 3], helix: bool) {
        let k = self.key(p);
        self.cells.entry(k).or_default().push((p, helix));
        let f = (
            (p[0] / self.fine).floor() as i32,
            (p[1] / self.fine).floor() as i32,
        );
        let t = self.tops.entry(f).or_insert(f64::NEG_INFINITY);
        *t = t.max(p[2]);
        self.max_top = self.max_top.max(p[2]);
    }

    /// Drops the slabs that no point at or above `p` can reach: the helix rises, so a
    /// later point searches Z keys from `key(p).2 - 1` up. Done every few slabs (a pass
    /// over the band held).
    fn rise_to(&mut self, p: [f64; 3]) {
        let keep = self.key(p).2 - 1;
        if keep > self.floor + 2 {
            self.cells.retain(|k, _| k.2 >= keep);
            // Only material above a later point can collide with it.
            self.tops.retain(|_, t| *t > p[2]);
            self.floor = keep;
        }
    }

    /// Nearest material point within one cell around `p` (point, distance, on the helix),
    /// and the highest material within `radius` (at most a cell) horizontally of `p` in
    /// those cells: what the bead lies on.
    fn probe(&self, p: [f64; 3], radius: f64) -> (Option<([f64; 3], f64, bool)>, f64) {
        let k = self.key(p);
        let mut best: Option<([f64; 3], f64, bool)> = None;
        let mut under = f64::NEG_INFINITY;
        let r2 = radius * radius;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(v) = self.cells.get(&(k.0 + dx, k.1 + dy, k.2 + dz)) else {
                        continue;
                    };
                    for (q, h) in v {
                        let h2 = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2);
                        if h2 <= r2 {
                            under = under.max(q[2]);
                        }
                        let d = (h2 + (q[2] - p[2]).powi(2)).sqrt();
                        if best.is_none_or(|b| d < b.1) {
                            best = Some((*q, d, *h));
                        }
                    }
                }
            }
        }
        (best, under)
    }

    /// Highest material within `radius` (horizontally) of `p`.
    fn top_near(&self, p: [f64; 3], radius: f64) -> f64 {
        if self.max_top <= p[2] {
            return self.max_top;
        }
        let n = (radius / self.fine).ceil() as i32;
        let (cx, cy) = (
            (p[0] / self.fine).floor() as i32,
            (p[1] / self.fine).floor() as i32,
        );
        let mut top = f64::NEG_INFINITY;
        for i in -n..=n {
            for j in -n..=n {
                // Cells whose nearest point is within the radius.
                let gx = ((i.abs() - 1).max(0)) as f64 * self.fine;
                let gy = ((j.abs() - 1).max(0)) as f64 * self.fine;
                if gx * gx + gy * gy > radius * radius {
                    continue;
                }
                if let Some(t) = self.tops.get(&(cx + i, cy + j)) {
                    top = top.max(*t);
                }
            }
        }
        top
    }
}

/// Judges every point of `helix` in `text` (see the module doc). `keep_samples` keeps at
/// most that many judged points, evenly spread, for pictures.
pub fn check(text: &[u8], helix: &Helix, bead: Bead, keep_samples: usize) -> Report {
    // (A text in memory is read without error.)
    check_in(text, helix, bead, keep_samples).unwrap_or_default()
}

/// [`check`] of the print `src` reads (one pass; a file is read a line at a time).
pub fn check_in<S: crate::helix::Source + ?Sized>(
    src: &S,
    helix: &Helix,
    bead: Bead,
    keep_samples: usize,
) -> Result<Report, crate::error::Error> {
    let step = (bead.width / 4.0).max(0.02);
    let guard = GUARD_WIDTHS * bead.width;
    let mut grid = Grid {
        cell: bead.reach().max(bead.nozzle_radius),
        cells: HashMap::default(),
        tops: HashMap::default(),
        fine: (bead.nozzle_radius / 2.0).max(0.05),
        floor: i32::MIN,
        max_top: f64::NEG_INFINITY,
    };
    let mut report = Report {
        turns: helix.turns,
        ..Report::default()
    };
    // Helix samples not yet material: (path length, point).
    let mut pending: VecDeque<(f64, [f64; 3])> = VecDeque::new();
    let mut path = 0.0;
    let mut angle = 0.0f64;
    let mut prev_angle: Option<f64> = None;
    let every = (helix.length / step / keep_samples.max(1) as f64)
        .ceil()
        .max(1.0) as u64;
    let c = helix.center;
    src.each_move(&mut |m, _| {
        if !m.is_extrusion() || m.line > helix.last_line {
            return;
        }
        let pts = m.points(0.01);
        let total = crate::geometry::polyline_length(&pts);
        let len3 = (total.powi(2) + (m.to[2] - m.from[2]).powi(2)).sqrt();
        // (A move of a damaged file can run for kilometres, Z 99999 or X 1299999: judged
        // at most [`MAX_MOVE_SAMPLES`] times, 100 s and more before for one vase.)
        let n = ((len3 / step).ceil() as usize).clamp(1, MAX_MOVE_SAMPLES);
        let at = |f: f64| -> [f64; 3] {
            // Point at share f of the move (along the XY polyline, Z linear).
            let want = f * total;
            let mut acc = 0.0;
            for w in pts.windows(2) {
                let l = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
                if acc + l >= want || l == 0.0 {
                    let t = if l > 0.0 {
                        ((want - acc) / l).clamp(0.0, 1.0)
                    } else {
                        1.0
                    };
                    return [
                        w[0][0] + (w[1][0] - w[0][0]) * t,
                        w[0][1] + (w[1][1] - w[0][1]) * t,
                        m.from[2] + (m.to[2] - m.from[2]) * f,
                    ];
                }
                acc += l;
            }
            m.to
        };
        if m.line < helix.first_line {
            for i in 0..=n {
                grid.insert(at(i as f64 / n as f64), false);
            }
            return;
        }
        let piece = len3 / n as f64;
        for i in 1..=n {
            let p = at(i as f64 / n as f64);
            path += piece;
            while pending.front().is_some_and(|(l, _)| *l < path - guard) {
                let (_, q) = pending.pop_front().unwrap();
                grid.insert(q, true);
            }
            let a = (p[1] - c[1]).atan2(p[0] - c[0]);
            if let Some(pa) = prev_angle {
                let mut d = a - pa;
                while d > std::f64::consts::PI {
                    d -= std::f64::consts::TAU;
                }
                while d < -std::f64::consts::PI {
                    d += std::f64::consts::TAU;
                }
                angle += d;
            }
            prev_angle = Some(a);
            let turn = angle.abs() / std::f64::consts::TAU;
            report.points += 1;
            grid.rise_to(p);
            let (near, under) = grid.probe(p, bead.width / 2.0);
            let mut broken = None;
            let (mut lean, mut lift) = (0.0, 0.0);
            match near {
                Some((s, d, on_helix)) if d <= bead.reach() => {
                    let horiz = (p[0] - s[0]).hypot(p[1] - s[1]);
                    lean = horiz.atan2(p[2] - s[2]).to_degrees();
                    // Lift: above the highest earlier material under the bead (within
                    // half a width, in the cells around it: a cell is at least a bead
                    // height); a bead leaning beside the one below has none.
                    lift = if under.is_finite() {
                        p[2] - under
                    } else {
                        bead.height
                    };
                    if turn >= 1.0 && on_helix {
                        report.max_lean_deg = report.max_lean_deg.max(lean);
                        if lift < LIFT_MIN * bead.height || lift > LIFT_MAX * bead.height + Z_SLACK
                        {
                            report.lift_out_of_range += 1;
                            broken = Some(Rule::Lift);
                        } else if lean > LEAN_MAX {
                            report.too_steep += 1;
                            broken = Some(Rule::Lean);
                        }
                    }
                }
                _ => {
                    report.unsupported += 1;
                    report.in_air_mm += piece;
                    broken = Some(Rule::Support);
                }
            }
            if grid.top_near(p, bead.nozzle_radius) > p[2] + Z_SLACK {
                report.collisions += 1;
                broken = broken.or(Some(Rule::Collision));
            }
            if let (Some(rule), None) = (broken, &report.first) {
                report.first = Some(Finding {
                    rule,
                    turn,
                    lean_deg: lean,
                    lift_mm: lift,
                    point: p,
                    line: m.line,
                });
            }
            if keep_samples > 0 && report.points % every == 0 {
                report.samples.push(Sample {
                    p,
                    ok: broken.is_none(),
                });
            }
            pending.push_back((path, p));
        }
    })?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::helix::{find, tests::vase};

    const BEAD: Bead = Bead {
        width: 0.45,
        height: 0.2,
        nozzle_radius: 0.2,
    };

    #[test]
    fn a_plain_vase_stands_and_a_turn_set_off_sideways_does_not() {
        let text = vase(15.0, 0.2, 10);
        let h = find(text.as_bytes()).unwrap();
        let r = check(text.as_bytes(), &h, BEAD, 100);
        assert!(r.ok(), "{:?}", r.first);
        assert!(r.points > 1000 && r.max_lean_deg < 5.0, "{r:?}");
        // The same helix, each turn 0.6 mm farther out: off the one below.
        let mut shifted = String::new();
        for line in text.lines() {
            let words: Vec<&str> = line.split(' ').collect();
            let z = words
                .iter()
                .find_map(|w| w.strip_prefix('Z'))
                .and_then(|z| z.parse::<f64>().ok());
            match (z, line.contains(" E")) {
                (Some(z), true) => {
                    let x: f64 = words[1][1..].parse().unwrap();
                    let y: f64 = words[2][1..].parse().unwrap();
                    let k = 1.0 + 3.0 * (z - 0.2) / 15.0;
                    let (x, y) = (100.0 + (x - 100.0) * k, 100.0 + (y - 100.0) * k);
                    shifted.push_str(&format!("G1 X{x:.3} Y{y:.3} Z{z:.4} {}\n", words[4]));
                }
                _ => {
                    shifted.push_str(line);
                    shifted.push('\n');
                }
            }
        }
        let h = find(shifted.as_bytes()).unwrap();
        let r = check(shifted.as_bytes(), &h, BEAD, 0);
        let f = r.first.clone().expect("refused");
        assert_eq!(f.rule, Rule::Support, "{f}");
        assert!(f.turn < 1.2, "{f}");
    }

    #[test]
    fn a_move_of_a_damaged_file_kilometres_long_is_judged_at_a_bounded_number_of_points() {
        let text = vase(15.0, 0.2, 10);
        let h = find(text.as_bytes()).unwrap();
        let whole = check(text.as_bytes(), &h, BEAD, 0).points;
        // One extrusion in the middle of the helix sent 100 m up (a flipped digit), and the
        // next one back down.
        let lines: Vec<&str> = text.lines().collect();
        let k = (h.first_line as usize + h.last_line as usize) / 2 - 1;
        let mut damaged = String::new();
        for (i, line) in lines.iter().enumerate() {
            if i == k {
                let words: Vec<String> = line
                    .split(' ')
                    .map(|w| match w.strip_prefix('Z') {
                        Some(_) => "Z99999".to_string(),
                        None => w.to_string(),
                    })
                    .collect();
                damaged.push_str(&words.join(" "));
            } else {
                damaged.push_str(line);
            }
            damaged.push('\n');
        }
        let h = find(damaged.as_bytes()).unwrap();
        let r = check(damaged.as_bytes(), &h, BEAD, 0);
        assert!(!r.ok(), "a move 100 m long is no printable helix");
        // There and back: two moves of at most MAX_MOVE_SAMPLES points more than the helix.
        assert!(
            r.points <= whole + 2 * MAX_MOVE_SAMPLES as u64,
            "{} points judged, {whole} without the damage",
            r.points
        );
    }
}
