//! Opening a G-code file for the pipeline.
//!
//! Input: a path. Output: a buffered reader of the file's G-code text and the file's
//! [`SlicerConfig`] (read from its head and tail, then overridden by `SLIC3R_*` variables).
//! Binary G-code (`.bgcode`, recognised by its magic bytes whatever the file is called) is
//! decoded in memory: the reader then yields its G-code text, the config comes from its
//! metadata blocks, and [`Opened::binary`] keeps the decoded file so that a rewrite can be
//! written back in the same format. Refuses, with a message saying what to do, what cannot be
//! G-code: directories, damaged binary G-code, text files with binary data in their head.

use std::fs::File;
use std::io::{BufRead, BufReader, Cursor, Read, Seek, SeekFrom};
use std::path::Path;

use crate::bgcode::{self, Bgcode, BlockKind};

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
    /// The decoded file when it is binary G-code.
    pub binary: Option<Bgcode>,
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
    if bgcode::is_bgcode(&head) {
        return open_binary(path, file, size);
    }
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
        reader: Box::new(BufReader::with_capacity(READ_BUFFER, file)),
        head,
        config,
        size,
        binary: None,
    })
}

/// Decodes a binary G-code file; the pipeline reads its G-code text.
fn open_binary(path: &Path, mut file: File, size: u64) -> Result<Opened> {
    let read_err = |source| Error::Read {
        path: path.to_path_buf(),
        source,
    };
    file.seek(SeekFrom::Start(0)).map_err(read_err)?;
    let mut data = Vec::with_capacity(size as usize);
    file.read_to_end(&mut data).map_err(read_err)?;
    let decoded = bgcode::decode(&data).map_err(|e| Error::NotGcode {
        path: path.to_path_buf(),
        reason: format!("the binary G-code is damaged: {e}; export it again"),
    })?;
    let text = decoded.gcode_text();
    // The slicer's settings live in the metadata blocks as `key=value` lines.
    let mut config = SlicerConfig::default();
    for block in &decoded.blocks {
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
    let head_len = text.len().min(HEAD_BYTES as usize);
    config.add_text(&text[..head_len]);
    config.apply_env(std::env::vars());
    let head = text[..head_len].to_vec();
    Ok(Opened {
        reader: Box::new(Cursor::new(text)),
        head,
        config,
        size,
        binary: Some(decoded),
    })
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
