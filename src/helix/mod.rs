//! Layer-less helical printing (Kanada): the helix of a spiral-vase print, found from its
//! moves, deformed ([`deform`]), checked for printability in 3D ([`printable`]) and drawn
//! ([`picture`]).
//!
//! Input: G-code text of a spiral-vase print (PrusaSlicer/SuperSlicer/Orca vase mode, Cura
//! "spiralize"; comments not needed). Output: a [`Helix`]: the lines of the one continuous
//! rising extrusion, its axis, start and top heights, pitch and turns.
//!
//! Invariants: the helix is the longest run of consecutive moves that each rise while
//! extruding (or do not move at all: the zero-length travels and feed-only lines slicers put
//! at each turn), so the flat bottom layers and the first layer are never part of it. A file
//! whose run rises less than [`MIN_RISE`] or holds less than [`MIN_SHARE`] of the file's
//! extrusion is not a vase-mode print.

pub mod deform;
pub mod picture;
pub mod printable;

use std::path::Path;

use crate::error::Error;
use crate::gcode::{parse_line, split_lines, strip_terminator, LineReader};
use crate::machine::{Action, Machine, Move};

/// Least rise of the helix (mm).
pub const MIN_RISE: f64 = 1.0;
/// Least share of the file's extruded length in the helix.
pub const MIN_SHARE: f64 = 0.2;

/// The helix of a spiral-vase print.
#[derive(Debug, Clone, PartialEq)]
pub struct Helix {
    /// First and last line (1-based) of the helix's moves.
    pub first_line: u64,
    pub last_line: u64,
    /// Z where the helix starts and where it ends.
    pub z0: f64,
    pub z_top: f64,
    /// The axis: centroid of the helix's path (length-weighted).
    pub center: [f64; 2],
    /// Mean distance of the first turn from the axis.
    pub r0: f64,
    /// Rise per turn (mm), on average and over the first turn (which slicers lay on the
    /// bottom at the sliced layer height, and `deform` keeps).
    pub pitch: f64,
    pub first_pitch: f64,
    pub turns: f64,
    /// Extruded length of the helix and of the whole file (mm).
    pub length: f64,
    pub total_length: f64,
}

/// Moves of a text with their line numbers (1-based); arcs included as moves.
pub fn moves(text: &[u8], mut each: impl FnMut(&Move, &Machine)) {
    let mut machine = Machine::new();
    for (i, raw) in split_lines(text).enumerate() {
        let before = machine.snapshot();
        let parsed = parse_line(strip_terminator(raw));
        if let Action::Move(m) = machine.step(&parsed, i as u64 + 1) {
            each(&m, &before);
        }
    }
}

/// Where the moves of a print are read from, once per pass: a text in memory, or a file read
/// a line at a time ([`FileSource`]), so that judging whether a file of any size is a
/// layer-less print holds one line, not the file.
pub trait Source {
    /// Calls `each` on every move in order, as [`moves`] does.
    fn each_move(&self, each: &mut dyn FnMut(&Move, &Machine)) -> Result<(), Error>;
}

impl Source for [u8] {
    fn each_move(&self, each: &mut dyn FnMut(&Move, &Machine)) -> Result<(), Error> {
        moves(self, each);
        Ok(())
    }
}

/// A regular file read line by line, from the start, at each pass (up to the size it had
/// when each pass opened it). A line over [`crate::gcode::MAX_LINE`] ends the pass with an
/// error, as the layered reader refuses it.
pub struct FileSource<'a>(pub &'a Path);

impl Source for FileSource<'_> {
    fn each_move(&self, each: &mut dyn FnMut(&Move, &Machine)) -> Result<(), Error> {
        use std::io::Read;
        let (file, size) = crate::input::open_regular(self.0)?;
        let mut lines =
            LineReader::new(std::io::BufReader::with_capacity(1 << 16, file.take(size)));
        let mut machine = Machine::new();
        let mut buf = Vec::new();
        let read_err = |source| Error::Read {
            path: self.0.to_path_buf(),
            source,
        };
        while let Some(number) = lines.read_into(&mut buf).map_err(read_err)? {
            let before = machine.snapshot();
            let parsed = parse_line(strip_terminator(&buf));
            if let Action::Move(m) = machine.step(&parsed, number) {
                each(&m, &before);
            }
        }
        Ok(())
    }
}

fn len3(m: &Move) -> f64 {
    let dz = m.to[2] - m.from[2];
    (m.xy_length().powi(2) + dz * dz).sqrt()
}

/// How a move takes part in a rising run.
#[derive(PartialEq)]
enum Step {
    /// Rises while pushing filament (or nothing: the ramp at the helix's start).
    Rise,
    /// Does not move at all (feed-only lines, zero-length travels at each turn).
    Still,
    /// Extrudes without rising: Z written to 3 decimals makes short pieces of a slow helix
    /// flat; allowed inside a run up to [`MAX_FLAT`] mm in a row.
    Flat(f64),
    Other,
}

/// Longest flat extrusion inside a run (mm) when the run rises fast.
const MAX_FLAT: f64 = 5.0;
/// Z resolution assumed of the file (mm): slicers and poa write Z to 3 decimals.
const Z_STEP: f64 = 0.001;

/// Longest flat extrusion inside a run that has risen `rise` mm over `length` mm: at least
/// [`MAX_FLAT`], and as long as the run's own rate of rise takes to climb two Z steps, so
/// that a slow helix (a dish at 0.1 mm layers rises 0.03 mm a turn, one 0.001 mm step every
/// 8 mm) stays one run.
fn max_flat(rise: f64, length: f64) -> f64 {
    if rise <= 0.0 || length <= 0.0 {
        return MAX_FLAT;
    }
    (2.0 * Z_STEP * length / rise).clamp(MAX_FLAT, 1000.0)
}

fn step(m: &Move) -> Step {
    let dz = m.to[2] - m.from[2];
    let xy = m.xy_length();
    if xy < 1e-9 && dz.abs() < 1e-9 && m.e.abs() < 1e-12 {
        Step::Still
    } else if dz > 1e-7 && m.e >= 0.0 && xy > 0.0 {
        Step::Rise
    } else if dz.abs() <= 1e-7 && m.e > 0.0 && xy > 0.0 {
        Step::Flat(xy)
    } else {
        Step::Other
    }
}

/// The helix of `text`, or a refusal saying to slice in vase mode.
pub fn find(text: &[u8]) -> Result<Helix, Error> {
    find_in(text)
}

/// The helix of the print `src` reads (two passes), or a refusal saying to slice in vase
/// mode; a read error of a file as it is.
pub fn find_in<S: Source + ?Sized>(src: &S) -> Result<Helix, Error> {
    #[derive(Clone, Copy, Default)]
    struct Run {
        first: u64,
        last: u64,
        z0: f64,
        z1: f64,
        length: f64,
        sx: f64,
        sy: f64,
        w: f64,
    }
    let mut best = Run::default();
    let mut cur: Option<Run> = None;
    let mut total = 0.0;
    let mut flat = 0.0;
    src.each_move(&mut |m, _| {
        if m.is_extrusion() {
            total += len3(m);
        }
        let st = step(m);
        match st {
            Step::Flat(l) if cur.is_some() => {
                flat += l;
                if flat
                    > max_flat(
                        cur.as_ref().map_or(0.0, |r| r.z1 - r.z0),
                        cur.as_ref().map_or(0.0, |r| r.length),
                    )
                {
                    if let Some(r) = cur.take() {
                        if r.length > best.length {
                            best = r;
                        }
                    }
                    return;
                }
            }
            Step::Rise => flat = 0.0,
            _ => {}
        }
        let joins = match st {
            Step::Rise => true,
            Step::Still | Step::Flat(_) => cur.is_some(),
            Step::Other => false,
        };
        // A run starts only with a rise (flat bottom extrusions never join it).
        if joins && (cur.is_some() || st == Step::Rise) {
            let r = cur.get_or_insert(Run {
                first: m.line,
                z0: m.from[2],
                ..Run::default()
            });
            r.last = m.line;
            r.z1 = m.to[2];
            if m.e > 0.0 {
                let l = len3(m);
                r.length += l;
                r.sx += l * (m.from[0] + m.to[0]) / 2.0;
                r.sy += l * (m.from[1] + m.to[1]) / 2.0;
                r.w += l;
            }
        } else if !joins {
            if let Some(r) = cur.take() {
                if r.length > best.length {
                    best = r;
                }
            }
        }
    })?;
    if let Some(r) = cur.take() {
        if r.length > best.length {
            best = r;
        }
    }
    let refuse = |why: String| {
        Error::Refused(format!(
            "{why}: not a spiral-vase print; slice it in vase mode (PrusaSlicer --spiral-vase, Cura magic_spiralize)"
        ))
    };
    if best.w <= 0.0 || best.z1 - best.z0 < MIN_RISE {
        return Err(refuse(format!(
            "no continuous rising extrusion of {MIN_RISE} mm or more"
        )));
    }
    if best.length < MIN_SHARE * total {
        return Err(refuse(format!(
            "the longest rising extrusion is {:.0} % of the extrusion",
            100.0 * best.length / total.max(1e-9)
        )));
    }
    let center = [best.sx / best.w, best.sy / best.w];
    // Turns: the angle swept around the axis; r0: mean radius over the first turn.
    let mut angle = 0.0f64;
    let mut prev: Option<f64> = None;
    let (mut r_sum, mut r_n) = (0.0, 0.0);
    let mut first_top = None;
    src.each_move(&mut |m, _| {
        if m.line < best.first || m.line > best.last || m.xy_length() <= 0.0 {
            return;
        }
        let a = (m.to[1] - center[1]).atan2(m.to[0] - center[0]);
        let p = prev.unwrap_or((m.from[1] - center[1]).atan2(m.from[0] - center[0]));
        let mut d = a - p;
        while d > std::f64::consts::PI {
            d -= std::f64::consts::TAU;
        }
        while d < -std::f64::consts::PI {
            d += std::f64::consts::TAU;
        }
        angle += d;
        prev = Some(a);
        if angle.abs() > std::f64::consts::TAU && first_top.is_none() {
            first_top = Some(m.to[2]);
        }
        if angle.abs() <= std::f64::consts::TAU {
            let l = m.xy_length();
            r_sum += l * ((m.to[0] - center[0]).hypot(m.to[1] - center[1]));
            r_n += l;
        }
    })?;
    let turns = angle.abs() / std::f64::consts::TAU;
    if turns < 1.5 {
        return Err(refuse(format!(
            "the rising extrusion turns {turns:.1} times around its axis"
        )));
    }
    Ok(Helix {
        first_line: best.first,
        last_line: best.last,
        z0: best.z0,
        z_top: best.z1,
        center,
        r0: r_sum / r_n.max(1e-9),
        pitch: (best.z1 - best.z0) / turns,
        first_pitch: first_top.map_or((best.z1 - best.z0) / turns, |z| z - best.z0),
        turns,
        length: best.length,
        total_length: total,
    })
}

/// The bead a file prints: the external perimeter's width, the sliced layer height (the
/// rise of the helix's first turn, which slicers lay at the layer height and `deform`
/// keeps; the file's setting when that is odd) and the nozzle.
pub fn bead_of(config: &crate::layers::SlicerConfig, helix: &Helix) -> printable::Bead {
    let height = Some(helix.first_pitch)
        .filter(|h| (0.02..=2.0).contains(h))
        .or(config.layer_height().filter(|h| (0.02..=2.0).contains(h)))
        .unwrap_or(helix.pitch);
    printable::Bead {
        width: config.external_perimeter_width(),
        height,
        nozzle_radius: config.nozzle_diameter() / 2.0,
    }
}

/// What [`deform_text`] made.
pub struct Deformed {
    pub text: Vec<u8>,
    pub helix: Helix,
    /// The helix of the output (what the check judged).
    pub helix_out: Helix,
    pub check: printable::Report,
    pub bead: printable::Bead,
    pub time_in: f64,
    pub time_out: f64,
    pub filament_in: f64,
    pub filament_out: f64,
    pub lines_rewritten: u64,
    pub pieces: u64,
}

/// Deforms the vase-mode print `text` by `spec`, checks the result (refused when it breaks
/// a rule, unless `force`), and updates its `M73` lines and statistics footer.
pub fn deform_text(
    text: &[u8],
    config: &crate::layers::SlicerConfig,
    spec: &deform::Spec,
    force: bool,
) -> Result<Deformed, Error> {
    let helix = find(text)?;
    let fa = config.e_area();
    let mut map = deform::Deform::new(spec, &helix, fa)?;
    let mut mapped = Vec::with_capacity(text.len() + text.len() / 4);
    let stats = crate::movemap::apply(text, &mut map, &crate::writer::Cartesian, &mut mapped)?;
    if let Some(p) = map.problem() {
        return Err(Error::Invalid(p.to_string()));
    }
    let helix_out = find(&mapped).map_err(|_| {
        Error::Refused(
            "the deformed path does not rise as one helix (Z must grow along it), so it cannot be printed layer-less; change the Z expression"
                .to_string(),
        )
    })?;
    let bead = bead_of(config, &helix);
    let check = printable::check(&mapped, &helix_out, bead, 20_000);
    if let (Some(f), false) = (&check.first, force) {
        return Err(Error::Refused(format!(
            "the deformation is not printable: {f}; change it, or give --force to write it anyway"
        )));
    }
    let done = crate::progress::refresh(text, mapped, config, crate::progress::Totals::of(config))?;
    Ok(Deformed {
        text: done.text,
        helix,
        helix_out,
        check,
        bead,
        time_in: done.time_in,
        time_out: done.time_out,
        filament_in: done.filament_in,
        filament_out: done.filament_out,
        lines_rewritten: stats.rewritten,
        pieces: map.pieces,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A synthetic vase: one flat bottom ring at Z 0.2, then `turns` turns of a helix of
    /// radius `r` around (100, 100) rising `pitch` per turn, 64 segments a turn, relative E,
    /// no comments.
    pub fn vase(r: f64, pitch: f64, turns: usize) -> String {
        let mut s = String::from("M83\nG90\nG28\nG1 Z0.2 F600\n");
        let n = 64;
        let at = |k: usize| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            (100.0 + r * a.cos(), 100.0 + r * a.sin())
        };
        let seg = std::f64::consts::TAU * r / n as f64;
        let (x, y) = at(0);
        s.push_str(&format!("G1 X{x:.3} Y{y:.3} F9000\n"));
        for k in 1..=n {
            let (x, y) = at(k);
            s.push_str(&format!("G1 X{x:.3} Y{y:.3} E{:.5} F1800\n", seg * 0.035));
        }
        for k in 1..=n * turns {
            let (x, y) = at(k);
            let z = 0.2 + pitch * k as f64 / n as f64;
            s.push_str(&format!("G1 X{x:.3} Y{y:.3} Z{z:.4} E{:.5}\n", seg * 0.035));
        }
        s.push_str("G1 Z30 F600\nM104 S0\n");
        s
    }

    #[test]
    fn the_helix_of_a_vase_is_found_without_comments() {
        let text = vase(15.0, 0.2, 20);
        let h = find(text.as_bytes()).unwrap();
        assert!(
            (h.z0 - 0.2).abs() < 1e-9 && (h.z_top - 4.2).abs() < 1e-3,
            "{h:?}"
        );
        assert!((h.center[0] - 100.0).abs() < 0.05 && (h.center[1] - 100.0).abs() < 0.05);
        assert!(
            (h.turns - 20.0).abs() < 0.01 && (h.pitch - 0.2).abs() < 1e-3,
            "{h:?}"
        );
        assert!((h.r0 - 15.0).abs() < 0.01, "{h:?}");
        assert_eq!(h.first_line, 6 + 64);
    }

    #[test]
    fn a_file_read_a_line_at_a_time_gives_the_helix_and_judgement_of_the_text_in_memory() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("vase.gcode");
        let text = vase(15.0, 0.2, 12);
        std::fs::write(&path, &text).unwrap();
        let src = FileSource(&path);
        let h = find_in(&src).unwrap();
        assert_eq!(h, find(text.as_bytes()).unwrap());
        let bead = printable::Bead {
            width: 0.45,
            height: 0.2,
            nozzle_radius: 0.2,
        };
        let from_file = printable::check_in(&src, &h, bead, 50).unwrap();
        let in_memory = printable::check(text.as_bytes(), &h, bead, 50);
        assert!(from_file.points > 1000);
        assert_eq!(format!("{from_file:?}"), format!("{in_memory:?}"));
        // A damaged file (a line of 2 MiB) is a read error, not a line held whole nor a
        // refusal taken for "not a vase".
        let mut damaged = text.into_bytes();
        damaged.extend(std::iter::repeat_n(b'9', 2 << 20));
        std::fs::write(&path, &damaged).unwrap();
        assert!(matches!(find_in(&src), Err(Error::Read { .. })));
    }

    #[test]
    fn a_slow_helix_written_to_three_decimals_is_one_run() {
        // A dish at 0.1 mm layers rises 0.03 mm a turn: with Z to 3 decimals, 8 mm of
        // path go by without a Z change (more than the 5 mm a fast helix is allowed).
        let text: String = vase(40.0, 0.03, 60)
            .lines()
            .map(|l| match l.split_once(" Z") {
                Some((head, tail)) if tail.contains(" E") => {
                    let (z, rest) = tail.split_once(' ').unwrap();
                    let z: f64 = z.parse().unwrap();
                    format!("{head} Z{z:.3} {rest}\n")
                }
                _ => format!("{l}\n"),
            })
            .collect();
        let h = find(text.as_bytes()).unwrap();
        assert!((h.turns - 60.0).abs() < 0.05, "{h:?}");
        assert!((h.z_top - h.z0 - 1.8).abs() < 0.01, "{h:?}");
    }

    #[test]
    fn a_layered_print_is_refused_with_what_to_do() {
        let mut s = String::from("M83\nG1 Z0.2 F600\n");
        for l in 0..20 {
            s.push_str(&format!("G1 Z{:.2}\nG1 X0 Y0\n", 0.2 + 0.2 * l as f64));
            s.push_str("G1 X10 Y0 E1\nG1 X10 Y10 E1\nG1 X0 Y10 E1\nG1 X0 Y0 E1\n");
        }
        let e = find(s.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("vase mode"), "{e}");
    }
}
