//! Progress lines (`M73`) and the statistics footer after a rewrite or a whole-file
//! transform (the finish stage).
//!
//! Input: a rewritten G-code text, where in it (byte offsets) the rewrite added time and how
//! much, and the slicer's total estimates. Output: the same text with the numbers of every
//! `M73 P.. R..` (normal mode) and `M73 Q.. S..` (silent mode) line recomputed, so that the
//! printer's display counts down the new total. Every other byte, the M73 lines' own comments
//! and other words included, is copied unchanged; the file keeps its line count.
//!
//! The footer's statistics (`; filament used [mm] = ...`, `; estimated printing time ...`)
//! get the filament and time added ([`update_footer`]); [`refresh`] does both for a whole
//! transformed text by comparing poa's estimates of input and output.
//!
//! Why a pass of its own: a time added late in the file changes the remaining time shown at
//! every earlier progress line, which was already written when the addition was found.

use std::io::{self, Read, Write};

use crate::gcode::{parse_line, split_lines, strip_terminator, Command};

/// Time a rewrite added, counted from a byte offset of the output on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Added {
    /// Output offset where the rewritten layer ends.
    pub offset: u64,
    pub seconds: f64,
}

/// The slicer's original totals (s), which the progress lines were computed from.
#[derive(Debug, Clone, Copy, Default)]
pub struct Totals {
    pub normal: Option<f64>,
    pub silent: Option<f64>,
}

impl Totals {
    /// The totals a slicer's file states (PrusaSlicer's config block).
    pub fn of(config: &crate::config::SlicerConfig) -> Totals {
        let time = |k: &str| config.get(k).and_then(crate::estimate::parse_dhms);
        Totals {
            normal: time("estimated_printing_time"),
            silent: time("estimated_printing_time_silent"),
        }
    }
}

/// Rewrites the `M73` lines of `input` into `output` for the time in `added` (sorted by
/// offset). Returns how many lines changed.
///
/// The text between progress lines is copied in blocks, not line by line: this pass reads
/// and writes the whole output a second time, so it must cost little more than a copy.
pub fn update<R: Read, W: Write>(
    mut input: R,
    output: &mut W,
    added: &[Added],
    totals: Totals,
) -> io::Result<usize> {
    const BLOCK: usize = 1 << 20;
    let finder = memchr::memmem::Finder::new(b"M73");
    let mut chunk: Vec<u8> = Vec::with_capacity(BLOCK);
    // Offset in the input of chunk[0].
    let mut base = 0u64;
    let mut changed = 0usize;
    let mut lines = Lines::new(added, totals);
    loop {
        let n = input.by_ref().take(BLOCK as u64).read_to_end(&mut chunk)?;
        let eof = n == 0;
        // Whole lines only; a line longer than a block waits for the next read.
        let end = if eof {
            chunk.len()
        } else {
            match memchr::memrchr(b'\n', &chunk) {
                Some(i) => i + 1,
                None => continue,
            }
        };
        let mut copied = 0;
        for at in finder.find_iter(&chunk[..end]) {
            if at > 0 && chunk[at - 1] != b'\n' {
                continue;
            }
            let line_end = line_end(&chunk[..end], at);
            let raw = &chunk[at..line_end];
            if let Some(line) = lines.next(base + at as u64, raw) {
                changed += 1;
                output.write_all(&chunk[copied..at])?;
                output.write_all(&line)?;
                copied = line_end;
            }
        }
        output.write_all(&chunk[copied..end])?;
        chunk.drain(..end);
        base += end as u64;
        if eof {
            return Ok(changed);
        }
    }
}

/// End (past its `\n`, or the end of `text`) of the line that starts at `at`.
pub(crate) fn line_end(text: &[u8], at: usize) -> usize {
    memchr::memchr(b'\n', &text[at..]).map_or(text.len(), |i| at + i + 1)
}

/// The new progress lines of a text, line by line in order: what [`update`] writes, for a
/// caller that finds the lines itself ([`crate::assemble`]).
pub struct Lines<'a> {
    added: &'a [Added],
    total_added: f64,
    next: usize,
    before: f64,
    // Totals from the first progress line when the footer gave none.
    totals: Totals,
    last: [f64; 2],
}

impl<'a> Lines<'a> {
    pub fn new(added: &'a [Added], totals: Totals) -> Lines<'a> {
        Lines {
            added,
            total_added: added.iter().map(|a| a.seconds).sum(),
            next: 0,
            before: 0.0,
            totals,
            last: [0.0; 2],
        }
    }

    /// The line that replaces `raw` (a line starting with `M73`, its terminator included, at
    /// `offset` of the text, offsets increasing call by call); `None` when it stays.
    pub fn next(&mut self, offset: u64, raw: &[u8]) -> Option<Vec<u8>> {
        while self.next < self.added.len() && self.added[self.next].offset <= offset {
            self.before += self.added[self.next].seconds;
            self.next += 1;
        }
        progress_line(
            raw,
            self.before,
            self.total_added,
            &mut self.totals,
            &mut self.last,
        )
        .filter(|l| l[..] != *raw)
    }
}

/// The line with new P/R (or Q/S) values; `None` when it is not a progress line.
/// `last` holds the normal and silent percentages of the previous line: a display never
/// counts backwards.
///
/// Long by design: rewrites one progress line in each form slicers write (P/R, Q/S,
/// percent only), with the rounding and never-backwards rules of each.
fn progress_line(
    raw: &[u8],
    before: f64,
    total_added: f64,
    totals: &mut Totals,
    last: &mut [f64; 2],
) -> Option<Vec<u8>> {
    let content = strip_terminator(raw);
    let parsed = parse_line(content);
    if !matches!(parsed.command, Command::Code { letter: b'M', number } if number == 73.0) {
        return None;
    }
    let after = (total_added - before).max(0.0);
    // Without totals from the footer, the first line (0 % done) states them.
    if parsed.get(b'P') == Some(0.0) && totals.normal.is_none() {
        totals.normal = parsed.get(b'R').map(|r| r * 60.0);
    }
    if parsed.get(b'Q') == Some(0.0) && totals.silent.is_none() {
        totals.silent = parsed.get(b'S').map(|s| s * 60.0);
    }
    // Silent-mode lines count slower: the added time scales like their total.
    let silent_scale = match (totals.normal, totals.silent) {
        (Some(n), Some(s)) if n > 0.0 => s / n,
        _ => 1.0,
    };
    let mut values: Vec<(u8, f64)> = parsed.words.iter().map(|w| (w.letter, w.value)).collect();
    let mut progress_words = false;
    for (pct, rem, scale) in [(b'P', b'R', 1.0), (b'Q', b'S', silent_scale)] {
        let total = if pct == b'P' {
            &mut totals.normal
        } else {
            &mut totals.silent
        };
        let p = values.iter().position(|w| w.0 == pct);
        let r = values.iter().position(|w| w.0 == rem);
        let (Some(p), Some(r)) = (p, r) else {
            continue;
        };
        let (p_old, r_old) = (values[p].1, values[r].1);
        if !(p_old.is_finite() && r_old.is_finite()) {
            continue;
        }
        progress_words = true;
        // The slicer truncates the remaining minutes: the time lies in [R, R + 1) minutes.
        values[r].1 = ((r_old * 60.0 + 30.0 + after * scale) / 60.0).floor();
        if let Some(t) = *total {
            let new_total = t + total_added * scale;
            if new_total > 0.0 && p_old < 100.0 {
                // Where the line stood in the original: the percentage and the rounded
                // minutes each bound the elapsed time; the middle of both bounds is closest.
                let lo = (p_old / 100.0 * t).max(t - (r_old + 1.0) * 60.0);
                let hi = ((p_old + 1.0) / 100.0 * t).min(t - r_old * 60.0);
                let elapsed = if lo <= hi {
                    (lo + hi) / 2.0
                } else {
                    p_old / 100.0 * t
                };
                let elapsed = elapsed.max(0.0) + before * scale;
                let last = if pct == b'P' {
                    &mut last[0]
                } else {
                    &mut last[1]
                };
                values[p].1 = (100.0 * elapsed / new_total).floor().clamp(*last, 99.0);
                *last = values[p].1;
            }
        }
    }
    if !progress_words {
        // `M73 C..`, `M73 P50` alone and the like: nothing of ours to recompute.
        return None;
    }
    let mut line = b"M73".to_vec();
    for (letter, v) in values {
        line.push(b' ');
        line.push(letter);
        if v.fract() == 0.0 && v.abs() < 1e15 {
            line.extend_from_slice(format!("{}", v as i64).as_bytes());
        } else {
            line.extend_from_slice(format!("{v:.2}").as_bytes());
        }
    }
    // Whatever followed the words (a comment) and the line ending stay as they were.
    let words_end = content
        .iter()
        .position(|&b| b == b';' || b == b'(')
        .unwrap_or(content.len());
    let tail = &content[words_end..];
    if !tail.is_empty() {
        // Keep the spacing before the comment.
        let body = &content[..words_end];
        let trailing = body.len() - body.trim_ascii_end().len();
        line.extend_from_slice(&body[body.len() - trailing..]);
        line.extend_from_slice(tail);
    }
    line.extend_from_slice(&raw[content.len()..]);
    Some(line)
}

/// Print time (s) at each `M73` line of `text` (by byte offset, in order) and in all, and the
/// net filament (mm), by poa's estimator.
pub fn progress_times(
    text: &[u8],
    limits: &crate::estimate::Limits,
) -> (Vec<(u64, f64)>, f64, f64) {
    use crate::machine::{Action, Machine};
    let mut est = crate::estimate::Estimator::new(limits.clone());
    let mut machine = Machine::new();
    let mut at = Vec::new();
    let mut filament = 0.0;
    let mut offset = 0u64;
    for raw in crate::gcode::split_lines(text) {
        let parsed = parse_line(strip_terminator(raw));
        let action = machine.step(&parsed, 0);
        if let Action::Move(m) = &action {
            filament += m.e;
        }
        est.line(&parsed, &action);
        if matches!(parsed.command, Command::Code { letter: b'M', number } if number == 73.0) {
            at.push((offset, est.clone().finish().0));
        }
        offset += raw.len() as u64;
    }
    (at, est.finish().0, filament)
}

/// A whole-file transform's output with its progress lines and footer brought up to date.
pub struct Refreshed {
    pub text: Vec<u8>,
    /// Print time (s) and net filament (mm) of the input and of the output, by poa's
    /// estimator.
    pub time_in: f64,
    pub time_out: f64,
    pub filament_in: f64,
    pub filament_out: f64,
}

/// Updates the `M73` lines and the statistics footer of `mapped`, a whole-file transform of
/// `input` that keeps its lines outside the moves it changed (a deformation, a texture): the
/// estimator's difference between input and output at each `M73` is added to the numbers
/// the lines have (computed against `totals`: [`Totals::of`] for a slicer's file), and the
/// footer gets the time and filament added.
pub fn refresh(
    input: &[u8],
    mapped: Vec<u8>,
    config: &crate::config::SlicerConfig,
    totals: Totals,
) -> Result<Refreshed, crate::error::Error> {
    let limits = crate::estimate::Limits::from_config(config);
    let (t_in, time_in, filament_in) = progress_times(input, &limits);
    let (t_out, time_out, filament_out) = progress_times(&mapped, &limits);
    let mut added = Vec::with_capacity(t_out.len() + 1);
    let mut before = 0.0;
    for (k, (off, t)) in t_out.iter().enumerate() {
        let d = t - t_in.get(k).map_or(*t, |x| x.1);
        added.push(Added {
            offset: *off,
            seconds: d - before,
        });
        before = d;
    }
    added.push(Added {
        offset: mapped.len() as u64,
        seconds: (time_out - time_in) - before,
    });
    let mut fixed = Vec::with_capacity(mapped.len());
    update(&mapped[..], &mut fixed, &added, totals).map_err(|e| {
        crate::error::Error::Refused(format!("cannot update the progress lines: {e}"))
    })?;
    // The footer: the last 64 KiB, from a line start.
    let footer = fixed.len().saturating_sub(64 * 1024);
    let footer = fixed[footer..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(0, |i| footer + i + 1)
        .min(fixed.len());
    let footer = if fixed.len() <= 64 * 1024 { 0 } else { footer };
    let tail = update_footer(
        &fixed[footer..],
        filament_out - filament_in,
        time_out - time_in,
        config.e_area(),
        config.filament_density(),
    );
    fixed.truncate(footer);
    fixed.extend_from_slice(&tail);
    Ok(Refreshed {
        text: fixed,
        time_in,
        time_out,
        filament_in,
        filament_out,
    })
}

/// Rewrites the slicer's statistics comments (PrusaSlicer family: `; filament used [mm] = `,
/// `[cm3]`, `[g]`, cost, `; estimated printing time (...) = 1h 2m 3s`) for what the rewrite
/// added. Lines it does not recognise, or with per-extruder lists, are left as they are.
pub fn update_footer(
    block: &[u8],
    filament_mm: f64,
    time_s: f64,
    filament_area: f64,
    density: f64,
) -> Vec<u8> {
    let cm3 = filament_mm * filament_area / 1000.0;
    let grams = cm3 * density;
    let mut out = Vec::with_capacity(block.len() + 64);
    let mut old_g = None;
    for raw in split_lines(block) {
        let content = strip_terminator(raw);
        let ending = &raw[content.len()..];
        let text = String::from_utf8_lossy(content);
        let replaced = footer_line(&text, filament_mm, cm3, grams, time_s, &mut old_g);
        match replaced {
            Some(new) => {
                out.extend_from_slice(new.as_bytes());
                out.extend_from_slice(ending);
            }
            None => out.extend_from_slice(raw),
        }
    }
    out
}

pub(crate) fn footer_line(
    text: &str,
    mm: f64,
    cm3: f64,
    grams: f64,
    secs: f64,
    old_g: &mut Option<f64>,
) -> Option<String> {
    let (key, value) = text.split_once(" = ")?;
    // A damaged statistic is left as it is, not added to.
    let number = || {
        value
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite() && (0.0..1e12).contains(x))
    };
    let new = match key {
        "; filament used [mm]" => format!("{:.2}", number()? + mm),
        "; filament used [cm3]" => format!("{:.2}", number()? + cm3),
        "; filament used [g]" | "; total filament used [g]" => {
            let g = number()?;
            old_g.get_or_insert(g);
            format!("{:.2}", g + grams)
        }
        "; filament cost" | "; total filament cost" => {
            // Cost scales with mass.
            let (c, g) = (number()?, (*old_g)?);
            if g <= 0.0 {
                return None;
            }
            format!("{:.2}", c * (g + grams) / g)
        }
        k if k.starts_with("; estimated printing time") => {
            crate::estimate::format_dhms(crate::estimate::parse_dhms(value.trim())? + secs)
        }
        _ => return None,
    };
    Some(format!("{key} = {new}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(text: &str, added: &[Added], totals: Totals) -> String {
        let mut out = Vec::new();
        update(text.as_bytes(), &mut out, added, totals).unwrap();
        String::from_utf8(out).unwrap()
    }

    /// Hands out its bytes a few at a time, as a pipe may.
    struct Trickle<'a>(&'a [u8]);

    impl Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = buf.len().min(self.0.len()).min(5);
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    #[test]
    fn lines_split_across_reads_come_out_as_from_one_block() {
        let text = "M73 P0 R10\nG1 X1\nM73 P50 R5 ; half\r\nG1 X2\nM73 P90 R1\nM73 P100 R0";
        let added = [Added {
            offset: 17,
            seconds: 120.0,
        }];
        let totals = Totals {
            normal: Some(600.0),
            silent: None,
        };
        let mut out = Vec::new();
        update(Trickle(text.as_bytes()), &mut out, &added, totals).unwrap();
        let whole = run(text, &added, totals);
        assert_eq!(String::from_utf8(out).unwrap(), whole);
        assert!(whole.starts_with("M73 P0 R12\n"), "{whole}");
        // The last line has no terminator and stays without one.
        assert!(whole.ends_with("M73 P100 R0"), "{whole}");
    }

    #[test]
    fn lines_before_an_addition_show_more_remaining_time() {
        // A 10-minute print; 120 s added by a layer ending at the offset of the third line.
        let text = "M73 P0 R10\nG1 X1\nM73 P50 R5 ; half\r\nG1 X2\nM73 P90 R1\nM73 P100 R0\n";
        let offset = "M73 P0 R10\nG1 X1\n".len() as u64;
        let added = [Added {
            offset,
            seconds: 120.0,
        }];
        let out = run(
            text,
            &added,
            Totals {
                normal: Some(600.0),
                silent: None,
            },
        );
        let lines: Vec<&str> = out.split_inclusive('\n').collect();
        assert_eq!(lines[0], "M73 P0 R12\n");
        assert_eq!(lines[1], "G1 X1\n");
        // After the addition: 5 of 10 minutes done becomes 7 of 12 (58 %), 5 remain; the
        // comment and the CRLF ending stay.
        assert_eq!(lines[2], "M73 P58 R5 ; half\r\n");
        assert_eq!(lines[4], "M73 P91 R1\n");
        assert_eq!(lines[5], "M73 P100 R0\n");
        assert_eq!(out.len(), text.len(), "only digits change here");
    }

    #[test]
    fn silent_mode_lines_scale_and_totals_come_from_the_first_line() {
        let text = "M73 P0 R10\nM73 Q0 S20\nG1 X1\nM73 Q50 S10\n";
        let added = [Added {
            offset: text.len() as u64,
            seconds: 60.0,
        }];
        let out = run(text, &added, Totals::default());
        // Silent totals run twice as long as normal ones: 60 s becomes 2 minutes.
        assert!(out.starts_with("M73 P0 R11\nM73 Q0 S22\n"), "{out}");
        assert!(out.ends_with("M73 Q45 S12\n"), "{out}");
    }

    #[test]
    fn nothing_added_changes_nothing() {
        let text = "M73 P0 R10\nM73 P50 R5\nM104 S200\nM73 P100 R0\nM73 P50.5\nM73 C2.50\n";
        assert_eq!(
            run(
                text,
                &[],
                Totals {
                    normal: Some(600.0),
                    silent: None
                }
            ),
            text
        );
    }
}
