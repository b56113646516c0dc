//! Binary G-code block by block, for files of any size in bounded memory.
//!
//! Input: a `.bgcode` file as a reader. Output: a [`Layout`] (the file header, every block
//! that is not G-code, decoded, and where the G-code blocks were) and a [`GcodeReader`] that
//! decodes the G-code blocks one at a time as text, exactly as [`super::Bgcode::gcode_text`]
//! would. Writing goes the other way through [`GcodeWriter`]: the blocks before the G-code, the
//! G-code text cut into blocks as it arrives, then the blocks after it, byte for byte what
//! [`super::encode`] of [`super::with_gcode`] writes.
//!
//! The whole-file conversions run on the same pieces: [`to_ascii`] writes what
//! [`super::Bgcode::to_ascii`] of the decoded file would, [`from_ascii`] what
//! [`super::encode`] of [`super::from_ascii`] would, from a seekable file to any writer.
//!
//! Invariants: at most one block's data is held at a time (a block may not claim more than
//! [`super::MAX_BLOCK_DECODED`]), besides the metadata and thumbnail blocks (at most
//! [`MAX_OTHER_BYTES`] of them); every block is checked (CRC, decompression) when it is read;
//! errors carry the block's index and file offset, as [`super::decode`] reports them. A text
//! is read one line at a time (at most [`crate::gcode::MAX_LINE`] bytes).

use std::io::{self, BufRead, Read, Seek, SeekFrom, Write};

use super::ascii::{AsciiScan, BinarizeConfig, LineSource};
use super::{
    decode, write_gcode_lines, Bgcode, BgcodeError, Block, BlockKind, BlockParams, ChecksumType,
    Compression, GcodeEncoding, FILE_HEADER_LEN, MAGIC, MAX_BLOCK_DECODED, MAX_GCODE_BLOCK_TEXT,
    VERSION,
};

/// A binary G-code file's blocks, without its G-code.
#[derive(Debug, Clone)]
pub struct Layout {
    /// The file header (magic, version, checksum type).
    pub header: [u8; FILE_HEADER_LEN],
    /// Every block that is not G-code, in file order (`blocks` of a file without G-code).
    pub other: Bgcode,
    /// How many of `other.blocks` come before the first G-code block.
    pub gcode_at: usize,
    /// Compression and encoding of the first G-code block, if any.
    pub gcode_format: Option<(Compression, BlockParams)>,
    /// Index (in file order, for messages) and file offset of each G-code block.
    pub gcode_blocks: Vec<(usize, u64)>,
}

/// Most blocks a file may have (a 4 GiB print cut into 64 KiB G-code blocks has 65536).
const MAX_BLOCKS: usize = 1 << 20;
/// Most metadata and thumbnail blocks, and their decoded bytes, kept in memory.
const MAX_OTHER_BLOCKS: usize = 4096;
pub const MAX_OTHER_BYTES: usize = 64 << 20;

/// Moves an error [`decode`] reported for a one-block file to the block's place in the file.
fn relocate(e: BgcodeError, index: usize, offset: u64) -> BgcodeError {
    let off = offset as usize;
    match e {
        BgcodeError::TruncatedBlock {
            needed, available, ..
        } => BgcodeError::TruncatedBlock {
            block: index,
            offset: off,
            needed,
            available,
        },
        BgcodeError::UnknownBlockType { kind, .. } => BgcodeError::UnknownBlockType {
            block: index,
            offset: off,
            kind,
        },
        BgcodeError::UnknownCompression { id, .. } => BgcodeError::UnknownCompression {
            block: index,
            offset: off,
            id,
        },
        BgcodeError::UnknownEncoding { kind, id, .. } => BgcodeError::UnknownEncoding {
            block: index,
            offset: off,
            kind,
            id,
        },
        BgcodeError::UnknownThumbnailFormat { format, .. } => BgcodeError::UnknownThumbnailFormat {
            block: index,
            offset: off,
            format,
        },
        BgcodeError::CrcMismatch {
            stored, computed, ..
        } => BgcodeError::CrcMismatch {
            block: index,
            offset: off,
            stored,
            computed,
        },
        BgcodeError::BlockTooLarge { size, limit, .. } => BgcodeError::BlockTooLarge {
            block: index,
            offset: off,
            size,
            limit,
        },
        BgcodeError::Decompression { reason, .. } => BgcodeError::Decompression {
            block: index,
            offset: off,
            reason,
        },
        other => other,
    }
}

/// Reading errors: the file's own damage, or the I/O underneath.
#[derive(Debug)]
pub enum ReadError {
    Format(BgcodeError),
    Io(io::Error),
}

impl From<io::Error> for ReadError {
    fn from(e: io::Error) -> Self {
        ReadError::Io(e)
    }
}

impl std::fmt::Display for ReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReadError::Format(e) => e.fmt(f),
            ReadError::Io(e) => e.fmt(f),
        }
    }
}

/// Reads the block at `offset` (its header first, to know its length), checks and decodes it.
/// `size` is the file's length.
///
/// Long by design: reads one block with every limit of the format checked in order (header, sizes, caps, checksum).
fn read_block<R: Read + Seek>(
    r: &mut R,
    header: &[u8; FILE_HEADER_LEN],
    index: usize,
    offset: u64,
    size: u64,
) -> Result<Block, ReadError> {
    let checksum = match u16::from_le_bytes([header[8], header[9]]) {
        1 => ChecksumType::Crc32,
        _ => ChecksumType::None,
    };
    r.seek(SeekFrom::Start(offset))?;
    let available = size - offset;
    let mut head = vec![0u8; 12.min(available) as usize];
    r.read_exact(&mut head)?;
    // What decode says of a block it cannot size (truncated header, unknown ids).
    let fail = |bytes: &[u8]| -> ReadError {
        let mut mini = header.to_vec();
        mini.extend_from_slice(bytes);
        ReadError::Format(relocate(
            decode(&mini).err().unwrap_or(BgcodeError::TruncatedBlock {
                block: 0,
                offset: 0,
                needed: 12,
                available: bytes.len(),
            }),
            index,
            offset,
        ))
    };
    if head.len() < 8 {
        return Err(fail(&head));
    }
    let kind = u16::from_le_bytes([head[0], head[1]]);
    let comp = u16::from_le_bytes([head[2], head[3]]);
    let uncompressed = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
    let (Some(kind), Some(compression)) = (BlockKind::from_id(kind), Compression::from_id(comp))
    else {
        return Err(fail(&head));
    };
    if u64::from(uncompressed) > MAX_BLOCK_DECODED {
        return Err(ReadError::Format(BgcodeError::BlockTooLarge {
            block: index,
            offset: offset as usize,
            size: uncompressed.into(),
            limit: MAX_BLOCK_DECODED,
        }));
    }
    let (header_len, stored) = if compression == Compression::None {
        (8u64, u64::from(uncompressed))
    } else {
        if head.len() < 12 {
            return Err(fail(&head));
        }
        (
            12,
            u64::from(u32::from_le_bytes([head[8], head[9], head[10], head[11]])),
        )
    };
    let params = if kind == BlockKind::Thumbnail { 6 } else { 2 };
    let crc = if checksum == ChecksumType::Crc32 {
        4
    } else {
        0
    };
    let total = header_len + params + stored + crc;
    if total > available {
        return Err(ReadError::Format(BgcodeError::TruncatedBlock {
            block: index,
            offset: offset as usize,
            needed: total,
            available: available as usize,
        }));
    }
    let mut mini = Vec::with_capacity(FILE_HEADER_LEN + total as usize);
    mini.extend_from_slice(header);
    mini.extend_from_slice(&head[..head.len().min(total as usize)]);
    let rest = total as usize - head.len().min(total as usize);
    let start = mini.len();
    mini.resize(start + rest, 0);
    r.read_exact(&mut mini[start..])?;
    let mut file = decode(&mini).map_err(|e| ReadError::Format(relocate(e, index, offset)))?;
    file.blocks
        .pop()
        .ok_or(ReadError::Format(BgcodeError::TruncatedBlock {
            block: index,
            offset: offset as usize,
            needed: total,
            available: available as usize,
        }))
}

/// The length of the block at `offset`, from its header alone.
fn block_len<R: Read + Seek>(
    r: &mut R,
    checksum: ChecksumType,
    offset: u64,
    size: u64,
) -> io::Result<Option<(BlockKind, u64)>> {
    r.seek(SeekFrom::Start(offset))?;
    let mut head = [0u8; 12];
    let n = (size - offset).min(12) as usize;
    r.read_exact(&mut head[..n])?;
    if n < 8 {
        return Ok(None);
    }
    let kind = BlockKind::from_id(u16::from_le_bytes([head[0], head[1]]));
    let comp = Compression::from_id(u16::from_le_bytes([head[2], head[3]]));
    let (Some(kind), Some(comp)) = (kind, comp) else {
        return Ok(None);
    };
    let uncompressed = u64::from(u32::from_le_bytes([head[4], head[5], head[6], head[7]]));
    let (header_len, stored) = if comp == Compression::None {
        (8, uncompressed)
    } else if n < 12 {
        return Ok(None);
    } else {
        (
            12,
            u64::from(u32::from_le_bytes([head[8], head[9], head[10], head[11]])),
        )
    };
    let params = if kind == BlockKind::Thumbnail { 6 } else { 2 };
    let crc = if checksum == ChecksumType::Crc32 {
        4
    } else {
        0
    };
    Ok(Some((kind, header_len + params + stored + crc)))
}

/// Reads the layout of a binary G-code file: decodes and checks every block but the G-code
/// ones, which are only located (they are checked as [`GcodeReader`] reads them).
pub fn layout<R: Read + Seek>(r: &mut R, size: u64) -> Result<Layout, ReadError> {
    let mut header = [0u8; FILE_HEADER_LEN];
    r.seek(SeekFrom::Start(0))?;
    let n = size.min(FILE_HEADER_LEN as u64) as usize;
    r.read_exact(&mut header[..n])?;
    // The file header's own checks.
    if let Err(e) = decode(&header[..n]) {
        return Err(ReadError::Format(e));
    }
    let checksum = if u16::from_le_bytes([header[8], header[9]]) == 1 {
        ChecksumType::Crc32
    } else {
        ChecksumType::None
    };
    let version = u32::from_le_bytes([header[4], header[5], header[6], header[7]]);
    let mut other = Bgcode {
        version,
        checksum,
        blocks: Vec::new(),
    };
    let (mut gcode_at, mut gcode_format, mut gcode_blocks) = (None, None, Vec::new());
    let mut offset = FILE_HEADER_LEN as u64;
    let mut index = 0;
    let mut kept_bytes = 0usize;
    while offset < size {
        // A slicer writes a dozen metadata and thumbnail blocks and one G-code block per
        // 64 KiB of text; far more is a file made to exhaust memory.
        if index >= MAX_BLOCKS
            || other.blocks.len() >= MAX_OTHER_BLOCKS
            || kept_bytes > MAX_OTHER_BYTES
        {
            return Err(ReadError::Format(BgcodeError::Limit(format!(
                "block {index} at offset {offset}: more blocks than any slicer writes (at most {MAX_BLOCKS} in all, {MAX_OTHER_BLOCKS} besides G-code, {} MiB of metadata and thumbnails)",
                MAX_OTHER_BYTES >> 20
            ))));
        }
        let Some((kind, len)) = block_len(r, checksum, offset, size)? else {
            // Let the full reader say what is wrong.
            return Err(read_block(r, &header, index, offset, size)
                .err()
                .unwrap_or(ReadError::Format(BgcodeError::BadMagic)));
        };
        if len > size - offset {
            return Err(ReadError::Format(BgcodeError::TruncatedBlock {
                block: index,
                offset: offset as usize,
                needed: len,
                available: (size - offset) as usize,
            }));
        }
        if kind == BlockKind::GCode {
            if gcode_format.is_none() {
                // The first G-code block is checked now: its format is the rewrite's.
                let b = read_block(r, &header, index, offset, size)?;
                gcode_format = Some((b.compression, b.params));
                gcode_at = Some(other.blocks.len());
            }
            gcode_blocks.push((index, offset));
        } else {
            let b = read_block(r, &header, index, offset, size)?;
            kept_bytes += b.payload.len();
            other.blocks.push(b);
        }
        offset += len;
        index += 1;
    }
    let gcode_at = gcode_at.unwrap_or(other.blocks.len());
    Ok(Layout {
        header,
        other,
        gcode_at,
        gcode_format,
        gcode_blocks,
    })
}

/// The G-code text of a binary file, decoded one block at a time.
pub struct GcodeReader<R> {
    inner: R,
    header: [u8; FILE_HEADER_LEN],
    size: u64,
    blocks: std::vec::IntoIter<(usize, u64)>,
    buf: Vec<u8>,
    pos: usize,
}

impl<R: Read + Seek> GcodeReader<R> {
    /// Reads the G-code blocks of `layout` from `inner` (the same file, `size` bytes long).
    pub fn new(inner: R, layout: &Layout, size: u64) -> Self {
        GcodeReader {
            inner,
            header: layout.header,
            size,
            blocks: layout.gcode_blocks.clone().into_iter(),
            buf: Vec::new(),
            pos: 0,
        }
    }

    fn refill(&mut self) -> io::Result<()> {
        while self.pos >= self.buf.len() {
            let Some((index, offset)) = self.blocks.next() else {
                return Ok(());
            };
            self.buf.clear();
            self.pos = 0;
            let block = read_block(&mut self.inner, &self.header, index, offset, self.size)
                .map_err(|e| match e {
                    ReadError::Io(e) => e,
                    ReadError::Format(e) => io::Error::new(
                        io::ErrorKind::InvalidData,
                        format!("the binary G-code is damaged: {e}; export it again"),
                    ),
                })?;
            write_gcode_lines(&block.payload, &mut self.buf);
        }
        Ok(())
    }
}

impl<R: Read + Seek> Read for GcodeReader<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let n = {
            let buf = self.fill_buf()?;
            let n = buf.len().min(out.len());
            out[..n].copy_from_slice(&buf[..n]);
            n
        };
        self.consume(n);
        Ok(n)
    }
}

impl<R: Read + Seek> BufRead for GcodeReader<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        self.refill()?;
        Ok(&self.buf[self.pos..])
    }

    fn consume(&mut self, amt: usize) {
        self.pos = (self.pos + amt).min(self.buf.len());
    }
}

/// Writes a binary G-code file with `layout`'s blocks around G-code text given as a stream:
/// the text is cut into blocks of at most [`MAX_GCODE_BLOCK_TEXT`] bytes at line ends, in the
/// first G-code block's compression and encoding (Heatshrink 12/4 with MeatPack when the file
/// had none).
pub struct GcodeWriter<'a, W: Write> {
    out: W,
    layout: &'a Layout,
    format: (Compression, BlockParams),
    /// Whole lines waiting for the block they go in.
    cache: Vec<u8>,
    /// A line not yet ended.
    partial: Vec<u8>,
    scratch: Vec<u8>,
}

impl<'a, W: Write> GcodeWriter<'a, W> {
    /// Writes the file header and the blocks that come before the G-code.
    pub fn new(mut out: W, layout: &'a Layout) -> io::Result<Self> {
        out.write_all(&layout.header)?;
        let mut scratch = Vec::new();
        for b in &layout.other.blocks[..layout.gcode_at] {
            scratch.clear();
            b.write(layout.other.checksum, &mut scratch);
            out.write_all(&scratch)?;
        }
        Ok(GcodeWriter {
            out,
            layout,
            format: layout.gcode_format.unwrap_or((
                Compression::Heatshrink12_4,
                BlockParams::GCode(GcodeEncoding::MeatPackComments),
            )),
            cache: Vec::new(),
            partial: Vec::new(),
            scratch,
        })
    }

    fn flush_block(&mut self) -> io::Result<()> {
        if self.cache.is_empty() {
            return Ok(());
        }
        let text = std::mem::take(&mut self.cache);
        let block = Block::new(BlockKind::GCode, self.format.0, self.format.1, text);
        self.scratch.clear();
        block.write(self.layout.other.checksum, &mut self.scratch);
        self.out.write_all(&self.scratch)?;
        self.cache = block.payload;
        self.cache.clear();
        Ok(())
    }

    fn add_line(&mut self, line: &[u8]) -> io::Result<()> {
        if line.len() + self.cache.len() > MAX_GCODE_BLOCK_TEXT && !self.cache.is_empty() {
            self.flush_block()?;
        }
        self.cache.extend_from_slice(line);
        Ok(())
    }

    /// Writes the last G-code block and the blocks after the G-code; returns the writer.
    pub fn finish(mut self) -> io::Result<W> {
        if !self.partial.is_empty() {
            let mut line = std::mem::take(&mut self.partial);
            // libbgcode only takes whole lines.
            line.push(b'\n');
            self.add_line(&line)?;
        }
        self.flush_block()?;
        for b in &self.layout.other.blocks[self.layout.gcode_at..] {
            self.scratch.clear();
            b.write(self.layout.other.checksum, &mut self.scratch);
            self.out.write_all(&self.scratch)?;
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write> Write for GcodeWriter<'_, W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let mut rest = buf;
        while let Some(i) = memchr::memchr(b'\n', rest) {
            if self.partial.is_empty() {
                self.add_line(&rest[..=i])?;
            } else {
                let mut line = std::mem::take(&mut self.partial);
                line.extend_from_slice(&rest[..=i]);
                self.add_line(&line)?;
                line.clear();
                self.partial = line;
            }
            rest = &rest[i + 1..];
        }
        self.partial.extend_from_slice(rest);
        if self.partial.len() > crate::gcode::MAX_LINE {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                "a G-code line longer than poa accepts",
            ));
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Why a whole-file conversion ([`to_ascii`], [`from_ascii`]) stopped.
#[derive(Debug)]
pub enum ConvertError {
    /// The input cannot be converted: a damaged binary file, or text that is not PrusaSlicer's
    /// (what [`super::decode`] or [`super::from_ascii`] say of it).
    Format(BgcodeError),
    /// A text line longer than [`crate::gcode::MAX_LINE`]: its number, counting lines ended
    /// by `\n` from 1.
    LineTooLong(u64),
    /// Reading the input failed.
    Read(io::Error),
    /// Writing the output failed.
    Write(io::Error),
}

impl From<ReadError> for ConvertError {
    fn from(e: ReadError) -> Self {
        match e {
            ReadError::Format(e) => ConvertError::Format(e),
            ReadError::Io(e) => ConvertError::Read(e),
        }
    }
}

/// Writes the text G-code of the binary G-code file `r` (`size` bytes long) to `out`: byte for
/// byte [`super::Bgcode::to_ascii`] of the decoded file, one G-code block in memory at a time.
/// The metadata and thumbnail blocks are all read and checked before anything is written; a
/// damaged G-code block is found as its turn comes, after the text before it was written.
pub fn to_ascii<R: Read + Seek, W: Write>(
    r: &mut R,
    size: u64,
    mut out: W,
) -> Result<W, ConvertError> {
    let layout = layout(r, size)?;
    let mut text = Vec::new();
    layout.other.ascii_head(&mut text);
    out.write_all(&text).map_err(ConvertError::Write)?;
    // GcodeReader's own loop, with the block's error kept whole (its Read impl can only
    // give it as text) and reading told apart from writing.
    for &(index, offset) in &layout.gcode_blocks {
        let block = read_block(r, &layout.header, index, offset, size)?;
        text.clear();
        write_gcode_lines(&block.payload, &mut text);
        out.write_all(&text).map_err(ConvertError::Write)?;
    }
    text.clear();
    layout.other.ascii_tail(&mut text);
    out.write_all(&text).map_err(ConvertError::Write)?;
    out.flush().map_err(ConvertError::Write)?;
    Ok(out)
}

/// How much of a text file is read at a time.
const TEXT_BUFFER: usize = 256 * 1024;

/// The lines of the text file `r` from its start, up to `size` bytes: a file that keeps
/// growing is not read forever.
fn text_lines<R: Read + Seek>(
    r: &mut R,
    size: u64,
) -> Result<LineSource<io::BufReader<io::Take<&mut R>>>, ConvertError> {
    r.seek(SeekFrom::Start(0)).map_err(ConvertError::Read)?;
    Ok(LineSource::new(io::BufReader::with_capacity(
        TEXT_BUFFER,
        r.take(size),
    )))
}

/// Writes the binary G-code of the PrusaSlicer text G-code file `r` (`size` bytes long) to
/// `out`: byte for byte [`super::encode`] of [`super::from_ascii`] with `config`, in memory of
/// one line, one block and the metadata.
///
/// Two passes over the file, because the binary starts with metadata the text states last
/// (the print statistics): the first scans every line and builds the metadata and thumbnail
/// blocks, the second scans again (the same rules, so the same lines are metadata) and sends
/// the other lines through [`GcodeWriter`], which cuts blocks where [`super::from_ascii`]
/// does. Every refusal (a line too long, text that is not PrusaSlicer's) comes from the first
/// pass, before anything is written; a line too long anywhere is reported before what the
/// scanner found wrong, as [`super::from_ascii`]'s callers always checked it first.
pub fn from_ascii<R: Read + Seek, W: Write>(
    r: &mut R,
    size: u64,
    config: &BinarizeConfig,
    out: W,
) -> Result<W, ConvertError> {
    let mut lines = text_lines(r, size)?;
    let mut scan = AsciiScan::new(config);
    let mut refused = None;
    while lines.piece(|i, line| {
        if refused.is_none() {
            if let Err(e) = scan.line(i, line) {
                refused = Some(e);
            }
        }
        Ok(())
    })? {}
    if let Some(e) = refused {
        return Err(ConvertError::Format(e));
    }
    let blocks = scan.finish().map_err(ConvertError::Format)?;
    drop(lines);

    let mut header = [0u8; FILE_HEADER_LEN];
    header[..4].copy_from_slice(MAGIC);
    header[4..8].copy_from_slice(&VERSION.to_le_bytes());
    header[8..].copy_from_slice(&config.checksum.id().to_le_bytes());
    let layout = Layout {
        header,
        gcode_at: blocks.len(),
        other: Bgcode {
            version: VERSION,
            checksum: config.checksum,
            blocks,
        },
        gcode_format: Some((config.gcode, BlockParams::GCode(config.gcode_encoding))),
        gcode_blocks: Vec::new(),
    };

    let mut lines = text_lines(r, size)?;
    let mut scan = AsciiScan::new(config);
    let mut writer = GcodeWriter::new(out, &layout).map_err(ConvertError::Write)?;
    // Lines gathered to a block's worth before the writer splits them again.
    let mut gcode = Vec::with_capacity(2 * MAX_GCODE_BLOCK_TEXT);
    while lines.piece(|i, line| {
        if !scan.line(i, line).map_err(ConvertError::Format)? {
            gcode.extend_from_slice(line);
            gcode.push(b'\n');
            if gcode.len() >= MAX_GCODE_BLOCK_TEXT {
                writer.write_all(&gcode).map_err(ConvertError::Write)?;
                gcode.clear();
            }
        }
        Ok(())
    })? {}
    writer.write_all(&gcode).map_err(ConvertError::Write)?;
    writer.finish().map_err(ConvertError::Write)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Bgcode {
        let text: Vec<u8> = (0..40_000)
            .map(|i| format!("G1 X{} Y{} E0.01 ; move {i}\n", i % 200, i % 37))
            .collect::<String>()
            .into_bytes();
        let meta = |kind| {
            Block::new(
                kind,
                Compression::Deflate,
                BlockParams::Metadata(super::super::MetadataEncoding::Ini),
                b"key=value\nother=1\n".to_vec(),
            )
        };
        let mut b = Bgcode {
            version: 1,
            checksum: ChecksumType::Crc32,
            blocks: vec![
                meta(BlockKind::FileMetadata),
                meta(BlockKind::PrinterMetadata),
            ],
        };
        b.blocks.push(Block::new(
            BlockKind::GCode,
            Compression::Heatshrink12_4,
            BlockParams::GCode(GcodeEncoding::MeatPackComments),
            Vec::new(),
        ));
        b.blocks.push(meta(BlockKind::SlicerMetadata));
        super::super::with_gcode(&b, &text)
    }

    #[test]
    fn streaming_reads_and_writes_what_the_whole_file_codec_does() {
        let file = sample();
        let bytes = super::super::encode(&file);
        let size = bytes.len() as u64;
        let layout = layout(&mut io::Cursor::new(&bytes), size).unwrap();
        assert_eq!(layout.other.blocks.len(), 3);
        assert_eq!(layout.gcode_at, 2);
        assert!(layout.gcode_blocks.len() > 10);
        let mut text = Vec::new();
        GcodeReader::new(io::Cursor::new(&bytes), &layout, size)
            .read_to_end(&mut text)
            .unwrap();
        assert!(text == decode(&bytes).unwrap().gcode_text());
        // Written back in odd-sized pieces: the same bytes as the whole-file encoder.
        let mut w = GcodeWriter::new(Vec::new(), &layout).unwrap();
        for piece in text.chunks(777) {
            w.write_all(piece).unwrap();
        }
        let again = w.finish().unwrap();
        let whole =
            super::super::encode(&super::super::with_gcode(&decode(&bytes).unwrap(), &text));
        assert!(again == whole);
    }

    #[test]
    fn damage_is_found_with_its_block() {
        let bytes = super::super::encode(&sample());
        let size = bytes.len() as u64;
        let l = layout(&mut io::Cursor::new(&bytes), size).unwrap();
        let at = l.gcode_blocks[3].1 as usize + 20;
        let mut bad = bytes.clone();
        bad[at] ^= 0x40;
        let mut text = Vec::new();
        let e = GcodeReader::new(io::Cursor::new(&bad), &l, size)
            .read_to_end(&mut text)
            .unwrap_err();
        assert!(e.to_string().contains("CRC mismatch"), "{e}");
        // Whole-file decoding reports the same block offset.
        let whole = decode(&bad).unwrap_err().to_string();
        assert!(
            whole.contains(&format!("offset {}", l.gcode_blocks[3].1)),
            "{whole}"
        );
        // A block claiming a gigabyte is refused before anything is inflated.
        let mut bomb = bytes.clone();
        let first = l.gcode_blocks[0].1 as usize;
        bomb[first + 4..first + 8].copy_from_slice(&(1u32 << 30).to_le_bytes());
        assert!(matches!(
            layout(&mut io::Cursor::new(&bomb), size),
            Err(ReadError::Format(BgcodeError::BlockTooLarge { .. }))
        ));
    }

    /// A PrusaSlicer-like text with every kind of line the converter tells apart, and line
    /// ends of every kind: `\r\n`, `\r` alone, a NUL cutting a line, no final newline.
    fn prusa_like_text() -> Vec<u8> {
        let mut t = Vec::new();
        t.extend_from_slice(b"; generated by PrusaSlicer 2.7.0 on 2024-01-02 at 10:11:12 UTC\r\n");
        t.extend_from_slice(b"; prepared by someone\n;\n\n");
        // A 4 x 4 thumbnail of 36 bytes: 48 base64 characters over two rows.
        let image: Vec<u8> = (0..36u8).collect();
        let b64 = super::super::base64(&image);
        t.extend_from_slice(format!("; thumbnail begin 4x4 {}\r\n", b64.len()).as_bytes());
        t.extend_from_slice(b"; ");
        t.extend_from_slice(&b64[..30]);
        t.extend_from_slice(b"\r; ");
        t.extend_from_slice(&b64[30..]);
        t.extend_from_slice(b"\n; thumbnail end\n;\n\n");
        t.extend_from_slice(b"M73 P0 R5\nG90\r\nM83\rG1 Z0.2 F720\n");
        for i in 0..6000 {
            // Enough lines for several 64 KiB blocks, with every line end.
            let end: &[u8] = [b"\n".as_slice(), b"\r\n", b"\r"][i % 3];
            t.extend_from_slice(
                format!("G1 X{} Y{} E0.0123 ; move {i}", i % 200, i % 37).as_bytes(),
            );
            t.extend_from_slice(end);
        }
        t.extend_from_slice(b"M117 cut\0 here, the rest is dropped\n");
        t.extend_from_slice(b"; filament used [mm] = 1234.5\r\n; printer_model = MK4\n");
        t.extend_from_slice(b"; estimated printing time (normal mode) = 1h 2m\n\n");
        t.extend_from_slice(b"; prusaslicer_config = begin\r\n; layer_height = 0.2\n");
        t.extend_from_slice(b"; nozzle_diameter = 0.4\r; printer_model = MK4\n");
        t.extend_from_slice(b"; prusaslicer_config = end");
        t
    }

    #[test]
    fn streamed_conversions_write_what_the_whole_file_ones_do() {
        let text = prusa_like_text();
        for config in [BinarizeConfig::prusaslicer(), {
            let mut c = BinarizeConfig::prusaslicer();
            c.gcode = Compression::Deflate;
            c.gcode_encoding = GcodeEncoding::None;
            c.checksum = ChecksumType::None;
            c
        }] {
            let whole = super::super::from_ascii(&text, &config).unwrap();
            assert!(whole.blocks.iter().any(|b| b.kind == BlockKind::Thumbnail));
            assert!(
                whole
                    .blocks
                    .iter()
                    .filter(|b| b.kind == BlockKind::GCode)
                    .count()
                    > 2
            );
            let whole = super::super::encode(&whole);
            let size = text.len() as u64;
            let streamed =
                from_ascii(&mut io::Cursor::new(&text), size, &config, Vec::new()).unwrap();
            assert!(streamed == whole, "text to binary");

            let ascii = decode(&whole).unwrap().to_ascii();
            let size = whole.len() as u64;
            let streamed = to_ascii(&mut io::Cursor::new(&whole), size, Vec::new()).unwrap();
            assert!(streamed == ascii, "binary to text");
        }
    }

    #[test]
    fn streamed_text_is_refused_as_the_whole_text_is() {
        let config = BinarizeConfig::prusaslicer();
        let convert =
            |t: &[u8]| from_ascii(&mut io::Cursor::new(t), t.len() as u64, &config, Vec::new());
        let max = crate::gcode::MAX_LINE;
        // A line of the longest length (its '\r' counted, as ever) passes; one byte more is
        // refused with its number (counting lines ended by '\n'), also after a line the
        // scanner refuses.
        let mut t = prusa_like_text();
        t.extend_from_slice(b"\n; ");
        t.extend_from_slice(&vec![b'x'; max - 3]);
        t.extend_from_slice(b"\r\n");
        assert!(convert(&t).is_ok());
        let lines = t.iter().filter(|&&c| c == b'\n').count() as u64;
        let mut bad = b"; generated by PrusaSlicer 2.7.0\n; thumbnail begin 1x1\n".to_vec();
        bad.extend_from_slice(&t[..t.len() - 2]);
        bad.extend_from_slice(b"yz");
        assert!(matches!(convert(&bad), Err(ConvertError::LineTooLong(n)) if n == lines + 2));
        // Without the long line, the scanner's refusal is the whole-text one.
        let bad = &bad[..bad.len() - max];
        let (Err(ConvertError::Format(e)), Err(whole)) =
            (convert(bad), super::super::from_ascii(bad, &config))
        else {
            panic!("not refused");
        };
        assert_eq!(e, whole);
        // Text that is not PrusaSlicer's.
        let (Err(ConvertError::Format(e)), Err(whole)) = (
            convert(b"G1 X1\r\n"),
            super::super::from_ascii(b"G1 X1\r\n", &config),
        ) else {
            panic!("not refused");
        };
        assert_eq!(e, whole);
    }
}
