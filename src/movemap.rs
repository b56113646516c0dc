//! Whole-stream move maps: every move's position, filament and feedrate mapped, for
//! transforms of a whole file (the helical deformation of vase-mode prints, textures).
//!
//! Input: G-code text as read and a [`MoveMap`]. Output: G-code where each move is replaced
//! by the pieces the map gives for it, written by the one [`Writer`] (with its kinematics).
//!
//! Invariants:
//! - A line is copied byte for byte when the map leaves its move as it was *and* the printer
//!   is where the file believes (position, E counter): so the identity map gives the input
//!   back byte for byte, and a map that changes only some moves rewrites only those and the
//!   moves until the output is back in step (a `G92 E`, a homing, or a move that ends where
//!   the file's does with the counter the file has). When only an absolute E counter is out
//!   of step before a move the map leaves alone, one `G92 E` (the file's value) is written
//!   before it and copying resumes: every other line stays the file's.
//! - Every line that is not a move (comments, temperatures, fan, G92, tool changes) is copied.
//! - A map sees each move once, in file order, with the interpreter state before it.
//! - Moves in relative XYZ mode (G91) that a map changes are refused: the writer writes
//!   absolute positions.

use std::io::{BufRead, Write};

use crate::error::Error;
use crate::gcode::{parse_line, strip_terminator, LineReader};
use crate::machine::{Action, Machine, Move};
use crate::writer::{Kinematics, MmPerMin, Pen, Writer};

/// One output piece of a mapped move: where it ends, the filament it pushes (mm, negative
/// for a retraction) and its feedrate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    pub to: [f64; 3],
    pub e: f64,
    pub feed: MmPerMin,
}

/// A transform of moves. `map` appends the pieces that replace `m` (in order; the first
/// starts where the previous move's last piece ended); `before` is the interpreter state
/// before the move.
pub trait MoveMap {
    fn map(&mut self, m: &Move, before: &Machine, out: &mut Vec<Piece>);
}

/// The map that changes nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Identity;

impl MoveMap for Identity {
    fn map(&mut self, m: &Move, _before: &Machine, out: &mut Vec<Piece>) {
        out.push(Piece::unchanged(m));
    }
}

impl Piece {
    /// The move as the file wrote it.
    pub fn unchanged(m: &Move) -> Piece {
        Piece {
            to: m.to,
            e: m.e,
            feed: MmPerMin(m.feed),
        }
    }
}

/// What a mapped stream did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MapStats {
    pub lines: u64,
    pub moves: u64,
    /// Input lines written anew (the others were copied).
    pub rewritten: u64,
    /// Output moves written for them.
    pub pieces: u64,
    /// `G92 E` lines written to bring an absolute E counter back in step.
    pub e_resets: u64,
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() < 1e-9)
}

/// Streams `input` through `map` into `output`, positions through `kinematics`.
pub fn apply<R: BufRead, W: Write>(
    input: R,
    map: &mut dyn MoveMap,
    kinematics: &dyn Kinematics,
    output: &mut W,
) -> Result<MapStats, Error> {
    let io_err = |e: std::io::Error| Error::Refused(format!("cannot map the moves: {e}"));
    let mut lines = LineReader::new(input);
    let mut raw = Vec::new();
    let mut machine = Machine::new();
    let mut pen = Pen::of(&machine);
    let mut pieces = Vec::new();
    let mut out = Vec::with_capacity(256);
    let mut stats = MapStats::default();
    while let Some(number) = lines.read_into(&mut raw).map_err(io_err)? {
        stats.lines += 1;
        let before = machine.snapshot();
        let parsed = parse_line(strip_terminator(&raw));
        let action = machine.step(&parsed, number);
        let Action::Move(m) = action else {
            // Not a move: the printer does what the file says, so a G92 or a homing puts
            // the output back in step with the file.
            output.write_all(&raw).map_err(io_err)?;
            // Only the axes the line names are reset (a bare G92 or G28 resets all): after
            // a `G92 E0` the output is still where the map put it, not where the file is.
            let resync = matches!(action, Action::SetPosition);
            let bare = parsed.words.is_empty()
                || (parsed.get(b'X').is_none()
                    && parsed.get(b'Y').is_none()
                    && parsed.get(b'Z').is_none()
                    && parsed.get(b'E').is_none());
            let mut pos = pen.pos;
            if resync {
                let now = machine.position();
                for (i, l) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
                    if bare || parsed.get(l).is_some() {
                        pos[i] = now[i];
                    }
                }
            }
            let e_reset = resync && (bare || parsed.get(b'E').is_some());
            pen = Pen {
                relative_e: machine.e_relative(),
                e: if e_reset { machine.e_logical() } else { pen.e },
                pos,
                feed: MmPerMin(machine.feedrate()),
            };
            continue;
        };
        stats.moves += 1;
        pieces.clear();
        map.map(&m, &before, &mut pieces);
        let in_step =
            close(pen.pos, m.from) && (pen.relative_e || (pen.e - before.e_logical()).abs() < 1e-9);
        let unchanged = pieces.len() == 1 && pieces[0] == Piece::unchanged(&m);
        if in_step && unchanged {
            output.write_all(&raw).map_err(io_err)?;
            pen = Pen::of(&machine);
            continue;
        }
        if unchanged && !pen.relative_e && close(pen.pos, m.from) && !before.xyz_relative() {
            // Only the absolute E counter is out of step (the map changed how much earlier
            // moves push): one `G92 E` puts it back, and the file's own lines are copied
            // again instead of every later move being rewritten for its E.
            let nl = if raw.ends_with(b"\r\n") { "\r\n" } else { "\n" };
            let reset = format!("G92 E{}{nl}", crate::writer::fmt_e(before.e_logical()));
            output.write_all(reset.as_bytes()).map_err(io_err)?;
            output.write_all(&raw).map_err(io_err)?;
            stats.e_resets += 1;
            pen = Pen::of(&machine);
            continue;
        }
        if before.xyz_relative() && pieces.len() == 1 && pieces[0] == Piece::unchanged(&m) {
            // A relative move the map leaves alone moves by the same amount from wherever
            // the output is: copied, and the output stays out of step by what it was.
            output.write_all(&raw).map_err(io_err)?;
            for i in 0..3 {
                pen.pos[i] += m.to[i] - m.from[i];
            }
            if !pen.relative_e {
                pen.e += m.e;
            }
            pen.relative_e = machine.e_relative();
            pen.feed = MmPerMin(machine.feedrate());
            continue;
        }
        if before.xyz_relative() {
            return Err(Error::Refused(format!(
                "line {number} moves in relative coordinates (G91), which a move map cannot rewrite; slice with absolute coordinates"
            )));
        }
        let nl = if raw.ends_with(b"\r\n") { "\r\n" } else { "\n" };
        out.clear();
        let mut w = Writer::resume(&mut out, nl, pen).with_kinematics(kinematics);
        for p in &pieces {
            w.move_xyz(p.to, p.e, p.feed);
        }
        pen = w.pen();
        stats.rewritten += 1;
        stats.pieces += pieces.len() as u64;
        output.write_all(&out).map_err(io_err)?;
        if close(pen.pos, machine.position())
            && (pen.relative_e || (pen.e - machine.e_logical()).abs() < 1e-9)
        {
            // Back in step: the file's next lines can be copied again.
            pen = Pen::of(&machine);
        }
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::writer::Cartesian;

    const FILE: &str = "M83\nG90\nG28\nG1 Z0.2 F600\n; a comment\nG1 X10 Y0 E0.5 F1200\nG2 X20 Y0 I5 J0 E0.8\nG1 X20.000 Y5.5 E.25\r\nM106 S255\n";

    fn run(map: &mut dyn MoveMap, text: &str) -> (String, MapStats) {
        let mut out = Vec::new();
        let stats = apply(text.as_bytes(), map, &Cartesian, &mut out).unwrap();
        (String::from_utf8(out).unwrap(), stats)
    }

    #[test]
    fn the_identity_gives_the_file_back_byte_for_byte() {
        let (out, stats) = run(&mut Identity, FILE);
        assert_eq!(out, FILE);
        assert_eq!(stats.rewritten, 0);
        assert_eq!(stats.moves, 4);
    }

    /// Lifts every move by 1 mm.
    struct Lift;
    impl MoveMap for Lift {
        fn map(&mut self, m: &Move, _b: &Machine, out: &mut Vec<Piece>) {
            out.push(Piece {
                to: [m.to[0], m.to[1], m.to[2] + 1.0],
                e: m.e,
                feed: MmPerMin(m.feed),
            });
        }
    }

    #[test]
    fn a_mapped_move_is_written_with_its_pieces_and_everything_else_is_copied() {
        let (out, stats) = run(
            &mut Lift,
            "M83\nG1 X0 Y0 Z0.2 F600\n; keep\nG1 X10 Y0 E0.5 F1200\n",
        );
        assert_eq!(
            out,
            "M83\nG1 X0 Y0 Z1.2 F600\n; keep\nG1 X10 Y0 Z1.2 E0.5 F1200\n"
        );
        assert_eq!(stats.rewritten, 2);
    }

    /// Splits every extrusion in two halves, each with half the filament (absolute E).
    struct Halves;
    impl MoveMap for Halves {
        fn map(&mut self, m: &Move, _b: &Machine, out: &mut Vec<Piece>) {
            if !m.is_extrusion() || m.arc.is_some() {
                out.push(Piece::unchanged(m));
                return;
            }
            let mid = [0, 1, 2].map(|i| (m.from[i] + m.to[i]) / 2.0);
            let feed = MmPerMin(m.feed);
            out.push(Piece {
                to: mid,
                e: m.e / 2.0,
                feed,
            });
            out.push(Piece {
                to: m.to,
                e: m.e / 2.0,
                feed,
            });
        }
    }

    #[test]
    fn absolute_e_stays_the_files_count_and_copying_resumes_in_step() {
        let text = "M82\nG92 E0\nG1 X0 Y0 Z0.2 F600\nG1 X10 Y0 E1 F1200\nG1 Z0.4\nG1 X0 Y0 E2\n";
        let (out, stats) = run(&mut Halves, text);
        assert_eq!(
            out,
            "M82\nG92 E0\nG1 X0 Y0 Z0.2 F600\nG1 X5 Y0 Z0.2 E0.5 F1200\nG1 X10 Y0 Z0.2 E1\nG1 Z0.4\nG1 X5 Y0 Z0.4 E1.5\nG1 X0 Y0 Z0.4 E2\n"
        );
        assert_eq!(stats.rewritten, 2);
        assert_eq!(stats.pieces, 4);
    }

    #[test]
    fn relative_xyz_moves_a_map_changes_are_refused() {
        let mut out = Vec::new();
        let e = apply(
            "G91\nG1 X1 Y0 E0.1\n".as_bytes(),
            &mut Lift,
            &Cartesian,
            &mut out,
        )
        .unwrap_err();
        assert!(e.to_string().contains("G91"), "{e}");
    }
}
