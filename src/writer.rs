//! The one G-code writer: every line poa itself composes (loops, travels, splits, the A/B
//! copy's junctions, deformed moves) is written here.
//!
//! Input: the machine state where writing starts ([`Machine`]), the file's way of travelling
//! ([`TravelStyle`]) and the output [`Kinematics`]. Output: G-code lines appended to a byte
//! buffer with the file's line ending.
//!
//! Invariants:
//! - The writer tracks what it wrote (position, E counter, feedrate), so callers say what
//!   they want ("extrude to P with this much filament", "restore the file's state") and the
//!   E word is right in both M82 and M83.
//! - Speeds are typed: [`MmPerS`] is what settings and slicer configs state, [`MmPerMin`] is
//!   what an F word and the interpreter carry; they cannot be mixed by accident.
//! - Positions go out through a [`Kinematics`]: [`Cartesian`] writes X/Y/Z as they are; a
//!   five-axis stage maps tool positions to joint words there and nowhere else.

use crate::config::SlicerConfig;
use crate::machine::Machine;

/// A speed in mm per second (settings, slicer configs, the estimator).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct MmPerS(pub f64);

impl std::fmt::Display for MmPerS {
    /// `25 mm/s`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} mm/s", self.0)
    }
}

/// A feedrate in mm per minute (G-code F words, the interpreter's modal feedrate).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct MmPerMin(pub f64);

impl From<MmPerS> for MmPerMin {
    fn from(v: MmPerS) -> MmPerMin {
        MmPerMin(v.0 * 60.0)
    }
}

impl From<MmPerMin> for MmPerS {
    fn from(v: MmPerMin) -> MmPerS {
        MmPerS(v.0 / 60.0)
    }
}

/// `v` with at most `decimals` decimals and no trailing zeros, as slicers write numbers
/// (`-0` comes out as `0`).
pub fn fmt_num(v: f64, decimals: usize) -> String {
    let mut out = String::with_capacity(16);
    push_num(&mut out, v, decimals);
    out
}

/// Appends [`fmt_num`]`(v, decimals)` to `out`. Exactly what `format!("{v:.decimals$}")`
/// trimmed gives, without its allocations (the writer's lines were a third of a rewrite's
/// time): `v` scaled and rounded as an integer wherever the scaled value is not within a
/// millionth of a tie (below 1e9 the product's error is under 1.2e-7, so that rounding is
/// the exact one); near ties, and for larger values, the formatter.
pub fn push_num(out: &mut String, v: f64, decimals: usize) {
    const POW: [f64; 7] = [1.0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6];
    let scaled = POW.get(decimals).map(|p| v * p);
    let fast = scaled.filter(|x| x.abs() < 1e9 && (x.abs().fract() - 0.5).abs() > 1e-6);
    let Some(x) = fast else {
        let s = format!("{v:.decimals$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.')
        } else {
            &s
        };
        out.push_str(if s == "-0" { "0" } else { s });
        return;
    };
    let r = x.abs().round() as u64;
    if r == 0 {
        out.push('0');
        return;
    }
    if x < 0.0 {
        out.push('-');
    }
    let p = 10u64.pow(decimals as u32);
    let (int, mut frac) = (r / p, r % p);
    push_u64(out, int);
    if frac > 0 {
        out.push('.');
        let mut digits = decimals;
        while frac % 10 == 0 {
            frac /= 10;
            digits -= 1;
        }
        let start = out.len();
        push_u64(out, frac);
        // Leading zeros of the fraction (0.05 -> "05").
        let written = out.len() - start;
        for _ in written..digits {
            out.insert(start, '0');
        }
    }
}

fn push_u64(out: &mut String, mut n: u64) {
    let mut buf = [0u8; 20];
    let mut i = buf.len();
    loop {
        i -= 1;
        buf[i] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    out.push_str(std::str::from_utf8(&buf[i..]).unwrap_or_default());
}

/// Coordinates to the micron, as slicers write them.
pub fn fmt_mm(v: f64) -> String {
    fmt_num(v, 3)
}

/// E values to 5 decimals, as slicers write them.
pub fn fmt_e(v: f64) -> String {
    fmt_num(v, 5)
}

/// How positions become axis words. The writer asks for the words of a move from `from` to
/// `to` (tool-tip coordinates on the part, mm); an implementation returns them without the
/// leading `G1 ` and without F or E.
pub trait Kinematics: Sync {
    /// Words for an XY move (Z unchanged).
    fn xy_words(&self, to: [f64; 3]) -> String;
    /// Words for a Z-only move.
    fn z_words(&self, to: [f64; 3]) -> String;
    /// Words for a move in all three axes (a mapped move).
    fn xyz_words(&self, to: [f64; 3]) -> String {
        format!("{} {}", self.xy_words(to), self.z_words(to))
    }
}

/// Three Cartesian axes, written as they are.
#[derive(Debug, Clone, Copy, Default)]
pub struct Cartesian;

impl Kinematics for Cartesian {
    fn xy_words(&self, to: [f64; 3]) -> String {
        let mut s = String::with_capacity(24);
        s.push('X');
        push_num(&mut s, to[0], 3);
        s.push_str(" Y");
        push_num(&mut s, to[1], 3);
        s
    }

    fn z_words(&self, to: [f64; 3]) -> String {
        format!("Z{}", fmt_mm(to[2]))
    }
}

/// The file's way of travelling between strands, read from its own settings: retraction,
/// lift and travel speeds.
#[derive(Debug, Clone)]
pub struct TravelStyle {
    /// Retraction length (mm of filament).
    pub retract_length: f64,
    pub retract_speed: MmPerS,
    pub deretract_speed: MmPerS,
    /// Z lift on travel (mm); 0 for none.
    pub lift: f64,
    pub travel_speed: MmPerS,
    /// 0 when the file has no separate Z travel speed.
    pub travel_speed_z: MmPerS,
    /// Travels up to this long (mm) go without retraction.
    pub short_travel: f64,
    /// G10/G11 instead of E moves.
    pub firmware_retraction: bool,
}

impl TravelStyle {
    pub fn from_config(config: &SlicerConfig) -> TravelStyle {
        let num = |k: &str, d: f64| config.number(k).filter(|v| *v >= 0.0).unwrap_or(d);
        // Speeds of 0 (let through as the slicer's "auto") say nothing: the default.
        let speed = |k: &str, d: f64| config.number(k).filter(|v| *v > 0.0).unwrap_or(d);
        let retract_speed = speed("retract_speed", 35.0).max(1.0);
        let deretract = num("deretract_speed", 0.0);
        TravelStyle {
            retract_length: config.retract_length(),
            retract_speed: MmPerS(retract_speed),
            deretract_speed: MmPerS(if deretract > 0.0 {
                deretract
            } else {
                retract_speed
            }),
            lift: num("retract_lift", 0.0).min(5.0),
            travel_speed: MmPerS(speed("travel_speed", 150.0).max(1.0)),
            travel_speed_z: MmPerS(num("travel_speed_z", 0.0).max(0.0)),
            short_travel: num("retract_before_travel", 2.0).max(0.0),
            firmware_retraction: config.bool("use_firmware_retraction") == Some(true),
        }
    }

    /// Seconds a travel of `mm` takes at the travel speed (the simple model poa reports
    /// before the estimator refines it).
    pub fn travel_time(&self, mm: f64) -> f64 {
        mm / self.travel_speed.0
    }
}

/// The printer's state as written: E mode and counter, position, feedrate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pen {
    pub relative_e: bool,
    pub e: f64,
    pub pos: [f64; 3],
    pub feed: MmPerMin,
}

impl Pen {
    /// The state the file's own lines leave the printer in.
    pub fn of(state: &Machine) -> Pen {
        Pen {
            relative_e: state.e_relative(),
            e: state.e_logical(),
            pos: state.position(),
            feed: MmPerMin(state.feedrate()),
        }
    }
}

/// Writes G-code lines with the file's line ending while tracking E, position and feedrate.
pub struct Writer<'a> {
    out: &'a mut Vec<u8>,
    nl: &'static str,
    relative_e: bool,
    /// The E counter as written (absolute mode).
    e: f64,
    pos: [f64; 3],
    feed: MmPerMin,
    kinematics: &'a dyn Kinematics,
}

impl<'a> Writer<'a> {
    /// A writer continuing from `state` (its E mode, E counter, position and feedrate),
    /// Cartesian output.
    pub fn new(out: &'a mut Vec<u8>, nl: &'static str, state: &Machine) -> Writer<'a> {
        Writer {
            out,
            nl,
            relative_e: state.e_relative(),
            e: state.e_logical(),
            pos: state.position(),
            feed: MmPerMin(state.feedrate()),
            kinematics: &Cartesian,
        }
    }

    /// A writer continuing from a [`Pen`] (state kept across buffers).
    pub fn resume(out: &'a mut Vec<u8>, nl: &'static str, pen: Pen) -> Writer<'a> {
        Writer {
            out,
            nl,
            relative_e: pen.relative_e,
            e: pen.e,
            pos: pen.pos,
            feed: pen.feed,
            kinematics: &Cartesian,
        }
    }

    /// What the writer has left the printer at, to resume from.
    pub fn pen(&self) -> Pen {
        Pen {
            relative_e: self.relative_e,
            e: self.e,
            pos: self.pos,
            feed: self.feed,
        }
    }

    /// The same writer with the nozzle really at `pos` (where the file's state is not).
    pub fn at(mut self, pos: [f64; 3]) -> Self {
        self.pos = pos;
        self
    }

    /// The same writer with another output kinematics.
    pub fn with_kinematics(mut self, k: &'a dyn Kinematics) -> Self {
        self.kinematics = k;
        self
    }

    pub fn position(&self) -> [f64; 3] {
        self.pos
    }

    pub fn feed(&self) -> MmPerMin {
        self.feed
    }

    /// Writes one line as given.
    pub fn line(&mut self, s: &str) {
        self.out.extend_from_slice(s.as_bytes());
        self.out.extend_from_slice(self.nl.as_bytes());
    }

    fn e_word(&mut self, de: f64) -> String {
        if self.relative_e {
            format!("E{}", fmt_e(de))
        } else {
            self.e += de;
            format!("E{}", fmt_e(self.e))
        }
    }

    /// Sets the feedrate with its own `G1 F` line, when it differs from the modal one.
    pub fn set_feed(&mut self, v: MmPerS) {
        self.feed_to(MmPerMin(MmPerMin::from(v).0.round()));
    }

    /// Sets a feedrate given in mm/min (the file's own), when it differs from the modal one.
    pub fn feed_to(&mut self, f: MmPerMin) {
        if (f.0 - self.feed.0).abs() > 0.5 {
            self.line(&format!("G1 F{}", fmt_num(f.0, 0)));
            self.feed = f;
        }
    }

    /// Writes `G1 F` with the file's feedrate whatever the writer thinks is modal (the
    /// end of a block, where a G-code viewer or the next line relies on it).
    pub fn restore_feed(&mut self, f: MmPerMin) {
        self.line(&format!("G1 F{}", fmt_num(f.0, 0)));
        self.feed = f;
    }

    /// Brings the written E counter back to the file's (`G92 E`), in absolute mode.
    pub fn sync_e(&mut self, file_e: f64) {
        if !self.relative_e && (self.e - file_e).abs() > 1e-9 {
            self.line(&format!("G92 E{}", fmt_e(file_e)));
            self.e = file_e;
        }
    }

    /// Sets the written E counter to `file_e` (`G92 E`) in absolute mode, whether or not it
    /// differs (a junction that hands over to the file's own lines states it).
    pub fn reset_e(&mut self, file_e: f64) {
        if !self.relative_e {
            self.line(&format!("G92 E{}", fmt_e(file_e)));
            self.e = file_e;
        }
    }

    /// An extrusion from the current position to `p` with `de` mm of filament.
    pub fn extrude_to(&mut self, p: [f64; 2], de: f64) {
        let to = [p[0], p[1], self.pos[2]];
        let mut line = self.kinematics.xy_words(to);
        line.insert_str(0, "G1 ");
        line.push_str(" E");
        let e = if self.relative_e {
            de
        } else {
            self.e += de;
            self.e
        };
        push_num(&mut line, e, 5);
        self.line(&line);
        self.pos = to;
    }

    /// A move to `to` in all three axes pushing `de` of filament (0 for a travel), at `feed`
    /// (its own `F` word when it differs from the modal one, on the same line).
    pub fn move_xyz(&mut self, to: [f64; 3], de: f64, feed: MmPerMin) {
        let mut line = format!("G1 {}", self.kinematics.xyz_words(to));
        if de != 0.0 {
            let e = self.e_word(de);
            line.push(' ');
            line.push_str(&e);
        }
        if (feed.0 - self.feed.0).abs() > 0.5 {
            line.push_str(&format!(" F{}", fmt_num(feed.0, 0)));
            self.feed = feed;
        }
        self.line(&line);
        self.pos = to;
    }

    /// A travel to `p` at the modal feedrate.
    pub fn move_to(&mut self, p: [f64; 2]) {
        let to = [p[0], p[1], self.pos[2]];
        let xy = self.kinematics.xy_words(to);
        self.line(&format!("G1 {xy}"));
        self.pos = to;
    }

    /// A travel to `p` with its feedrate on the same line.
    pub fn move_at(&mut self, p: [f64; 2], v: MmPerS) {
        let to = [p[0], p[1], self.pos[2]];
        let f = MmPerMin::from(v).0.round();
        let xy = self.kinematics.xy_words(to);
        self.line(&format!("G1 {xy} F{}", fmt_mm(f)));
        self.pos = to;
        self.feed = MmPerMin(f);
    }

    /// A Z move with its feedrate on the same line, or `None` for the modal one.
    pub fn z_at(&mut self, z: f64, v: Option<MmPerS>) {
        let to = [self.pos[0], self.pos[1], z];
        let words = self.kinematics.z_words(to);
        match v {
            Some(v) => {
                let f = MmPerMin::from(v).0.round();
                self.line(&format!("G1 {words} F{}", fmt_mm(f)));
                self.feed = MmPerMin(f);
            }
            None => self.line(&format!("G1 {words}")),
        }
        self.pos = to;
    }

    /// An E-only move of `de` with its feedrate on the same line.
    pub fn e_at(&mut self, de: f64, v: MmPerS) {
        let f = MmPerMin::from(v).0.round();
        let e = self.e_word(de);
        self.line(&format!("G1 {e} F{}", fmt_mm(f)));
        self.feed = MmPerMin(f);
    }

    /// Retracts `length` mm the file's way (G10 with firmware retraction).
    pub fn retract(&mut self, t: &TravelStyle, length: f64) {
        if t.firmware_retraction {
            self.line("G10");
        } else if length > 0.0 {
            self.set_feed(t.retract_speed);
            let e = self.e_word(-length);
            self.line(&format!("G1 {e}"));
        }
    }

    /// Primes `length` mm back the file's way (G11 with firmware retraction).
    pub fn unretract(&mut self, t: &TravelStyle, length: f64) {
        if t.firmware_retraction {
            self.line("G11");
        } else if length > 0.0 {
            self.set_feed(t.deretract_speed);
            let e = self.e_word(length);
            self.line(&format!("G1 {e}"));
        }
    }

    /// Moves Z to `z` at the file's Z travel speed, when it differs.
    pub fn set_z(&mut self, t: &TravelStyle, z: f64) {
        if (z - self.pos[2]).abs() > 1e-6 {
            if t.travel_speed_z.0 > 0.0 {
                self.set_feed(t.travel_speed_z);
            } else {
                self.set_feed(t.travel_speed);
            }
            let to = [self.pos[0], self.pos[1], z];
            let words = self.kinematics.z_words(to);
            self.line(&format!("G1 {words}"));
            self.pos = to;
        }
    }

    /// A travel with the file's retraction and lift when `retract`. Returns its length.
    pub fn travel(&mut self, t: &TravelStyle, to: [f64; 2], retract: bool) -> f64 {
        let d = ((to[0] - self.pos[0]).powi(2) + (to[1] - self.pos[1]).powi(2)).sqrt();
        if d < 1e-6 {
            return 0.0;
        }
        let z = self.pos[2];
        if retract {
            self.retract(t, t.retract_length);
            if t.lift > 0.0 {
                self.set_z(t, z + t.lift);
            }
        }
        self.set_feed(t.travel_speed);
        self.move_to(to);
        if retract {
            if t.lift > 0.0 {
                self.set_z(t, z);
            }
            self.unretract(t, t.retract_length);
        }
        d
    }

    /// Part-cooling fan at `fraction` of full (M107 for off when `off_as_m107`). S keeps two
    /// decimals: a fan the slicer set to `S170.85` is restored as it wrote it.
    pub fn fan(&mut self, fraction: f64, off_as_m107: bool) {
        let s = fraction.clamp(0.0, 1.0) * 255.0;
        if s < 0.005 && off_as_m107 {
            self.line("M107");
        } else {
            self.line(&format!("M106 S{}", fmt_num(s, 2)));
        }
    }

    /// Hotend temperature (no wait).
    pub fn hotend(&mut self, celsius: f64) {
        self.line(&format!("M104 S{}", fmt_num(celsius.max(0.0), 0)));
    }

    /// A pause of `seconds`.
    pub fn dwell(&mut self, seconds: f64) {
        self.line(&format!("G4 P{}", fmt_num(seconds * 1000.0, 0)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What `fmt_num` wrote before it formatted without allocating.
    fn by_format(v: f64, decimals: usize) -> String {
        let s = format!("{v:.decimals$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        if s == "-0" {
            "0".into()
        } else {
            s
        }
    }

    #[test]
    fn numbers_are_written_as_the_formatter_writes_them() {
        // Ties, near-ties, tiny, negative, huge, non-finite and a pseudo-random sweep.
        let mut values = vec![
            0.0,
            -0.0,
            0.0005,
            -0.0005,
            0.00049999,
            1.0005,
            2.5,
            0.125,
            -0.125,
            0.0625,
            1e-9,
            -1e-9,
            123.4565,
            99.9995,
            999999.9999,
            1e13,
            -1e13,
            1e300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.05,
            0.005,
            10.0,
            100.0,
            1e6,
            12.34,
        ];
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let mag = 10f64.powi((x % 9) as i32 - 3);
            let v = (x >> 11) as f64 / (1u64 << 53) as f64 * mag;
            values.push(if x & 1 == 0 { v } else { -v });
            // Values a slicer writes, read back.
            values.push(((x % 2_000_000) as f64 - 1_000_000.0) / 1000.0);
        }
        for v in values {
            for d in [0, 1, 2, 3, 5, 6, 8] {
                assert_eq!(fmt_num(v, d), by_format(v, d), "{v:e} to {d}");
            }
        }
    }

    fn state(text: &str) -> Machine {
        let mut m = Machine::default();
        for (i, l) in text.lines().enumerate() {
            m.step(&crate::gcode::parse_line(l.as_bytes()), i as u64 + 1);
        }
        m
    }

    #[test]
    fn absolute_e_counts_on_and_syncs_back() {
        let m = state("M82\nG92 E10\nG1 X1 Y1 F600");
        let mut out = Vec::new();
        let mut w = Writer::new(&mut out, "\n", &m);
        w.extrude_to([2.0, 1.0], 0.5);
        w.set_feed(MmPerS(10.0));
        w.extrude_to([3.0, 1.0], 0.25);
        w.sync_e(10.0);
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "G1 X2 Y1 E10.5\nG1 X3 Y1 E10.75\nG92 E10\n"
        );
    }

    #[test]
    fn a_fan_is_restored_as_the_slicer_set_it() {
        let m = state("M82");
        let mut out = Vec::new();
        let mut w = Writer::new(&mut out, "\n", &m);
        w.fan(1.0, true);
        w.fan(170.85 / 255.0, true);
        w.fan(0.0, true);
        w.fan(0.0, false);
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "M106 S255\nM106 S170.85\nM107\nM106 S0\n"
        );
    }

    #[test]
    fn relative_e_writes_each_move_and_units_convert() {
        let m = state("M83\nG1 X0 Y0 Z0.2 F1200");
        let mut out = Vec::new();
        let mut w = Writer::new(&mut out, "\r\n", &m);
        w.set_feed(MmPerS(20.0)); // 1200 mm/min: already modal
        w.e_at(-0.8, MmPerS(35.0));
        w.z_at(0.6, Some(MmPerS(10.0)));
        w.move_at([5.0, 0.0], MmPerS(150.0));
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "G1 E-0.8 F2100\r\nG1 Z0.6 F600\r\nG1 X5 Y0 F9000\r\n"
        );
        assert_eq!(MmPerS::from(MmPerMin(9000.0)), MmPerS(150.0));
    }

    #[test]
    fn travel_retracts_lifts_and_comes_back_the_file_way() {
        let m = state("M83\nG1 X0 Y0 Z0.2 F1200");
        let t = TravelStyle {
            retract_length: 0.8,
            retract_speed: MmPerS(35.0),
            deretract_speed: MmPerS(35.0),
            lift: 0.4,
            travel_speed: MmPerS(150.0),
            travel_speed_z: MmPerS(0.0),
            short_travel: 2.0,
            firmware_retraction: false,
        };
        let mut out = Vec::new();
        let mut w = Writer::new(&mut out, "\n", &m);
        let d = w.travel(&t, [3.0, 4.0], true);
        assert_eq!(d, 5.0);
        assert_eq!(w.position(), [3.0, 4.0, 0.2]);
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "G1 F2100\nG1 E-0.8\nG1 F9000\nG1 Z0.6\nG1 X3 Y4\nG1 Z0.2\nG1 F2100\nG1 E0.8\n"
        );
    }

    struct Swapped;
    impl Kinematics for Swapped {
        fn xy_words(&self, to: [f64; 3]) -> String {
            format!("X{} Y{}", fmt_mm(to[1]), fmt_mm(to[0]))
        }
        fn z_words(&self, to: [f64; 3]) -> String {
            format!("Z{}", fmt_mm(-to[2]))
        }
    }

    #[test]
    fn positions_go_out_through_the_kinematics() {
        let m = state("M83\nG1 X0 Y0 Z1 F600");
        let mut out = Vec::new();
        let k = Swapped;
        let mut w = Writer::new(&mut out, "\n", &m).with_kinematics(&k);
        w.extrude_to([1.0, 2.0], 0.1);
        w.z_at(2.0, None);
        assert_eq!(String::from_utf8(out).unwrap(), "G1 X2 Y1 E0.1\nG1 Z-2\n");
    }
}
