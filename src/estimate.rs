//! Print-time estimate with a trapezoidal motion model.
//!
//! Input: parsed lines and the [`Action`]s the interpreter made of them, in file order, and
//! the file's [`SlicerConfig`]. Output: the time the printer takes, in seconds, and marks of
//! the time reached at source lines (for progress lines).
//!
//! The model is the one printer firmware plans with (and PrusaSlicer's estimator mirrors): each
//! move accelerates from its entry speed to its cruise speed and decelerates to the next
//! move's entry speed; junction speeds follow the classic per-axis jerk rule; moves are
//! planned in windows (a backward then a forward pass) the way a firmware planner queue sees
//! them. Limits (per-axis feedrate, acceleration and jerk; print, retract and travel
//! accelerations) come from the config block and change with M201, M203, M204 and M205 in the
//! file. Dwells and heat-up waits count nothing: their length depends on the printer, not on
//! the file.
//!
//! Invariants: never fails and never returns a negative or non-finite time; a move with no
//! known feedrate takes no time.

// Per-axis quantities live in parallel [X, Y, Z, E] arrays; an axis index reads clearest.
#![allow(clippy::needless_range_loop)]

use crate::config::SlicerConfig;
use crate::gcode::{Command, Parsed};
use crate::machine::{Action, Move};

const X: usize = 0;
const Y: usize = 1;
const Z: usize = 2;
const E: usize = 3;

/// Blocks the planner holds before it commits the oldest ones.
const REFRESH: usize = 256;
/// Blocks kept back (and replanned with the next window) when committing.
const KEEP: usize = 64;

/// Motion limits of the printer, in mm/s and mm/s2.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    pub max_feedrate: [f64; 4],
    pub max_acceleration: [f64; 4],
    pub max_jerk: [f64; 4],
    /// Caps on the print, retract and travel accelerations (0 = no cap).
    pub max_extruding: f64,
    pub max_retracting: f64,
    pub max_travel: f64,
    pub min_extruding_rate: f64,
    pub min_travel_rate: f64,
    /// M203 values are in mm/s (Marlin) rather than mm/min (RepRapFirmware, Klipper).
    pub m203_per_second: bool,
    /// Initial accelerations.
    pub extruding: f64,
    pub retracting: f64,
    pub travel: f64,
}

/// Whether a firmware of `flavor` (lower case, as PrusaSlicer or Cura name it) reads M203 in
/// mm/s: the Marlin family (Cura's UltiGCode and Griffin run Marlin derivatives) and
/// Smoothie; RepRapFirmware and the older firmwares read mm/min. Cura writes
/// `M203 X500 Y500` for a Creality CR-10: read as mm/min it capped every move at 8 mm/s.
fn m203_per_second(flavor: &str) -> bool {
    matches!(
        flavor,
        "" | "marlin"
            | "marlin2"
            | "marlinlegacy"
            | "smoothie"
            | "reprap (marlin/sprinter)"
            | "ultigcode"
            | "griffin"
            | "reprap (volumetric)"
    )
}

/// Firmware defaults when a file states no limits (PrusaSlicer's defaults, which are those of
/// a typical Marlin printer).
impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_feedrate: [500.0, 500.0, 12.0, 120.0],
            max_acceleration: [9000.0, 9000.0, 500.0, 10000.0],
            max_jerk: [10.0, 10.0, 0.2, 2.5],
            max_extruding: 1500.0,
            max_retracting: 1500.0,
            max_travel: 0.0,
            min_extruding_rate: 0.0,
            min_travel_rate: 0.0,
            m203_per_second: true,
            extruding: 1500.0,
            retracting: 1500.0,
            travel: 1250.0,
        }
    }
}

impl Limits {
    /// Limits from a slicer's config block (PrusaSlicer, SuperSlicer, OrcaSlicer keys).
    pub fn from_config(config: &SlicerConfig) -> Limits {
        let mut l = Limits::default();
        // PrusaSlicer writes `marlin2`, Cura `Marlin` or `RepRap (Marlin/Sprinter)`.
        let flavor = config
            .get("gcode_flavor")
            .unwrap_or("")
            .trim()
            .to_ascii_lowercase();
        let usage = config
            .get("machine_limits_usage")
            .unwrap_or("time_estimate_only")
            .trim()
            .to_string();
        l.m203_per_second = m203_per_second(&flavor);
        let uses_limits = matches!(
            flavor.as_str(),
            "marlin" | "marlin2" | "reprapfirmware" | "klipper"
        ) && usage != "ignore";
        if !uses_limits {
            return l;
        }
        let num = |k: &str| config.number(k).filter(|v| *v >= 0.0);
        for (i, axis) in ["x", "y", "z", "e"].iter().enumerate() {
            if let Some(v) = num(&format!("machine_max_feedrate_{axis}")) {
                l.max_feedrate[i] = v;
            }
            if let Some(v) = num(&format!("machine_max_acceleration_{axis}")) {
                l.max_acceleration[i] = v;
            }
            if let Some(v) = num(&format!("machine_max_jerk_{axis}")) {
                l.max_jerk[i] = v;
            }
        }
        if let Some(v) = num("machine_max_acceleration_extruding") {
            l.max_extruding = v;
        }
        if let Some(v) = num("machine_max_acceleration_retracting") {
            l.max_retracting = v;
        }
        l.min_extruding_rate = num("machine_min_extruding_rate").unwrap_or(0.0);
        l.min_travel_rate = num("machine_min_travel_rate").unwrap_or(0.0);
        if flavor == "reprapfirmware" {
            l.min_extruding_rate = 0.0;
            l.min_travel_rate = 0.0;
        }
        // Only these firmwares take a travel acceleration of its own, and the slicer only
        // states it when it writes the limits into the file.
        let separate_travel =
            matches!(flavor.as_str(), "marlin2" | "reprapfirmware") && usage == "emit_to_gcode";
        l.max_travel = if separate_travel {
            num("machine_max_acceleration_travel").unwrap_or(0.0)
        } else {
            0.0
        };
        l.extruding = if l.max_extruding > 0.0 {
            l.max_extruding
        } else {
            1500.0
        };
        l.retracting = if l.max_retracting > 0.0 {
            l.max_retracting
        } else {
            1500.0
        };
        l.travel = if l.max_travel > 0.0 {
            l.max_travel
        } else {
            1250.0
        };
        l
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct Block {
    line: u64,
    distance: f64,
    acceleration: f64,
    cruise: f64,
    safe: f64,
    entry: f64,
    max_entry: f64,
    exit: f64,
    nominal_length: bool,
    recalculate: bool,
    accelerate_until: f64,
    decelerate_after: f64,
    cruise_reached: f64,
}

impl Block {
    fn trapezoid(&mut self) {
        let (v0, vc, v1, a, d) = (
            self.entry,
            self.cruise,
            self.exit,
            self.acceleration,
            self.distance,
        );
        let dist = |from: f64, to: f64| {
            if a > 0.0 {
                ((to * to - from * from) / (2.0 * a)).max(0.0)
            } else {
                0.0
            }
        };
        let mut s_acc = dist(v0, vc);
        let s_dec = dist(v1, vc);
        let mut s_cruise = d - s_acc - s_dec;
        let mut reached = vc;
        if s_cruise < 0.0 {
            s_acc = if a > 0.0 {
                ((2.0 * a * d - v0 * v0 + v1 * v1) / (4.0 * a)).clamp(0.0, d)
            } else {
                0.0
            };
            s_cruise = 0.0;
            reached = (v0 * v0 + 2.0 * a * s_acc).max(0.0).sqrt();
        }
        self.accelerate_until = s_acc;
        self.decelerate_after = s_acc + s_cruise;
        self.cruise_reached = reached;
    }

    fn time(&self) -> f64 {
        let a = self.acceleration;
        let v0 = self.entry;
        let vc = self.cruise_reached;
        let t_acc = if a > 0.0 {
            ((v0 * v0 + 2.0 * a * self.accelerate_until).max(0.0).sqrt() - v0) / a
        } else {
            0.0
        };
        let t_cruise = if vc > 0.0 {
            (self.decelerate_after - self.accelerate_until) / vc
        } else {
            0.0
        };
        let s_dec = self.distance - self.decelerate_after;
        let t_dec = if a > 0.0 {
            (vc - (vc * vc - 2.0 * a * s_dec).max(0.0).sqrt()) / a
        } else {
            0.0
        };
        let t = t_acc + t_cruise + t_dec;
        if t.is_finite() {
            t.max(0.0)
        } else {
            0.0
        }
    }
}

/// The previous move as the junction rule needs it.
#[derive(Debug, Clone, Copy)]
struct Prev {
    feedrate: f64,
    axis: [f64; 4],
    safe: f64,
}

/// Streaming print-time estimator.
#[derive(Debug, Clone)]
pub struct Estimator {
    limits: Limits,
    acceleration: f64,
    retract_acceleration: f64,
    travel_acceleration: f64,
    blocks: Vec<Block>,
    prev: Option<Prev>,
    in_wipe: bool,
    feed_multiply: f64,
    time: f64,
    /// Source line and time at its end, every `mark_every` seconds of print.
    marks: Vec<(u64, f64)>,
    mark_every: f64,
    next_mark: f64,
}

impl Estimator {
    pub fn new(limits: Limits) -> Estimator {
        Estimator {
            acceleration: limits.extruding,
            retract_acceleration: limits.retracting,
            travel_acceleration: limits.travel,
            limits,
            blocks: Vec::with_capacity(REFRESH + 1),
            prev: None,
            in_wipe: false,
            feed_multiply: 1.0,
            time: 0.0,
            marks: Vec::new(),
            mark_every: 0.0,
            next_mark: 0.0,
        }
    }

    /// Also records `(line, time)` each time the elapsed time passes a multiple of `every`
    /// seconds (see [`Estimator::marks`]).
    pub fn with_marks(mut self, every: f64) -> Estimator {
        self.mark_every = every.max(1e-3);
        self.next_mark = 0.0;
        self
    }

    fn clamp(v: f64, max: f64) -> f64 {
        if max > 0.0 {
            v.min(max)
        } else {
            v
        }
    }

    /// Takes one line in.
    ///
    /// Long by design: one match over the commands that change motion state or time (moves, dwell, limits, M-codes).
    pub fn line(&mut self, parsed: &Parsed<'_>, action: &Action) {
        if let Some(c) = parsed.comment {
            let c = c.trim_ascii();
            if c.starts_with(b"WIPE_START") {
                self.in_wipe = true;
            } else if c.starts_with(b"WIPE_END") {
                self.in_wipe = false;
            } else if c.starts_with(b"COLOR_CHANGE") || c.starts_with(b"PAUSE_PRINT") {
                self.flush();
            }
        }
        match action {
            Action::Move(m) => self.motion(m),
            Action::Tool(_) => self.flush(),
            _ => {}
        }
        let Command::Code { letter, number } = parsed.command else {
            return;
        };
        let get = |c: u8| parsed.get(c).filter(|v| v.is_finite() && *v >= 0.0);
        match (letter, number as i64, number.fract() == 0.0) {
            (b'G', 92, true) if !parsed.has(b'E') => self.flush(),
            (b'M', 1, true) => self.flush(),
            (b'M', 201, true) => {
                for (i, c) in [b'X', b'Y', b'Z', b'E'].into_iter().enumerate() {
                    if let Some(v) = get(c) {
                        self.limits.max_acceleration[i] = v;
                    }
                }
            }
            (b'M', 203, true) => {
                let k = if self.limits.m203_per_second {
                    1.0
                } else {
                    1.0 / 60.0
                };
                for (i, c) in [b'X', b'Y', b'Z', b'E'].into_iter().enumerate() {
                    if let Some(v) = get(c) {
                        self.limits.max_feedrate[i] = v * k;
                    }
                }
            }
            (b'M', 204, true) => {
                if let Some(s) = get(b'S') {
                    self.acceleration = Self::clamp(s, self.limits.max_extruding);
                    self.travel_acceleration = Self::clamp(s, self.limits.max_travel);
                    if let Some(t) = get(b'T') {
                        self.retract_acceleration = Self::clamp(t, self.limits.max_retracting);
                    }
                } else {
                    if let Some(p) = get(b'P') {
                        self.acceleration = Self::clamp(p, self.limits.max_extruding);
                    }
                    if let Some(r) = get(b'R') {
                        self.retract_acceleration = Self::clamp(r, self.limits.max_retracting);
                    }
                    if let Some(t) = get(b'T') {
                        self.travel_acceleration = Self::clamp(t, self.limits.max_travel);
                    }
                }
            }
            (b'M', 205, true) => {
                if let Some(v) = get(b'X') {
                    self.limits.max_jerk[X] = v;
                    self.limits.max_jerk[Y] = v;
                }
                if let Some(v) = get(b'Y') {
                    self.limits.max_jerk[Y] = v;
                }
                if let Some(v) = get(b'Z') {
                    self.limits.max_jerk[Z] = v;
                }
                if let Some(v) = get(b'E') {
                    self.limits.max_jerk[E] = v;
                }
                if let Some(v) = get(b'S') {
                    self.limits.min_extruding_rate = v;
                }
                if let Some(v) = get(b'T') {
                    self.limits.min_travel_rate = v;
                }
            }
            (b'M', 220, true) => {
                if let Some(s) = get(b'S') {
                    self.feed_multiply = s / 100.0;
                }
            }
            _ => {}
        }
    }

    fn motion(&mut self, m: &Move) {
        let feed = m.feed / 60.0 * self.feed_multiply;
        if m.arc.is_none() {
            let delta = [
                m.to[0] - m.from[0],
                m.to[1] - m.from[1],
                m.to[2] - m.from[2],
                m.e,
            ];
            self.block(m.line, delta, feed);
            return;
        }
        // Arcs: the length along the arc, split like a firmware does into short chords.
        let points = m.points(0.02);
        let n = (points.len() - 1).max(1) as f64;
        for w in points.windows(2) {
            let delta = [
                w[1][0] - w[0][0],
                w[1][1] - w[0][1],
                (m.to[2] - m.from[2]) / n,
                m.e / n,
            ];
            self.block(m.line, delta, feed);
        }
    }

    /// Long by design: turns one move into a planner block in the firmware's order (per-axis
    /// limits, acceleration by kind, junction speed), as Marlin's planner does in one function.
    fn block(&mut self, line: u64, delta: [f64; 4], feedrate: f64) {
        if delta.iter().any(|d| !d.is_finite()) || !feedrate.is_finite() {
            return;
        }
        if delta.iter().all(|d| d.abs() < 1e-9) {
            return;
        }
        let xyz_moves = delta[X].abs() > 1e-9 || delta[Y].abs() > 1e-9 || delta[Z].abs() > 1e-9;
        let mut distance = (delta[X] * delta[X] + delta[Y] * delta[Y] + delta[Z] * delta[Z]).sqrt();
        if distance < 1e-9 {
            distance = delta[E].abs();
        }
        let extruding = delta[E] != 0.0;
        let v = if extruding {
            feedrate.max(self.limits.min_extruding_rate)
        } else {
            feedrate.max(self.limits.min_travel_rate)
        };
        let mut axis = [0.0; 4];
        for a in 0..4 {
            axis[a] = v * delta[a] / distance;
        }
        let mut f: f64 = 1.0;
        for a in 0..4 {
            let max = self.limits.max_feedrate[a];
            if axis[a].abs() > 0.0 && max > 0.0 {
                f = f.min(max / axis[a].abs());
            }
        }
        let cruise = f * v;
        if f < 1.0 {
            for x in &mut axis {
                *x *= f;
            }
        }
        let xy_moves = delta[X].abs() > 1e-9 || delta[Y].abs() > 1e-9;
        // Which acceleration applies: wipes print-like, E-only moves retract, the rest of the
        // non-printing moves travel.
        let mut acc = if self.in_wipe {
            self.acceleration
        } else if delta[E] < 0.0 {
            if xyz_moves {
                self.travel_acceleration
            } else {
                self.retract_acceleration
            }
        } else if delta[E] > 0.0 {
            if xy_moves {
                self.acceleration
            } else if delta[Z].abs() > 1e-9 {
                self.travel_acceleration
            } else {
                self.retract_acceleration
            }
        } else {
            self.travel_acceleration
        };
        for a in 0..4 {
            let scale = delta[a].abs() / distance;
            let max = self.limits.max_acceleration[a];
            if acc * scale > max {
                acc = max / scale;
            }
        }
        let mut safe = cruise;
        for a in 0..4 {
            let jerk = self.limits.max_jerk[a];
            if axis[a].abs() > jerk {
                safe = safe.min(jerk);
            }
        }
        let vmax_junction = match self.prev {
            Some(prev) if !self.blocks.is_empty() && prev.feedrate > 1e-4 => {
                let prev_larger = prev.feedrate > cruise;
                let k = if prev_larger {
                    cruise / prev.feedrate
                } else if cruise > 0.0 {
                    prev.feedrate / cruise
                } else {
                    1.0
                };
                let mut vj = prev.feedrate.min(cruise);
                let mut v_factor: f64 = 1.0;
                let mut limited = false;
                for a in 0..4 {
                    let mut ve = prev.axis[a];
                    if prev_larger {
                        ve *= k;
                    }
                    let mut vn = axis[a];
                    if limited {
                        ve *= v_factor;
                        vn *= v_factor;
                    }
                    let jerk = if ve > vn {
                        if vn > 0.0 || ve < 0.0 {
                            ve - vn
                        } else {
                            ve.max(-vn)
                        }
                    } else if vn < 0.0 || ve > 0.0 {
                        vn - ve
                    } else {
                        (-ve).max(vn)
                    };
                    if jerk > self.limits.max_jerk[a] {
                        v_factor *= self.limits.max_jerk[a] / jerk;
                        limited = true;
                    }
                }
                if limited {
                    vj *= v_factor;
                }
                if prev.safe > 0.99 * vj && safe > 0.99 * vj {
                    vj = safe;
                }
                vj
            }
            _ => safe,
        };
        let v_allow = (safe * safe + 2.0 * acc * distance).sqrt();
        let b = Block {
            line,
            distance,
            acceleration: acc,
            cruise,
            safe,
            entry: vmax_junction.min(v_allow),
            max_entry: vmax_junction,
            exit: safe,
            nominal_length: cruise <= v_allow,
            recalculate: true,
            ..Default::default()
        };
        // Its trapezoid is computed when the queue is planned (every new block is flagged).
        self.blocks.push(b);
        self.prev = Some(Prev {
            feedrate: v,
            axis,
            safe,
        });
        if self.blocks.len() > REFRESH {
            self.plan(KEEP);
        }
    }

    /// Plans the queue and commits all but the last `keep` blocks.
    fn plan(&mut self, keep: usize) {
        let n = self.blocks.len();
        if n < 2 {
            if keep == 0 {
                // A lone block still takes its time.
                if let Some(mut b) = self.blocks.pop() {
                    b.exit = b.safe;
                    b.trapezoid();
                    self.commit(&b);
                }
            }
            return;
        }
        let blocks = &mut self.blocks;
        for i in (1..n).rev() {
            let next_entry = blocks[i].entry;
            let next_recalc = blocks[i].recalculate;
            let curr = &mut blocks[i - 1];
            if curr.entry != curr.max_entry || next_recalc {
                let new = if curr.nominal_length {
                    curr.max_entry
                } else {
                    curr.max_entry.min(
                        (next_entry * next_entry + 2.0 * curr.acceleration * curr.distance).sqrt(),
                    )
                };
                if new != curr.entry {
                    curr.entry = new;
                    curr.recalculate = true;
                }
            }
        }
        for i in 0..n - 1 {
            let prev = blocks[i];
            let curr = &mut blocks[i + 1];
            if !prev.nominal_length && prev.entry < curr.entry {
                let new =
                    (prev.entry * prev.entry + 2.0 * prev.acceleration * prev.distance).sqrt();
                if new < curr.entry {
                    curr.entry = new;
                    curr.recalculate = true;
                }
            }
        }
        for i in 0..n - 1 {
            if blocks[i].recalculate || blocks[i + 1].recalculate {
                blocks[i].exit = blocks[i + 1].entry;
                blocks[i].trapezoid();
                blocks[i].recalculate = false;
            }
        }
        let last = n - 1;
        blocks[last].exit = blocks[last].safe;
        blocks[last].trapezoid();
        blocks[last].recalculate = false;
        let commit = n.saturating_sub(keep);
        let mut blocks = std::mem::take(&mut self.blocks);
        for b in &blocks[..commit] {
            self.commit(b);
        }
        blocks.drain(..commit);
        self.blocks = blocks;
        if let Some(front) = self.blocks.first_mut() {
            front.max_entry = front.entry;
        }
    }

    fn commit(&mut self, b: &Block) {
        self.time += b.time();
        if self.mark_every > 0.0 && self.time >= self.next_mark {
            self.marks.push((b.line, self.time));
            self.next_mark =
                (self.time / self.mark_every).floor() * self.mark_every + self.mark_every;
        }
    }

    /// Takes in the limit-setting lines (M201, M203, M204, M205, M220) of `raw`, skipping the
    /// moves: cheap enough to follow the limits through a whole file.
    pub fn track_limits(&mut self, raw: &[u8]) {
        let starts =
            std::iter::once(0).chain(memchr::memmem::find_iter(raw, b"\nM2").map(|i| i + 1));
        for at in starts {
            let rest = &raw[at..];
            if !(rest.starts_with(b"M20") || rest.starts_with(b"M220")) {
                continue;
            }
            let end = memchr::memchr(b'\n', rest).map_or(rest.len(), |i| i + 1);
            let parsed = crate::gcode::parse_line(crate::gcode::strip_terminator(&rest[..end]));
            self.line(&parsed, &Action::None);
        }
    }

    /// An estimator with the limits and accelerations in force now and nothing planned.
    pub fn fresh(&self) -> Estimator {
        let mut e = Estimator::new(self.limits.clone());
        e.acceleration = self.acceleration;
        e.retract_acceleration = self.retract_acceleration;
        e.travel_acceleration = self.travel_acceleration;
        e.feed_multiply = self.feed_multiply;
        e
    }

    /// Plans and commits everything queued (what firmware does on a synchronising command).
    pub fn flush(&mut self) {
        self.plan(0);
        self.prev = None;
    }

    /// Total time so far, everything queued included.
    pub fn finish(mut self) -> (f64, Vec<(u64, f64)>) {
        self.flush();
        (self.time, self.marks)
    }
}

/// Print time (s) and net filament (mm) of `text` run from machine state `start`, with the
/// limits and accelerations `limits` has now.
pub fn run_text(limits: &Estimator, start: &crate::machine::Machine, text: &[u8]) -> (f64, f64) {
    let mut est = limits.fresh();
    let mut machine = start.clone();
    let mut filament = 0.0;
    for raw in crate::gcode::split_lines(text) {
        let parsed = crate::gcode::parse_line(crate::gcode::strip_terminator(raw));
        let action = machine.step(&parsed, 0);
        if let Action::Move(m) = &action {
            filament += m.e;
        }
        est.line(&parsed, &action);
    }
    (est.finish().0, filament)
}

/// Estimates the print time of G-code text, in seconds.
pub fn estimate_text(text: &[u8], config: &SlicerConfig) -> f64 {
    let mut machine = crate::machine::Machine::new();
    let mut est = Estimator::new(Limits::from_config(config));
    feed_text(&mut est, &mut machine, text, 0);
    est.finish().0
}

/// Feeds every line of `text` to `est` through `machine`, numbering lines from `first + 1`.
pub fn feed_text(
    est: &mut Estimator,
    machine: &mut crate::machine::Machine,
    text: &[u8],
    first: u64,
) {
    for (i, raw) in crate::gcode::split_lines(text).enumerate() {
        let parsed = crate::gcode::parse_line(crate::gcode::strip_terminator(raw));
        let action = machine.step(&parsed, first + i as u64 + 1);
        est.line(&parsed, &action);
    }
}

/// Formats seconds like PrusaSlicer's statistics: `1d 2h 3m 4s`, `2h 3m 4s`, `3m 4s`, `4s`.
pub fn format_dhms(seconds: f64) -> String {
    let t = seconds.max(0.0);
    if t < 60.0 {
        return format!("{}s", t.round() as i64);
    }
    let t = t as i64;
    let (d, h, m, s) = (t / 86400, t % 86400 / 3600, t % 3600 / 60, t % 60);
    if d > 0 {
        format!("{d}d {h}h {m}m {s}s")
    } else if h > 0 {
        format!("{h}h {m}m {s}s")
    } else {
        format!("{m}m {s}s")
    }
}

/// Longest print time a file may state: ten years. A longer (or negative) stated time is a
/// damaged file, read as no statement rather than added to.
pub const MAX_STATED_SECONDS: f64 = 10.0 * 365.0 * 86400.0;

/// Parses `1d 2h 3m 4s` (any subset) into seconds; `None` past [`MAX_STATED_SECONDS`].
pub fn parse_dhms(text: &str) -> Option<f64> {
    let mut total = 0.0;
    let mut any = false;
    for part in text.split_whitespace() {
        let (num, unit) = part.split_at(part.find(|c: char| c.is_ascii_alphabetic())?);
        let v: f64 = num.parse().ok()?;
        total += v * match unit {
            "d" => 86400.0,
            "h" => 3600.0,
            "m" => 60.0,
            "s" => 1.0,
            _ => return None,
        };
        any = true;
    }
    (any && (0.0..=MAX_STATED_SECONDS).contains(&total)).then_some(total)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(text: &str) -> f64 {
        estimate_text(text.as_bytes(), &SlicerConfig::default())
    }

    #[test]
    fn cura_marlin_reads_m203_in_mm_per_second() {
        // 100 mm at 50 mm/s: the cap of 500 mm/s changes nothing; read as mm/min (8.3 mm/s)
        // it would take 12 s.
        let text = "G1 F3000\nG1 X100 E5\n";
        let plain = est(text);
        for flavor in ["Marlin", "RepRap (Marlin/Sprinter)", "marlin2", "Griffin"] {
            let head = format!(";FLAVOR:{flavor}\nM203 X500 Y500 Z10 E50\n{text}");
            let config = SlicerConfig::parse(head.as_bytes());
            let t = estimate_text(head.as_bytes(), &config);
            assert!((t - plain).abs() < 1e-6, "{flavor}: {t} vs {plain}");
        }
        // RepRapFirmware reads mm/min: M203 X3000 is 50 mm/s, no cap either.
        let head = format!("; gcode_flavor = reprapfirmware\nM203 X3000 Y3000\n{text}");
        let config = SlicerConfig::parse(head.as_bytes());
        assert!((estimate_text(head.as_bytes(), &config) - plain).abs() < 1e-6);
        let head = format!("; gcode_flavor = reprapfirmware\nM203 X600 Y600\n{text}");
        let config = SlicerConfig::parse(head.as_bytes());
        assert!(estimate_text(head.as_bytes(), &config) > 9.9);
    }

    #[test]
    fn a_long_move_takes_length_over_speed_plus_ramps() {
        // 100 mm at 50 mm/s, 1500 mm/s2, jerk 10: ramps 0->... start and end at the safe
        // speed (10 mm/s): t = 2 * (50-10)/1500 + (100 - 2 * (50^2-10^2)/3000) / 50.
        let t = est("G1 F3000\nG1 X100 E5\n");
        let ramp = (50.0 - 10.0) / 1500.0;
        let s_ramp = (50.0f64.powi(2) - 10.0f64.powi(2)) / 3000.0;
        let expected = 2.0 * ramp + (100.0 - 2.0 * s_ramp) / 50.0;
        assert!((t - expected).abs() < 1e-6, "{t} vs {expected}");
    }

    #[test]
    fn straight_continuation_keeps_speed() {
        // Two collinear moves take what one move of their joint length takes.
        let one = est("G1 F3000\nG1 X100 E5\n");
        let two = est("G1 F3000\nG1 X50 E2.5\nG1 X100 E5\n");
        assert!((one - two).abs() < 1e-6, "{one} vs {two}");
        // A right angle forces a slow-down at the corner.
        let corner = est("G1 F3000\nG1 X50 E2.5\nG1 Y50 E5\n");
        assert!(corner > one + 0.01);
    }

    #[test]
    fn limits_from_lines_apply() {
        let slow = est("M204 S500\nG1 F6000\nG1 X100 E5\n");
        let fast = est("M204 S1500\nG1 F6000\nG1 X100 E5\n");
        assert!(slow > fast);
        // Feedrate capped by M203 (mm/s by default).
        let capped = est("M203 X20 Y20\nG1 F6000\nG1 X100 E5\n");
        assert!(capped > 100.0 / 20.0);
    }

    #[test]
    fn a_lone_move_after_a_flush_takes_its_time() {
        // G92 without E flushes the planner between the two moves.
        let t = est("G1 F3000\nG1 X100 E5\nG92 X0\nG1 X100 E10\n");
        let one = est("G1 F3000\nG1 X100 E5\n");
        assert!((t - 2.0 * one).abs() < 1e-6, "{t} vs {one}");
    }

    #[test]
    fn time_format_round_trips() {
        assert_eq!(format_dhms(35.0 * 60.0 + 49.4), "35m 49s");
        assert_eq!(format_dhms(3723.0), "1h 2m 3s");
        assert_eq!(format_dhms(90061.0), "1d 1h 1m 1s");
        assert_eq!(parse_dhms("1h 2m 3s"), Some(3723.0));
        assert_eq!(parse_dhms("35m 49s"), Some(2149.0));
        assert_eq!(parse_dhms("junk"), None);
    }
}
