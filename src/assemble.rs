//! Finish stage for a text file rewritten into a regular file: the output assembled from its
//! pieces and written once.
//!
//! Input: the rewrite's blocks in order ([`Recorder`], an [`emit::Sink`]): stretches of the
//! input file, named by their offsets, and bytes the rewrite made; then the time the rewrite
//! added, for the progress lines. Output: the destination's temporary file holding the
//! blocks' concatenation with every `M73` line's numbers recomputed: exactly what
//! [`progress::update`] makes of that concatenation (the same [`progress::Lines`] decide each
//! line; a test compares both ways on whole files).
//!
//! Why: the progress lines before a rewritten layer must show time found only later, so a
//! rewrite streamed into a file had to read and write it all a second time (60 of the 430 ms
//! of a 24 MB plate, on one core, after everything else). Here nothing is written before the
//! end. The input's stretches are not held but read again from the input file (copied file to
//! file by the kernel where it can, `copy_file_range`; a reflink on file systems that share
//! blocks); the progress lines are found as the blocks pass and recomputed once the time
//! added is known; two threads write the two halves of the output at their offsets.
//!
//! Memory: the lists of pieces and progress lines, at most [`MAX_ENTRIES`] entries in all
//! (past that, [`Recorder::overflowed`] says so and the caller writes the file the streaming
//! way), and [`MADE_IN_MEMORY`] bytes of made text; more goes to an unnamed temporary file
//! (where none can be made, the recorder says it overflowed too).
//! The input file must not change while it is rewritten (a file cut shorter is a read error).

use std::fs::File;
use std::io::{self, Write};

use crate::emit::Sink;
use crate::progress::{self, Added, Totals};

/// Pieces and progress lines a [`Recorder`] lists at most (24 and 16 bytes each, and 40 for
/// each operation of the write): a file needs more only with over a hundred thousand layers
/// rewritten, or a progress line every few bytes (100 hours of print make 12 000).
pub const MAX_ENTRIES: usize = 1 << 18;
/// Made text kept in memory; the rest goes to a temporary file.
pub const MADE_IN_MEMORY: usize = 16 << 20;
/// Bytes a writer thread hands the kernel before asking it to start writing them back.
const KICK_BYTES: u64 = 4 << 20;
/// Buffer of a copy done by reading and writing (where the kernel cannot copy).
const COPY_BUFFER: usize = 1 << 20;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Source {
    Input,
    Memory,
    Spill,
}

/// A stretch of the output: `len` bytes at `at` of its source.
#[derive(Debug, Clone, Copy)]
struct Piece {
    source: Source,
    at: u64,
    len: u64,
}

/// The output of a rewrite as a list of pieces, recorded block by block.
#[derive(Default)]
pub struct Recorder {
    pieces: Vec<Piece>,
    /// Progress lines: output offset and length (terminator included).
    lines: Vec<(u64, u64)>,
    len: u64,
    made: Vec<u8>,
    spill: Option<File>,
    spilled: u64,
    /// Whether the output so far ends a line (a block's first byte then starts one).
    mid_line: bool,
    overflow: bool,
}

impl Recorder {
    pub fn new() -> Recorder {
        Recorder::default()
    }

    /// Whether the output had more pieces and progress lines than [`MAX_ENTRIES`], or made
    /// text past [`MADE_IN_MEMORY`] and no temporary file to put it in: nothing is recorded
    /// then, and the output must be made another way.
    pub fn overflowed(&self) -> bool {
        self.overflow
    }

    fn push(&mut self, source: Source, at: u64, len: u64) {
        match self.pieces.last_mut() {
            Some(p) if p.source == source && p.at + p.len == at => p.len += len,
            _ => self.pieces.push(Piece { source, at, len }),
        }
    }
}

impl Sink for Recorder {
    fn block(&mut self, bytes: &[u8], from_input: Option<u64>) -> io::Result<()> {
        if self.overflow || bytes.is_empty() {
            return Ok(());
        }
        // The lines progress::update rewrites: `M73` at the start of a line.
        for at in memchr::memmem::find_iter(bytes, b"M73") {
            let starts = if at == 0 {
                !self.mid_line
            } else {
                bytes[at - 1] == b'\n'
            };
            if starts {
                let end = progress::line_end(bytes, at);
                self.lines.push((self.len + at as u64, (end - at) as u64));
            }
        }
        self.mid_line = !bytes.ends_with(b"\n");
        let len = bytes.len() as u64;
        match from_input {
            Some(at) => self.push(Source::Input, at, len),
            None if self.spill.is_none() && self.made.len() + bytes.len() <= MADE_IN_MEMORY => {
                let at = self.made.len() as u64;
                self.made.extend_from_slice(bytes);
                self.push(Source::Memory, at, len);
            }
            None => {
                if self.spill.is_none() {
                    self.spill = tempfile::tempfile().ok();
                }
                // No temporary file to be had (a read-only or missing TMPDIR): the caller
                // streams instead, as past the entries.
                let spilled = match &mut self.spill {
                    Some(f) => f.write_all(bytes).is_ok(),
                    None => false,
                };
                let at = self.spilled;
                self.spilled += len;
                self.push(Source::Spill, at, len);
                self.overflow |= !spilled;
            }
        }
        self.len += len;
        if self.overflow || self.pieces.len() + self.lines.len() > MAX_ENTRIES {
            self.overflow = true;
            self.pieces = Vec::new();
            self.lines = Vec::new();
            self.made = Vec::new();
            self.spill = None;
        }
        Ok(())
    }
}

/// What failed while the output was written: reading the input (or the made text) back, or
/// writing the output.
#[derive(Debug)]
pub enum Failure {
    Read(io::Error),
    Write(io::Error),
}

/// One stretch of the final output, at its offset there.
#[derive(Debug, Clone, Copy)]
enum Op {
    Copy(Piece),
    /// The replacement line with this index.
    Line(usize),
}

/// The files the pieces come from.
struct Files<'a> {
    input: &'a File,
    made: &'a [u8],
    spill: Option<&'a File>,
}

impl Files<'_> {
    fn read(&self, p: &Piece, buf: &mut [u8]) -> io::Result<()> {
        match p.source {
            Source::Memory => {
                let at = p.at as usize;
                buf.copy_from_slice(&self.made[at..at + buf.len()]);
                Ok(())
            }
            Source::Input => read_at(self.input, buf, p.at),
            Source::Spill => match self.spill {
                Some(f) => read_at(f, buf, p.at),
                None => Err(io::Error::other("made text lost")),
            },
        }
    }
}

impl Recorder {
    /// Writes the output into `out` (an empty file), the progress lines recomputed for
    /// `progress` (the time added and the slicer's totals) when given. Returns how many
    /// progress lines changed.
    pub fn write(
        self,
        input: &File,
        out: &File,
        progress: Option<(&[Added], Totals)>,
    ) -> Result<usize, Failure> {
        if self.overflow {
            return Err(Failure::Write(io::Error::other("output not recorded")));
        }
        let files = Files {
            input,
            made: &self.made,
            spill: self.spill.as_ref(),
        };
        // The replaced lines: (output offset, old length, new bytes).
        let mut replaced: Vec<(u64, u64, Vec<u8>)> = Vec::new();
        if let Some((added, totals)) = progress {
            let mut lines = progress::Lines::new(added, totals);
            let mut pieces = self.pieces.iter();
            let mut piece = pieces.next();
            let mut piece_at = 0u64;
            let mut raw = Vec::new();
            for &(at, len) in &self.lines {
                while let Some(p) = piece.filter(|p| piece_at + p.len <= at) {
                    piece_at += p.len;
                    piece = pieces.next();
                }
                // A line lies in one block, so in one piece.
                let Some(p) = piece else { break };
                raw.resize(len as usize, 0);
                let sub = Piece {
                    at: p.at + (at - piece_at),
                    len,
                    ..*p
                };
                files.read(&sub, &mut raw).map_err(Failure::Read)?;
                if let Some(new) = lines.next(at, &raw) {
                    replaced.push((at, len, new));
                }
            }
        }
        // The output as operations in order, each with its offset in the output.
        let mut ops: Vec<(u64, Op)> = Vec::with_capacity(self.pieces.len() + 2 * replaced.len());
        let mut out_at = 0u64;
        let mut old_at = 0u64;
        let mut next = 0;
        for p in &self.pieces {
            let (mut at, end) = (old_at, old_at + p.len);
            while let Some((line_at, line_len, new)) = replaced.get(next).filter(|r| r.0 < end) {
                if *line_at > at {
                    let len = line_at - at;
                    ops.push((out_at, Op::Copy(sub_piece(p, at - old_at, len))));
                    out_at += len;
                }
                ops.push((out_at, Op::Line(next)));
                out_at += new.len() as u64;
                at = line_at + line_len;
                next += 1;
            }
            if end > at {
                ops.push((out_at, Op::Copy(sub_piece(p, at - old_at, end - at))));
                out_at += end - at;
            }
            old_at = end;
        }
        let total = out_at;
        // Two halves, each written by a thread at its offsets.
        let split = split_at(&mut ops, total / 2);
        let (first, second) = ops.split_at(split);
        let replaced = &replaced;
        let files = &files;
        std::thread::scope(|s| {
            let other = s.spawn(move || write_ops(second, files, replaced, out));
            let mine = write_ops(first, files, replaced, out);
            let theirs = other
                .join()
                .unwrap_or_else(|p| std::panic::resume_unwind(p));
            mine.and(theirs)
        })?;
        Ok(replaced.len())
    }
}

fn sub_piece(p: &Piece, from: u64, len: u64) -> Piece {
    Piece {
        at: p.at + from,
        len,
        ..*p
    }
}

/// Index of the first operation at or past output offset `half`, a copy that straddles it
/// cut in two there: the two threads get about as many bytes each.
fn split_at(ops: &mut Vec<(u64, Op)>, half: u64) -> usize {
    let i = ops.partition_point(|(at, _)| *at < half);
    if i > 0 {
        if let (at, Op::Copy(p)) = ops[i - 1] {
            if at + p.len > half {
                let head = half - at;
                ops[i - 1].1 = Op::Copy(sub_piece(&p, 0, head));
                ops.insert(i, (half, Op::Copy(sub_piece(&p, head, p.len - head))));
                return i;
            }
        }
    }
    i
}

fn write_ops(
    ops: &[(u64, Op)],
    files: &Files<'_>,
    replaced: &[(u64, u64, Vec<u8>)],
    out: &File,
) -> Result<(), Failure> {
    let mut buf = Vec::new();
    let mut kernel_copies = cfg!(target_os = "linux");
    let Some(start) = ops.first().map(|o| o.0) else {
        return Ok(());
    };
    let mut kicked = start;
    for &(at, op) in ops {
        let end = match op {
            Op::Line(i) => {
                let line = &replaced[i].2;
                write_at(out, line, at).map_err(Failure::Write)?;
                at + line.len() as u64
            }
            Op::Copy(p) => {
                match p.source {
                    Source::Memory => {
                        let from = p.at as usize;
                        write_at(out, &files.made[from..from + p.len as usize], at)
                            .map_err(Failure::Write)?;
                    }
                    Source::Input => copy(files.input, &p, out, at, &mut buf, &mut kernel_copies)?,
                    Source::Spill => match files.spill {
                        Some(f) => copy(f, &p, out, at, &mut buf, &mut kernel_copies)?,
                        None => return Err(Failure::Read(io::Error::other("made text lost"))),
                    },
                }
                at + p.len
            }
        };
        if end - kicked >= KICK_BYTES {
            crate::output::start_writeback(out, kicked, end - kicked);
            kicked = end;
        }
    }
    Ok(())
}

/// Copies piece `p` of `src` to `out` at `out_at`: by the kernel while it can, else by
/// reading and writing.
fn copy(
    src: &File,
    p: &Piece,
    out: &File,
    out_at: u64,
    buf: &mut Vec<u8>,
    kernel: &mut bool,
) -> Result<(), Failure> {
    let (mut at, mut out_at, mut len) = (p.at, out_at, p.len);
    #[cfg(target_os = "linux")]
    while len > 0 && *kernel {
        use std::os::fd::AsRawFd;
        let (Ok(mut off_in), Ok(mut off_out)) = (i64::try_from(at), i64::try_from(out_at)) else {
            break;
        };
        let want = len.min(1 << 30) as usize;
        // SAFETY: a system call on two descriptors the caller keeps open, with offsets of
        // its own (the files' positions are neither read nor moved).
        let n = unsafe {
            libc::copy_file_range(
                src.as_raw_fd(),
                &mut off_in,
                out.as_raw_fd(),
                &mut off_out,
                want,
                0,
            )
        };
        if n > 0 {
            let n = n as u64;
            at += n;
            out_at += n;
            len -= n;
            continue;
        }
        let err = io::Error::last_os_error();
        if n < 0 && err.raw_os_error() == Some(libc::EINTR) {
            continue;
        }
        // Across file systems, on a file system that cannot, or at an end of file the
        // reading below reports: read and write from here on.
        *kernel = false;
    }
    if len > 0 && buf.is_empty() {
        buf.resize(COPY_BUFFER, 0);
    }
    while len > 0 {
        let n = len.min(buf.len() as u64) as usize;
        let chunk = &mut buf[..n];
        read_at(src, chunk, at).map_err(Failure::Read)?;
        write_at(out, chunk, out_at).map_err(Failure::Write)?;
        at += n as u64;
        out_at += n as u64;
        len -= n as u64;
    }
    Ok(())
}

#[cfg(unix)]
fn read_at(f: &File, buf: &mut [u8], at: u64) -> io::Result<()> {
    use std::os::unix::fs::FileExt;
    f.read_exact_at(buf, at)
}

#[cfg(unix)]
fn write_at(f: &File, buf: &[u8], at: u64) -> io::Result<()> {
    use std::os::unix::fs::FileExt;
    f.write_all_at(buf, at)
}

#[cfg(windows)]
fn read_at(f: &File, mut buf: &mut [u8], mut at: u64) -> io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match f.seek_read(buf, at)? {
            0 => return Err(io::ErrorKind::UnexpectedEof.into()),
            n => {
                buf = &mut buf[n..];
                at += n as u64;
            }
        }
    }
    Ok(())
}

#[cfg(windows)]
fn write_at(f: &File, mut buf: &[u8], mut at: u64) -> io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match f.seek_write(buf, at)? {
            0 => return Err(io::ErrorKind::WriteZero.into()),
            n => {
                buf = &buf[n..];
                at += n as u64;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records `blocks` (text, from the input or made) over `input`, writes the output and
    /// returns it with what progress::update makes of the blocks' concatenation.
    fn both(input: &[u8], blocks: &[(&[u8], Option<u64>)], added: &[Added]) -> (Vec<u8>, Vec<u8>) {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("in.gcode");
        std::fs::write(&inp, input).unwrap();
        let mut rec = Recorder::new();
        let mut whole = Vec::new();
        for (b, from) in blocks {
            rec.block(b, *from).unwrap();
            whole.extend_from_slice(b);
        }
        let outp = dir.path().join("out.gcode");
        let out = File::create(&outp).unwrap();
        let totals = Totals {
            normal: Some(600.0),
            silent: None,
        };
        rec.write(&File::open(&inp).unwrap(), &out, Some((added, totals)))
            .unwrap();
        let mut expect = Vec::new();
        progress::update(&whole[..], &mut expect, added, totals).unwrap();
        (std::fs::read(&outp).unwrap(), expect)
    }

    #[test]
    fn the_output_is_the_blocks_with_their_progress_lines_updated() {
        let input: &[u8] = b"M73 P0 R9\nG1 X1 E1\nM73 P50 R5\nG1 X2 E2\nM73 P90 R1\nG1 X3 E3\n";
        let (l2, l3) = (19, 39);
        assert_eq!(&input[l2..l2 + 3], b"M73");
        assert_eq!(&input[l3 - 9..l3], b"G1 X2 E2\n");
        // The middle layer rewritten (made bytes), the rest from the input; the first line
        // grows (R9 -> R15) and shifts everything after it.
        let made: &[u8] = b"; poa\nM73 P50 R5\nG1 X2 E2.5\n";
        let blocks: [(&[u8], Option<u64>); 3] = [
            (&input[..l2], Some(0)),
            (made, None),
            (&input[l3..], Some(l3 as u64)),
        ];
        let added = [Added {
            offset: (l2 + made.len()) as u64,
            seconds: 330.0,
        }];
        let (got, expect) = both(input, &blocks, &added);
        assert_eq!(
            String::from_utf8_lossy(&got),
            String::from_utf8_lossy(&expect)
        );
        assert!(
            got.starts_with(b"M73 P0 R15\n"),
            "{}",
            String::from_utf8_lossy(&got)
        );
    }

    #[test]
    fn a_block_starting_mid_line_starts_no_progress_line() {
        // "G4 ; M73 .." cut after the comment's start: the second block's M73 is no command.
        let input = b"G4 ; wait\nM73 P0 R10\n";
        let blocks: [(&[u8], Option<u64>); 3] = [
            (b"G4 ; ", None),
            (b"M73 P9 R9\n", None),
            (&input[10..], Some(10)),
        ];
        let added = [Added {
            offset: 1000,
            seconds: 120.0,
        }];
        let (got, expect) = both(input, &blocks, &added);
        assert_eq!(got, expect);
        assert_eq!(&got[..], b"G4 ; M73 P9 R9\nM73 P0 R12\n");
    }

    #[test]
    fn long_outputs_are_split_between_the_threads_and_spilled_text_is_read_back() {
        // 3 MB of input around 17 MB of made text (past the memory share), progress lines
        // in both.
        let mut input = Vec::new();
        while input.len() < 3 << 20 {
            input.extend_from_slice(b"G1 X1.234 Y5.678 E0.0123\nM73 P1 R9\n");
        }
        let mut made = Vec::new();
        while made.len() < MADE_IN_MEMORY + (1 << 20) {
            for _ in 0..40 {
                made.extend_from_slice(b"G1 X9 Y9 E0.5 ; poa\n");
            }
            made.extend_from_slice(b"M73 P2 R99\n");
        }
        let half = (input.len() / 2 / 36 * 36) as u64;
        let blocks: [(&[u8], Option<u64>); 4] = [
            (&input[..half as usize], Some(0)),
            (&made[..1 << 20], None),
            (&made[1 << 20..], None),
            (&input[half as usize..], Some(half)),
        ];
        let added = [Added {
            offset: half + (3 << 20),
            seconds: 60.0,
        }];
        let (got, expect) = both(&input, &blocks, &added);
        assert!(got == expect, "outputs differ");
    }

    #[test]
    fn an_input_cut_shorter_meanwhile_is_a_read_error() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("in.gcode");
        std::fs::write(&inp, b"G1 X1\n").unwrap();
        let mut rec = Recorder::new();
        rec.block(b"G1 X1\nG1 X2\n", Some(0)).unwrap();
        let out = tempfile::tempfile().unwrap();
        let r = rec.write(&File::open(&inp).unwrap(), &out, None);
        assert!(matches!(r, Err(Failure::Read(_))), "{r:?}");
    }

    #[test]
    fn past_its_entries_the_recorder_lists_nothing_and_says_so() {
        let mut rec = Recorder::new();
        for i in 0..MAX_ENTRIES as u64 - 1 {
            rec.block(b"M73 P1\n", Some(7 * i)).unwrap();
            assert!(!rec.overflowed());
        }
        rec.block(b"M73 P2\n", None).unwrap();
        assert!(rec.overflowed() && rec.pieces.is_empty() && rec.lines.is_empty());
        let out = tempfile::tempfile().unwrap();
        assert!(rec.write(&out, &out, None).is_err());
    }
}
