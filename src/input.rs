//! Opening a G-code file for the pipeline.
//!
//! Input: a path. Output: a buffered reader of the file's G-code text and the file's
//! [`SlicerConfig`] (read from its head and tail, then overridden by `SLIC3R_*` variables).
//! Binary G-code (`.bgcode`, recognised by its magic bytes whatever the file is called) is
//! decoded block by block: the reader yields its G-code text, the config comes from its
//! metadata blocks, and [`Opened::binary`] keeps the other blocks so that a rewrite can be
//! written back in the same format. Refuses, with a message saying what to do, what cannot be
//! G-code: directories, devices, FIFOs and sockets (only regular files are read: `/dev/zero`
//! would never end and a FIFO without a writer would block), damaged binary G-code, text files
//! with binary data in their head, and text that holds no G-code command (an STL, OBJ or any
//! other text file). The slicer settings poa uses are range-checked here, once, for every
//! command. A file is read up to the size it had when opened. [`open_regular`] and
//! [`read_all`] give a checked regular file as it is, for commands that read it their own way.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use crate::bgcode::{self, BlockKind};

use crate::error::{Error, Result};
use crate::layers::config::{HEAD_BYTES, TAIL_BYTES};
use crate::layers::SlicerConfig;

/// Buffer size for streaming reads: large enough to amortise syscalls, small enough to keep
/// memory flat.
pub const READ_BUFFER: usize = 256 * 1024;

pub struct Opened {
    pub reader: Box<dyn BufRead + Send>,
    /// The first bytes of the file (up to 64 KiB).
    pub head: Vec<u8>,
    pub config: SlicerConfig,
    pub size: u64,
    /// The file's blocks other than G-code when it is binary G-code (the G-code is what
    /// `reader` yields).
    pub binary: Option<bgcode::stream::Layout>,
    /// The text file itself, read again at its offsets by the finish stage
    /// ([`crate::assemble`]); `None` for binary G-code, whose text is decoded.
    pub file: Option<File>,
}

/// Opens `path`, checks that it looks like text G-code and reads its configuration.
pub fn open(path: &Path) -> Result<Opened> {
    let read_err = |source| Error::Read {
        path: path.to_path_buf(),
        source,
    };
    let (mut file, size) = open_regular(path)?;
    let mut head = vec![0u8; HEAD_BYTES.min(size) as usize];
    file.read_exact(&mut head).map_err(read_err)?;
    if bgcode::is_bgcode(&head) {
        return open_binary(path, file, size);
    }
    check_text(path, &head)?;
    // An empty file is read as zero layers (and stays empty), not refused.
    if size > 0 {
        check_has_commands(&mut file, &head, size).map_err(|e| match e {
            CommandScan::Io(source) => read_err(source),
            CommandScan::None(reason) => Error::NotGcode {
                path: path.to_path_buf(),
                reason,
            },
        })?;
    }
    let mut config = SlicerConfig::parse(&head);
    if size > HEAD_BYTES {
        let start = size.saturating_sub(TAIL_BYTES).max(HEAD_BYTES);
        file.seek(SeekFrom::Start(start)).map_err(read_err)?;
        let mut tail = Vec::with_capacity((size - start) as usize);
        file.read_to_end(&mut tail).map_err(read_err)?;
        config.add_text(&tail);
    }
    config.apply_env(std::env::vars());
    if config.filament_diameter_unstated() || config.filament_diameter_griffin_assumed() {
        file.seek(SeekFrom::Start(0)).map_err(read_err)?;
        infer_filament_diameter(&mut file, &mut config).map_err(read_err)?;
    }
    config.check()?;
    file.seek(SeekFrom::Start(0)).map_err(read_err)?;
    // Positional reads of the clone leave the reader's position alone.
    let again = file.try_clone().ok();
    Ok(Opened {
        // Up to the size it had: a file that keeps growing is not read forever.
        reader: Box::new(BufReader::with_capacity(READ_BUFFER, file.take(size))),
        head,
        config,
        size,
        binary: None,
        file: again,
    })
}

/// How much of a file [`infer_filament_diameter`] reads at most: the external perimeters of
/// the first layers above the first one.
const FILAMENT_SCAN_BYTES: u64 = 8 << 20;
/// External perimeter paths sampled (longer than 1 mm, above the first layer).
const FILAMENT_SAMPLES: usize = 64;
/// Fewest samples a decision is made on.
const FILAMENT_MIN_SAMPLES: usize = 16;

/// Where a file states no filament diameter (Cura for Marlin-flavour printers, Lulzbot and
/// older Ultimaker profiles among them), E is read as 1.75 mm filament. A file sliced for
/// 2.85 mm filament then reads as walls 0.4 of the nozzle wide (2.65 times too little
/// material), and poa's loops would be laid with 2.65 times the slicer's flow. When the
/// median external perimeter reads narrower than 0.55 of the nozzle at 1.75 mm and 0.7 to
/// 1.8 nozzles wide at 2.85 mm, the file is read as 2.85 mm filament and the config says so
/// ([`SlicerConfig::inferred`]). Reads at most [`FILAMENT_SCAN_BYTES`] of `input`.
pub fn infer_filament_diameter<R: Read>(
    input: R,
    config: &mut SlicerConfig,
) -> std::io::Result<()> {
    use crate::layers::{filament_area, flow_width, LayerKind, LayerReader, ReaderOptions, Role};
    let nozzle = config.nozzle_diameter();
    let reader = LayerReader::new(
        BufReader::with_capacity(READ_BUFFER, input.take(FILAMENT_SCAN_BYTES)),
        ReaderOptions {
            keep_raw: false,
            config: config.clone(),
        },
    );
    // Cross-sections (mm2 of bead at 1.75 mm filament) with their heights.
    let area = filament_area(1.75);
    let mut samples: Vec<(f64, f64)> = Vec::with_capacity(FILAMENT_SAMPLES);
    for layer in reader {
        let layer = match layer {
            Ok(l) => l,
            // A file cut short or malformed is judged on what was read; the pipeline reports
            // the error itself.
            Err(_) => break,
        };
        if layer.kind != LayerKind::Layer || layer.index == 0 {
            continue;
        }
        for p in &layer.paths {
            let length = p.length();
            let e: f64 = p.seg_e.iter().sum();
            if p.role == Role::ExternalPerimeter && length > 1.0 && e > 0.0 && p.height > 0.0 {
                samples.push((flow_width(e, length, p.height, area), p.height));
            }
        }
        if samples.len() >= FILAMENT_SAMPLES {
            break;
        }
    }
    if samples.len() < FILAMENT_MIN_SAMPLES {
        return Ok(());
    }
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (w175, h) = samples[samples.len() / 2];
    // Same bead, 2.65 times the cross-section: the flow model's rounded ends stay.
    let ends = h * (1.0 - std::f64::consts::FRAC_PI_4);
    let w285 = (w175 - ends) * filament_area(2.85) / area + ends;
    if config.filament_diameter_griffin_assumed() {
        // The other way round: Cura's Griffin flavour set on a printer that takes 1.75 mm
        // filament (an Ender 3 profile) read as 2.85 mm gives walls 2.65 times too wide, and
        // poa's loops as wide (a mushroom's cap: 26 loops for 58) with 0.38 of the flow.
        if w285 > 1.8 * nozzle && (0.7 * nozzle..=1.8 * nozzle).contains(&w175) {
            config.infer(
                "filament_diameter",
                "1.75",
                format!(
                    "the file states no filament diameter and Cura's Griffin flavour means 2.85 mm, but its walls read {w285:.2} mm wide at 2.85 mm and {w175:.2} mm at 1.75 mm (nozzle {nozzle} mm): E is read as 1.75 mm filament (set SLIC3R_FILAMENT_DIAMETER to say otherwise)"
                ),
            );
        }
    } else if w175 < 0.55 * nozzle && (0.7 * nozzle..=1.8 * nozzle).contains(&w285) {
        config.infer(
            "filament_diameter",
            "2.85",
            format!(
                "the file states no filament diameter; its walls read {w175:.2} mm wide at 1.75 mm and {w285:.2} mm at 2.85 mm (nozzle {nozzle} mm): E is read as 2.85 mm filament (set SLIC3R_FILAMENT_DIAMETER to say otherwise)"
            ),
        );
    }
    Ok(())
}

/// Opens a regular file for reading and returns it with its size then (read no further: a
/// file that keeps growing is not read forever). Devices, FIFOs, sockets and folders are
/// refused, naming what they are, before they are opened.
pub fn open_regular(path: &Path) -> Result<(File, u64)> {
    let read_err = |source| Error::Read {
        path: path.to_path_buf(),
        source,
    };
    // stat does not block on a FIFO, so what is not a regular file is refused before opening.
    let meta = std::fs::metadata(path).map_err(read_err)?;
    check_regular(path, &meta)?;
    // Non-blocking, so that a file swapped for a FIFO since cannot hang the open either; the
    // opened file is checked again.
    let file = {
        use std::os::unix::fs::OpenOptionsExt;
        std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)
            .map_err(read_err)?
    };
    let meta = file.metadata().map_err(read_err)?;
    check_regular(path, &meta)?;
    Ok((file, meta.len()))
}

/// Reads a whole regular file (up to the size it had when opened), refusing devices, FIFOs
/// and folders as [`open`] does.
pub fn read_all(path: &Path) -> Result<Vec<u8>> {
    let (file, size) = open_regular(path)?;
    let mut data = Vec::with_capacity(size as usize);
    file.take(size)
        .read_to_end(&mut data)
        .map_err(|source| Error::Read {
            path: path.to_path_buf(),
            source,
        })?;
    Ok(data)
}

/// Opens a binary G-code file: its metadata and thumbnails are read (and checked) now, its
/// G-code blocks one at a time as the pipeline reads the text, so memory stays at one block
/// whatever the file's size.
fn open_binary(path: &Path, file: File, size: u64) -> Result<Opened> {
    let read_err = |source| Error::Read {
        path: path.to_path_buf(),
        source,
    };
    let damaged = |e: bgcode::stream::ReadError| match e {
        bgcode::stream::ReadError::Io(source) => read_err(source),
        bgcode::stream::ReadError::Format(e) => Error::NotGcode {
            path: path.to_path_buf(),
            reason: format!("the binary G-code is damaged: {e}; export it again"),
        },
    };
    let mut file = file;
    let layout = bgcode::stream::layout(&mut file, size).map_err(damaged)?;
    // The slicer's settings live in the metadata blocks as `key=value` lines.
    let mut config = SlicerConfig::default();
    for block in &layout.other.blocks {
        if matches!(
            block.kind,
            BlockKind::SlicerMetadata
                | BlockKind::PrinterMetadata
                | BlockKind::PrintMetadata
                | BlockKind::FileMetadata
        ) {
            config.add_text(&block.metadata_as_comments());
        }
    }
    let text_of = |f: &File| -> Result<bgcode::stream::GcodeReader<File>> {
        Ok(bgcode::stream::GcodeReader::new(
            f.try_clone().map_err(read_err)?,
            &layout,
            size,
        ))
    };
    let mut head = Vec::with_capacity(HEAD_BYTES as usize);
    text_of(&file)?
        .take(HEAD_BYTES)
        .read_to_end(&mut head)
        .map_err(|e| binary_read_error(path, e))?;
    config.add_text(&head);
    config.apply_env(std::env::vars());
    config.check()?;
    let reader = text_of(&file)?;
    Ok(Opened {
        reader: Box::new(reader),
        head,
        config,
        size,
        binary: Some(layout),
        file: None,
    })
}

/// A damaged G-code block met while reading the text of binary G-code is the file's fault.
fn binary_read_error(path: &Path, e: std::io::Error) -> Error {
    if e.kind() == std::io::ErrorKind::InvalidData {
        Error::NotGcode {
            path: path.to_path_buf(),
            reason: e.to_string(),
        }
    } else {
        Error::Read {
            path: path.to_path_buf(),
            source: e,
        }
    }
}

/// Refuses binary data early, with the reason.
pub fn check_text(path: &Path, head: &[u8]) -> Result<()> {
    let sample = &head[..head.len().min(8192)];
    let nul = sample.iter().filter(|&&b| b == 0).count();
    let control = sample
        .iter()
        .filter(|&&b| b < 0x20 && !matches!(b, b'\n' | b'\r' | b'\t' | 0x0c))
        .count();
    if nul > 0 || (sample.len() >= 64 && control * 10 > sample.len()) {
        return Err(Error::NotGcode {
            path: path.to_path_buf(),
            reason: "it contains binary data; pass the text G-code the slicer exported".into(),
        });
    }
    Ok(())
}

/// Refuses what is not a regular file, naming what it is.
fn check_regular(path: &Path, meta: &std::fs::Metadata) -> Result<()> {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    let what = if t.is_file() {
        return Ok(());
    } else if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a pipe (FIFO)"
    } else if t.is_char_device() || t.is_block_device() {
        "a device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    };
    Err(Error::NotGcode {
        path: path.to_path_buf(),
        reason: format!("it is {what}; save the G-code to a file and pass that file"),
    })
}

/// How far into a file the first G-code command is looked for. Comment lines do not count
/// against [`COMMAND_SCAN`] (thumbnails and long headers come before the first command), up
/// to [`COMMENT_SCAN`] bytes of them.
const COMMAND_SCAN: u64 = 64 * 1024;
const COMMENT_SCAN: u64 = 32 << 20;

enum CommandScan {
    Io(std::io::Error),
    None(String),
}

/// Whether a line is a G-code command: `G`, `M` or `T` and a digit, after an optional `N`
/// line number.
fn is_command(line: &[u8]) -> bool {
    let mut l = line.trim_ascii_start();
    if let Some(rest) = l.strip_prefix(b"N").or_else(|| l.strip_prefix(b"n")) {
        let digits = rest.iter().take_while(|b| b.is_ascii_digit()).count();
        if digits > 0 {
            l = rest[digits..].trim_ascii_start();
        }
    }
    matches!(l, [b'G' | b'g' | b'M' | b'm' | b'T' | b't', d, ..] if d.is_ascii_digit())
}

/// Refuses text that is not G-code: a known model format by its signature, or no G/M/T command
/// in the first [`COMMAND_SCAN`] bytes of non-comment text. The file is left at an unknown
/// position; the caller seeks back.
fn check_has_commands(
    file: &mut File,
    head: &[u8],
    size: u64,
) -> std::result::Result<(), CommandScan> {
    // Lines ended by CR alone (classic Mac OS) read as one line: say so, rather than that
    // the file holds no command. (Two lines' worth of CR with no LF at all.)
    if memchr::memchr(b'\n', head).is_none() && memchr::memchr_iter(b'\r', head).nth(1).is_some() {
        return Err(CommandScan::None(
            "its lines end in CR alone (classic Mac OS), which poa does not read; convert them to LF (e.g. tr '\\r' '\\n' < IN > OUT)".into(),
        ));
    }
    let start = head.trim_ascii_start();
    let lower: Vec<u8> = start.iter().take(512).map(u8::to_ascii_lowercase).collect();
    if lower.starts_with(b"solid") && memchr::memmem::find(&lower, b"facet").is_some() {
        return Err(CommandScan::None(
            "it is an STL model; slice it first and pass the G-code".into(),
        ));
    }
    if head.starts_with(b"PK\x03\x04") {
        return Err(CommandScan::None(
            "it is a zip archive (a 3MF project?); export G-code from the slicer and pass that"
                .into(),
        ));
    }
    file.seek(SeekFrom::Start(0)).map_err(CommandScan::Io)?;
    let mut reader = BufReader::with_capacity(64 * 1024, (&*file).take(size));
    let (mut code, mut comments) = (0u64, 0u64);
    let mut line = Vec::new();
    loop {
        line.clear();
        let n = (&mut reader)
            .take(COMMAND_SCAN + 1)
            .read_until(b'\n', &mut line)
            .map_err(CommandScan::Io)?;
        if n == 0 {
            break;
        }
        let t = line.trim_ascii();
        if t.starts_with(b";") || t.starts_with(b"(") || t.is_empty() {
            comments += n as u64;
            if comments > COMMENT_SCAN {
                break;
            }
            continue;
        }
        if is_command(t) {
            return Ok(());
        }
        code += n as u64;
        if code > COMMAND_SCAN {
            break;
        }
    }
    let obj = head
        .split(|&b| b == b'\n')
        .any(|l| l.starts_with(b"v ") || l.starts_with(b"vn ") || l.starts_with(b"f "));
    Err(CommandScan::None(if obj && size > 0 {
        "it looks like an OBJ model, not G-code; slice it first and pass the G-code".into()
    } else {
        "it holds no G-code command (G, M or T); pass the G-code file the slicer exported".into()
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Thirty layers of a 10 mm square wall 0.45 mm wide and 0.2 mm high, with E for
    /// filament of `diameter`.
    fn walls(diameter: f64) -> String {
        let area = (0.45 - 0.2 * (1.0 - std::f64::consts::FRAC_PI_4)) * 0.2;
        let per_mm = area / crate::layers::filament_area(diameter);
        let mut g = String::from(";FLAVOR:Marlin\nM83\n");
        for l in 0..30 {
            g.push_str(&format!(
                ";LAYER:{l}\nG0 Z{:.1} X0 Y0\n;TYPE:WALL-OUTER\n",
                0.2 * (l + 1) as f64
            ));
            for (x, y) in [(10, 0), (10, 10), (0, 10), (0, 0)] {
                g.push_str(&format!("G1 X{x} Y{y} E{:.5}\n", 10.0 * per_mm));
            }
        }
        g
    }

    /// Cura's Griffin flavour means 2.85 mm filament unless the walls read far too wide at
    /// it and right at 1.75 mm.
    #[test]
    fn a_griffin_file_in_1_75_mm_filament_is_told_from_its_walls() {
        for (diameter, read) in [(1.75, 1.75), (2.85, 2.85)] {
            let text = walls(diameter).replace(";FLAVOR:Marlin", ";FLAVOR:Griffin");
            let mut config = SlicerConfig::parse(text.as_bytes());
            assert!(config.filament_diameter_griffin_assumed());
            infer_filament_diameter(text.as_bytes(), &mut config).unwrap();
            assert_eq!(config.filament_diameter(), read, "{diameter}");
            assert_eq!(config.inferred().len(), usize::from(read == 1.75));
        }
    }

    #[test]
    fn a_2_85_mm_file_is_told_from_its_walls() {
        for (diameter, inferred) in [(2.85, true), (1.75, false)] {
            let text = walls(diameter);
            let mut config = SlicerConfig::parse(text.as_bytes());
            assert!(config.filament_diameter_unstated());
            infer_filament_diameter(text.as_bytes(), &mut config).unwrap();
            assert_eq!(config.filament_diameter() == 2.85, inferred, "{diameter}");
            assert_eq!(config.inferred().len(), usize::from(inferred));
        }
        // Too few walls to judge: nothing assumed.
        let text: String = walls(2.85)
            .lines()
            .take(40)
            .map(|l| format!("{l}\n"))
            .collect();
        let mut config = SlicerConfig::parse(text.as_bytes());
        infer_filament_diameter(text.as_bytes(), &mut config).unwrap();
        assert!(config.inferred().is_empty());
    }
}
