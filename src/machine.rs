//! Stage 2: one interpreter of the printer's modal state.
//!
//! Input: parsed lines from [`crate::gcode`] in file order. Output: one [`Action`] per line,
//! with moves in absolute millimetre coordinates (start and end XYZ, E delta in mm of filament,
//! feedrate in mm/min) and the source line number.
//!
//! Invariants: every mode that changes what a number means (G90/G91, M82/M83, G92, G20/G21,
//! modal F, firmware retraction) is handled here and nowhere else. The interpreter never fails:
//! what it cannot interpret becomes a [`Diagnostic`] and the line is treated as having no effect.
//!
//! Relative-extrusion rule: E is relative when M83 is in force or when G91 is in force (Marlin,
//! Prusa firmware and Klipper all make E relative under G91); G90 restores the M82/M83 choice.

use std::collections::BTreeMap;

use crate::gcode::{Command, Parsed};

/// Coordinates beyond this (mm) are treated as corrupt: no printer is this large.
const MAX_COORD_MM: f64 = 100_000.0;

pub type Vec3 = [f64; 3];

/// Euclidean distance. `f64::hypot` guards against overflow we cannot have (coordinates are
/// bounded by `MAX_COORD_MM`) and costs a tenth of the whole pipeline on a profile.
#[inline]
pub fn dist(x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
    let (dx, dy) = (x1 - x0, y1 - y0);
    (dx * dx + dy * dy).sqrt()
}

/// A circular arc's geometry (G2/G3), in absolute XY.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arc {
    pub center: [f64; 2],
    pub clockwise: bool,
}

/// A motion from `from` to `to`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Move {
    pub line: u64,
    pub from: Vec3,
    pub to: Vec3,
    /// Filament pushed (mm); negative for a retraction.
    pub e: f64,
    /// Feedrate in force for this move, mm/min.
    pub feed: f64,
    pub arc: Option<Arc>,
    /// Written as G0.
    pub rapid: bool,
}

impl Move {
    pub fn xy_length(&self) -> f64 {
        match self.arc {
            None => dist(self.from[0], self.from[1], self.to[0], self.to[1]),
            Some(arc) => {
                let (r, sweep) = arc_sweep(self.from, self.to, arc);
                r * sweep.abs()
            }
        }
    }

    /// XY movement with material pushed: what prints a strand.
    pub fn is_extrusion(&self) -> bool {
        self.e > 0.0
            && ((self.to[0] - self.from[0]).abs() > 1e-9
                || (self.to[1] - self.from[1]).abs() > 1e-9
                || self.arc.is_some())
    }

    /// The XY polyline of the move, starting at `from` and ending at `to`. Arcs are
    /// linearized so that no chord strays more than `tolerance` mm from the arc.
    pub fn points(&self, tolerance: f64) -> Vec<[f64; 2]> {
        let start = [self.from[0], self.from[1]];
        let end = [self.to[0], self.to[1]];
        let Some(arc) = self.arc else {
            return vec![start, end];
        };
        let (r, sweep) = arc_sweep(self.from, self.to, arc);
        if r < 1e-9 {
            return vec![start, end];
        }
        let tol = tolerance.max(1e-4).min(r);
        let max_step = 2.0 * (1.0 - tol / r).clamp(-1.0, 1.0).acos();
        let n = ((sweep.abs() / max_step.max(1e-3)).ceil() as usize).clamp(1, 10_000);
        let a0 = (start[1] - arc.center[1]).atan2(start[0] - arc.center[0]);
        let mut pts = Vec::with_capacity(n + 1);
        pts.push(start);
        for i in 1..n {
            let a = a0 + sweep * (i as f64) / (n as f64);
            pts.push([arc.center[0] + r * a.cos(), arc.center[1] + r * a.sin()]);
        }
        pts.push(end);
        pts
    }
}

/// Radius and signed sweep angle (counter-clockwise positive) of an arc move.
fn arc_sweep(from: Vec3, to: Vec3, arc: Arc) -> (f64, f64) {
    let (cx, cy) = (arc.center[0], arc.center[1]);
    let r = dist(from[0], from[1], cx, cy);
    let a0 = (from[1] - cy).atan2(from[0] - cx);
    let a1 = (to[1] - cy).atan2(to[0] - cx);
    let mut sweep = a1 - a0;
    let full = (from[0] - to[0]).abs() < 1e-9 && (from[1] - to[1]).abs() < 1e-9;
    if arc.clockwise {
        if sweep >= 0.0 {
            sweep -= std::f64::consts::TAU;
        }
        if full {
            sweep = -std::f64::consts::TAU;
        }
    } else {
        if sweep <= 0.0 {
            sweep += std::f64::consts::TAU;
        }
        if full {
            sweep = std::f64::consts::TAU;
        }
    }
    (r, sweep)
}

/// What one line does to the machine.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    None,
    Move(Move),
    /// G10 without parameters: firmware retraction.
    FirmwareRetract,
    /// G11: firmware unretraction.
    FirmwareUnretract,
    /// Part-cooling fan, 0..=1.
    Fan(f64),
    Tool(u32),
    /// G92 or G28 changed the coordinate frame.
    SetPosition,
}

/// Something worth telling the user; not an error.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Diagnostic {
    /// First line where it was seen.
    pub line: u64,
    pub message: String,
}

/// Distinct diagnostics with the line of their first occurrence and how often they occurred.
#[derive(Debug, Default, Clone)]
pub struct Diagnostics {
    entries: BTreeMap<&'static str, (u64, String, u64)>,
}

impl Diagnostics {
    pub fn add(&mut self, code: &'static str, line: u64, message: impl FnOnce() -> String) {
        self.entries
            .entry(code)
            .and_modify(|e| e.2 += 1)
            .or_insert_with(|| (line, message(), 1));
    }

    pub fn has(&self, code: &str) -> bool {
        self.entries.contains_key(code)
    }

    /// Human-readable list sorted by first line.
    pub fn list(&self) -> Vec<(u64, String, u64)> {
        let mut v: Vec<_> = self.entries.values().cloned().collect();
        v.sort();
        v
    }

    pub fn merge(&mut self, other: &Diagnostics) {
        for (k, v) in &other.entries {
            self.entries
                .entry(k)
                .and_modify(|e| e.2 += v.2)
                .or_insert_with(|| v.clone());
        }
    }
}

/// Which E modes appeared in the file.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct EModes {
    pub absolute: bool,
    pub relative: bool,
}

/// The modal interpreter.
#[derive(Debug, Clone)]
pub struct Machine {
    /// Physical position (mm).
    pos: Vec3,
    /// Logical E position as the file counts it (for absolute E).
    e_logical: f64,
    /// physical = logical + offset, per axis (set by G92).
    offset: Vec3,
    xyz_relative: bool,
    g91: bool,
    m83: bool,
    /// mm per file unit: 1 (G21) or 25.4 (G20).
    unit: f64,
    feed: f64,
    pub fan: f64,
    pub tool: u32,
    pub e_modes: EModes,
    pub diagnostics: Diagnostics,
    /// Seen G20 at least once.
    pub inches_seen: bool,
    /// Filament pulled back by E moves and not yet pushed again (mm).
    pub retracted: f64,
    /// G10 in force.
    pub firmware_retracted: bool,
    /// Hotend target temperature of the active tool (M104/M109 S), when the file set one.
    pub hotend_temp: Option<f64>,
}

impl Default for Machine {
    fn default() -> Self {
        Machine {
            pos: [0.0; 3],
            e_logical: 0.0,
            offset: [0.0; 3],
            xyz_relative: false,
            g91: false,
            m83: false,
            unit: 1.0,
            feed: 1500.0,
            fan: 0.0,
            tool: 0,
            e_modes: EModes::default(),
            diagnostics: Diagnostics::default(),
            inches_seen: false,
            retracted: 0.0,
            firmware_retracted: false,
            hotend_temp: None,
        }
    }
}

impl Machine {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn position(&self) -> Vec3 {
        self.pos
    }

    pub fn feedrate(&self) -> f64 {
        self.feed
    }

    pub fn e_relative(&self) -> bool {
        self.m83 || self.g91
    }

    /// The file's own E counter (what an absolute-E file would write next).
    pub fn e_logical(&self) -> f64 {
        self.e_logical
    }

    pub fn xyz_relative(&self) -> bool {
        self.xyz_relative
    }

    /// Whether a `G92` shifted X, Y or Z away from the machine's coordinates.
    pub fn shifted(&self) -> bool {
        self.offset.iter().any(|o| *o != 0.0)
    }

    /// Whether coordinates are read in inches (G20 in force).
    pub fn inches(&self) -> bool {
        self.unit != 1.0
    }

    /// Interprets one parsed line.
    pub fn step(&mut self, p: &Parsed<'_>, line: u64) -> Action {
        let action = self.interpret(p, line);
        match &action {
            Action::Move(m) if !m.is_extrusion() && m.e != 0.0 => {
                // Retraction (also while wiping) and the push back that undoes it.
                self.retracted = (self.retracted - m.e).max(0.0);
            }
            // A slicer extrudes only from a primed nozzle: whatever was pulled back has been
            // pushed again, if not by E alone (a multi-material toolchange unloads tens of
            // millimetres with E alone and loads the next filament while moving along the
            // wipe tower).
            Action::Move(m) if m.is_extrusion() => self.retracted = 0.0,
            Action::FirmwareRetract => self.firmware_retracted = true,
            Action::FirmwareUnretract => self.firmware_retracted = false,
            _ => {}
        }
        action
    }

    /// Moves the machine's idea of its position by `d` in X and Y (a translated copy of the
    /// same moves ends there).
    pub fn shift_xy(&mut self, d: [f64; 2]) {
        self.pos[0] += d[0];
        self.pos[1] += d[1];
    }

    /// The modal state partway along a move as it is being rewritten: the nozzle at `xy` (Z
    /// kept), the E counter at `e_logical` and the feedrate `feed` (mm/min). A block written
    /// where a rewritten move enters a region starts from it.
    pub fn partway(&self, xy: [f64; 2], e_logical: f64, feed: f64) -> Machine {
        Machine {
            pos: [xy[0], xy[1], self.pos[2]],
            e_logical,
            feed,
            ..self.snapshot()
        }
    }

    /// A copy of the modal state without the diagnostics gathered so far: what a later stage
    /// needs to re-interpret a stretch of lines from here.
    pub fn snapshot(&self) -> Machine {
        Machine {
            diagnostics: Diagnostics::default(),
            ..*self
        }
    }

    /// [`Machine::snapshot`] into `self`, whose diagnostics stay as they are: the reader
    /// keeps the state before every line, and building and dropping a diagnostics map for
    /// each cost 2 % of a rewrite. The pattern names every field, so a new one is not missed.
    pub fn copy_state_from(&mut self, from: &Machine) {
        let Machine {
            pos,
            e_logical,
            offset,
            xyz_relative,
            g91,
            m83,
            unit,
            feed,
            fan,
            tool,
            e_modes,
            diagnostics: _,
            inches_seen,
            retracted,
            firmware_retracted,
            hotend_temp,
        } = *from;
        self.pos = pos;
        self.e_logical = e_logical;
        self.offset = offset;
        self.xyz_relative = xyz_relative;
        self.g91 = g91;
        self.m83 = m83;
        self.unit = unit;
        self.feed = feed;
        self.fan = fan;
        self.tool = tool;
        self.e_modes = e_modes;
        self.inches_seen = inches_seen;
        self.retracted = retracted;
        self.firmware_retracted = firmware_retracted;
        self.hotend_temp = hotend_temp;
    }

    /// Whether the nozzle is primed (not retracted): where an extrusion may start.
    pub fn is_retracted(&self) -> bool {
        self.firmware_retracted || self.retracted > 1e-3
    }

    /// Long by design: one match over the G/M codes the interpreter knows; each arm is short.
    fn interpret(&mut self, p: &Parsed<'_>, line: u64) -> Action {
        let (letter, code) = match p.command {
            // Sub-codes such as `G29.1` are not motion or mode commands we interpret.
            Command::Code { letter, number }
                if (0.0..10_000.0).contains(&number) && number.fract() == 0.0 =>
            {
                (letter, number as u32)
            }
            _ => return Action::None,
        };
        match (letter, code) {
            (b'G', n @ (0 | 1)) => self.linear(p, line, n == 0),
            (b'G', n @ (2 | 3)) => self.arc(p, line, n == 2),
            (b'G', 10) => {
                // G10 with P/L is a tool-offset or temperature command (RepRapFirmware, CNC).
                if p.has(b'P') || p.has(b'L') {
                    Action::None
                } else {
                    Action::FirmwareRetract
                }
            }
            (b'G', 11) => Action::FirmwareUnretract,
            (b'G', 20) => {
                self.unit = 25.4;
                self.inches_seen = true;
                self.diagnostics.add("inches", line, || {
                    "G20: file uses inches; converted to mm".to_string()
                });
                Action::None
            }
            (b'G', 21) => {
                self.unit = 1.0;
                Action::None
            }
            (b'G', 28) => {
                let all = !(p.has(b'X') || p.has(b'Y') || p.has(b'Z'));
                for (i, l) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
                    if all || p.has(l) {
                        self.pos[i] = 0.0;
                        self.offset[i] = 0.0;
                    }
                }
                Action::SetPosition
            }
            (b'G', 90) => {
                self.xyz_relative = false;
                self.g91 = false;
                Action::None
            }
            (b'G', 91) => {
                self.xyz_relative = true;
                self.g91 = true;
                self.diagnostics.add("g91", line, || {
                    "G91: relative XYZ; E is relative too while G91 is in force (Marlin rule)"
                        .to_string()
                });
                Action::None
            }
            (b'G', 92) => {
                let none = p.words.is_empty();
                for (i, l) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
                    if let Some(v) = self.word(p, l, line) {
                        self.offset[i] = self.pos[i] - v * self.unit;
                    } else if none {
                        self.offset[i] = self.pos[i];
                    }
                }
                if let Some(v) = self.word(p, b'E', line) {
                    self.e_logical = v * self.unit;
                } else if none {
                    self.e_logical = 0.0;
                }
                Action::SetPosition
            }
            (b'M', 82) => {
                self.m83 = false;
                self.e_modes.absolute = true;
                Action::None
            }
            (b'M', 83) => {
                self.m83 = true;
                self.e_modes.relative = true;
                Action::None
            }
            // `P2`, `P3`..: another fan (Bambu's auxiliary and chamber fans), which poa
            // neither sets nor restores: read as the part fan, a layer's `M106 S255` then
            // `M106 P2 S0` left the part fan off after poa's block. `P1` stays the part fan:
            // it is Bambu's name for it (its custom G-code's `M106 P1 S0`).
            (b'M', 106 | 107) if p.get(b'P').is_some_and(|n| n >= 2.0) => Action::None,
            (b'M', 106) => {
                let s = self.word(p, b'S', line).unwrap_or(255.0);
                self.fan = (s / 255.0).clamp(0.0, 1.0);
                Action::Fan(self.fan)
            }
            (b'M', 104 | 109) => {
                // M104 T1 sets another tool; only the active tool's target matters here.
                let other_tool = p.get(b'T').is_some_and(|t| t as u32 != self.tool);
                if let (Some(t), false) = (p.get(b'S').or_else(|| p.get(b'R')), other_tool) {
                    if t.is_finite() && (0.0..1000.0).contains(&t) {
                        self.hotend_temp = Some(t);
                    }
                }
                Action::None
            }
            (b'M', 107) => {
                self.fan = 0.0;
                Action::Fan(0.0)
            }
            (b'T', n) => {
                self.tool = n;
                Action::Tool(self.tool)
            }
            _ => Action::None,
        }
    }

    /// A finite, sane parameter value, or `None` with a diagnostic.
    fn word(&mut self, p: &Parsed<'_>, letter: u8, line: u64) -> Option<f64> {
        let v = p.get(letter)?;
        if v.is_finite() && v.abs() * self.unit <= MAX_COORD_MM {
            Some(v)
        } else {
            self.diagnostics.add("bad-number", line, || {
                format!(
                    "{}{v} is not a usable number; the word was ignored",
                    letter as char
                )
            });
            None
        }
    }

    /// Resolves the target of X/Y/Z/E words; returns (target xyz, e delta).
    fn target(&mut self, p: &Parsed<'_>, line: u64) -> (Vec3, f64) {
        // One pass over the words (this is the hottest path of the reader); the first
        // occurrence of a letter wins, as `Parsed::get` would have it.
        let mut vals: [Option<f64>; 5] = [None; 5];
        for w in &p.words {
            let slot = match w.letter {
                b'X' => 0,
                b'Y' => 1,
                b'Z' => 2,
                b'E' => 3,
                b'F' => 4,
                _ => continue,
            };
            if vals[slot].is_none() {
                vals[slot] = Some(w.value);
            }
        }
        for (slot, v) in vals.iter_mut().enumerate() {
            if let Some(x) = *v {
                if !(x.is_finite() && x.abs() * self.unit <= MAX_COORD_MM) {
                    let letter = [b'X', b'Y', b'Z', b'E', b'F'][slot] as char;
                    self.diagnostics.add("bad-number", line, || {
                        format!("{letter}{x} is not a usable number; the word was ignored")
                    });
                    *v = None;
                }
            }
        }
        let mut to = self.pos;
        for i in 0..3 {
            if let Some(v) = vals[i] {
                let v = v * self.unit;
                to[i] = if self.xyz_relative {
                    self.pos[i] + v
                } else {
                    v + self.offset[i]
                };
            }
        }
        let mut e = 0.0;
        if let Some(v) = vals[3] {
            let v = v * self.unit;
            if self.e_relative() {
                e = v;
                self.e_logical += v;
            } else {
                e = v - self.e_logical;
                self.e_logical = v;
            }
        }
        if let Some(f) = vals[4] {
            if f > 0.0 {
                self.feed = f * self.unit;
            }
        }
        (to, e)
    }

    fn linear(&mut self, p: &Parsed<'_>, line: u64, rapid: bool) -> Action {
        let from = self.pos;
        let (to, e) = self.target(p, line);
        self.pos = to;
        Action::Move(Move {
            line,
            from,
            to,
            e,
            feed: self.feed,
            arc: None,
            rapid,
        })
    }

    fn arc(&mut self, p: &Parsed<'_>, line: u64, clockwise: bool) -> Action {
        let from = self.pos;
        let i = self.word(p, b'I', line);
        let j = self.word(p, b'J', line);
        let r = self.word(p, b'R', line);
        let (to, e) = self.target(p, line);
        self.pos = to;
        let center = if i.is_some() || j.is_some() {
            // I/J are offsets from the start point in every firmware, whatever G90/G91 says.
            Some([
                from[0] + i.unwrap_or(0.0) * self.unit,
                from[1] + j.unwrap_or(0.0) * self.unit,
            ])
        } else if let Some(r) = r {
            arc_center_from_radius(from, to, r * self.unit, clockwise)
        } else {
            None
        };
        let Some(center) = center else {
            self.diagnostics.add("bad-arc", line, || {
                "arc without a usable centre; treated as a straight move".to_string()
            });
            return Action::Move(Move {
                line,
                from,
                to,
                e,
                feed: self.feed,
                arc: None,
                rapid: false,
            });
        };
        Action::Move(Move {
            line,
            from,
            to,
            e,
            feed: self.feed,
            arc: Some(Arc { center, clockwise }),
            rapid: false,
        })
    }
}

/// Centre of an R-form arc. A negative R asks for the arc longer than a half circle.
fn arc_center_from_radius(from: Vec3, to: Vec3, r: f64, clockwise: bool) -> Option<[f64; 2]> {
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let d = dx.hypot(dy);
    if d < 1e-9 || r.abs() < d / 2.0 - 1e-6 {
        return None;
    }
    let h = (r * r - d * d / 4.0).max(0.0).sqrt();
    let (mx, my) = (from[0] + dx / 2.0, from[1] + dy / 2.0);
    // Unit normal to the chord, on the left of the travel direction.
    let (nx, ny) = (-dy / d, dx / d);
    // Short arc: the centre lies right of the chord for clockwise, left for counter-clockwise.
    let mut side = if clockwise { -1.0 } else { 1.0 };
    if r < 0.0 {
        side = -side;
    }
    Some([mx + side * h * nx, my + side * h * ny])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_line;

    fn run(src: &str) -> (Machine, Vec<Action>) {
        let mut m = Machine::new();
        let acts = src
            .lines()
            .enumerate()
            .map(|(i, l)| m.step(&parse_line(l.as_bytes()), i as u64 + 1))
            .collect();
        (m, acts)
    }

    fn moves(acts: &[Action]) -> Vec<Move> {
        acts.iter()
            .filter_map(|a| match a {
                Action::Move(m) => Some(*m),
                _ => None,
            })
            .collect()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn absolute_and_relative_e() {
        let (_, a) = run("M82\nG1 X10 E1\nG1 X20 E3\nG92 E0\nG1 X30 E0.5\nM83\nG1 X40 E0.25");
        let m = moves(&a);
        let es: Vec<f64> = m.iter().map(|m| m.e).collect();
        assert_eq!(es, vec![1.0, 2.0, 0.5, 0.25]);
        assert!(close(m[3].from[0], 30.0) && close(m[3].to[0], 40.0));
    }

    #[test]
    fn g91_makes_e_relative_and_g90_restores() {
        let (m, a) = run("M82\nG1 X10 E5\nG91\nG1 X1 Y1 E0.1\nG90\nG1 X0 E5.5");
        let mv = moves(&a);
        assert!(close(mv[1].to[0], 11.0) && close(mv[1].to[1], 1.0));
        assert!(close(mv[1].e, 0.1));
        assert!(close(mv[2].e, 0.4), "{}", mv[2].e);
        assert!(m.diagnostics.has("g91"));
    }

    #[test]
    fn g92_shifts_frame_and_inches() {
        let (_, a) = run("G1 X10 Y10\nG92 X0 Y0\nG1 X5\nG20\nG1 X1 E0.1\nG21");
        let mv = moves(&a);
        assert!(close(mv[1].to[0], 15.0));
        assert!(close(mv[2].to[0], 10.0 + 25.4));
        assert!(close(mv[2].e, 2.54));
    }

    #[test]
    fn modal_feedrate() {
        let (_, a) = run("G1 X1 F600\nG1 X2\nG0 X3 F9000");
        let mv = moves(&a);
        assert_eq!(mv[1].feed, 600.0);
        assert!(mv[2].rapid);
        assert_eq!(mv[2].feed, 9000.0);
    }

    #[test]
    fn arcs_ij_and_r_agree() {
        // Quarter circle of radius 10 around the origin, counter-clockwise from (10,0) to (0,10).
        let (_, a) = run("G1 X10 Y0\nG3 X0 Y10 I-10 J0 E1\nG1 X10 Y0\nG3 X0 Y10 R10 E1");
        let mv = moves(&a);
        let (ij, r) = (mv[1], mv[3]);
        assert!(close(ij.arc.unwrap().center[0], 0.0));
        let c = r.arc.unwrap().center;
        assert!(c[0].abs() < 1e-9 && c[1].abs() < 1e-9, "{c:?}");
        let quarter = std::f64::consts::FRAC_PI_2 * 10.0;
        assert!((ij.xy_length() - quarter).abs() < 1e-9);
        let pts = ij.points(0.01);
        for p in &pts {
            assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-9);
        }
        assert!(pts.len() > 5);
    }

    #[test]
    fn clockwise_full_circle() {
        let (_, a) = run("G1 X10 Y0\nG2 X10 Y0 I-10 J0 E1");
        let mv = moves(&a);
        let len = mv[1].xy_length();
        assert!((len - std::f64::consts::TAU * 10.0).abs() < 1e-9);
    }

    #[test]
    fn an_extrusion_primes_whatever_e_alone_pulled_back() {
        // A multi-material unload (E alone) then a load while moving along the wipe tower.
        let mut m = Machine::new();
        for (k, l) in ["M83", "G1 E-15 F5000", "G1 E-79", "G1 X10 Y0 E20"]
            .iter()
            .enumerate()
        {
            m.step(&parse_line(l.as_bytes()), k as u64 + 1);
            if k == 2 {
                assert!((m.retracted - 94.0).abs() < 1e-9);
            }
        }
        assert_eq!(m.retracted, 0.0);
        assert!(!m.is_retracted());
    }

    #[test]
    fn firmware_retraction_fan_tool() {
        let (_, a) = run("G10\nG11\nG10 P0 S200\nM106 S127.5\nM107\nT1");
        assert_eq!(a[0], Action::FirmwareRetract);
        assert_eq!(a[1], Action::FirmwareUnretract);
        assert_eq!(a[2], Action::None);
        assert_eq!(a[3], Action::Fan(0.5));
        assert_eq!(a[4], Action::Fan(0.0));
        assert_eq!(a[5], Action::Tool(1));
    }

    #[test]
    fn only_the_part_fan_is_the_fan() {
        // Bambu Studio starts each layer so: the part fan at full, the auxiliary fan off.
        let (m, a) = run("M106 S255\nM106 P2 S0\nM106 P3 S0\nM107 P2\nM106 P1 S127.5\nM107 P0");
        assert_eq!(a[0], Action::Fan(1.0));
        assert_eq!(&a[1..4], &[Action::None, Action::None, Action::None]);
        assert_eq!(a[4], Action::Fan(0.5));
        assert_eq!(a[5], Action::Fan(0.0));
        assert_eq!(m.fan, 0.0);
    }

    #[test]
    fn absurd_numbers_are_ignored() {
        let (m, a) = run("G1 X1e308 Y5\nG1 Xnan");
        let mv = moves(&a);
        assert_eq!(mv[0].to, [0.0, 5.0, 0.0]);
        assert!(m.diagnostics.has("bad-number"));
    }
}
