//! Opening a G-code file for the pipeline.
//!
//! Input: a path. Output: a buffered reader positioned at the start of the file and the file's
//! [`SlicerConfig`] (read from its head and tail, then overridden by `SLIC3R_*` variables).
//! Refuses, with a message saying what to do, what cannot be G-code: directories, binary
//! G-code (handled by a later stage), files with NUL bytes in their head.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use crate::error::{Error, Result};
use crate::layers::config::{HEAD_BYTES, TAIL_BYTES};
use crate::layers::SlicerConfig;

/// Buffer size for streaming reads: large enough to amortise syscalls, small enough to keep
/// memory flat.
pub const READ_BUFFER: usize = 256 * 1024;

pub struct Opened {
    pub reader: BufReader<File>,
    /// The first bytes of the file (up to 64 KiB).
    pub head: Vec<u8>,
    pub config: SlicerConfig,
    pub size: u64,
}

/// Opens `path`, checks that it looks like text G-code and reads its configuration.
pub fn open(path: &Path) -> Result<Opened> {
    let read_err = |source| Error::Read {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(read_err)?;
    if meta.is_dir() {
        return Err(Error::NotGcode {
            path: path.to_path_buf(),
            reason: "it is a directory; pass a .gcode file".into(),
        });
    }
    let mut file = File::open(path).map_err(read_err)?;
    let size = meta.len();
    let mut head = vec![0u8; HEAD_BYTES.min(size) as usize];
    file.read_exact(&mut head).map_err(read_err)?;
    check_text(path, &head)?;
    let mut config = SlicerConfig::parse(&head);
    if size > HEAD_BYTES {
        let start = size.saturating_sub(TAIL_BYTES).max(HEAD_BYTES);
        file.seek(SeekFrom::Start(start)).map_err(read_err)?;
        let mut tail = Vec::with_capacity((size - start) as usize);
        file.read_to_end(&mut tail).map_err(read_err)?;
        config.add_text(&tail);
    }
    config.apply_env(std::env::vars());
    file.seek(SeekFrom::Start(0)).map_err(read_err)?;
    Ok(Opened {
        reader: BufReader::with_capacity(READ_BUFFER, file),
        head,
        config,
        size,
    })
}

/// Refuses binary data early, with the reason.
pub fn check_text(path: &Path, head: &[u8]) -> Result<()> {
    if head.starts_with(b"GCDE") {
        return Err(Error::NotGcode {
            path: path.to_path_buf(),
            reason: "it is binary G-code (.bgcode), which this version cannot read yet; \
                     turn off binary G-code in the printer settings"
                .into(),
        });
    }
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
