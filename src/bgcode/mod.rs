//! Binary G-code (`.bgcode`, PrusaSlicer 2.7+), format version 1 of prusa3d/libbgcode's
//! `doc/specifications.md`.
//!
//! Input: the bytes of a `.bgcode` file. [`decode`] checks the header, walks every block,
//! verifies its CRC32 (over block header, parameters and stored data) and undoes compression
//! (Deflate in a zlib wrapper, Heatshrink 11/4 and 12/4) and G-code encoding (MeatPack, with or
//! without comment lines). Output: a [`Bgcode`] whose blocks keep kind, compression, parameters
//! and the decoded payload (INI text for metadata, image bytes for thumbnails, G-code text).
//! [`Bgcode::to_ascii`] writes the text G-code that libbgcode's `from_binary_to_ascii` writes;
//! [`encode`] writes blocks back with their own compression and encoding; [`with_gcode`]
//! swaps the G-code for new text, cut into blocks as PrusaSlicer cuts it. [`stream`] does the
//! same for files of any size, one block at a time, and converts text <-> binary that way.
//!
//! Invariants: [`decode`] never panics and rejects what it cannot read exactly. A block that was
//! decoded and not changed is written back with its stored bytes, so `encode(&decode(x)?) == x`.
//! A new or changed block is encoded afresh: Heatshrink gives the C library's bytes, MeatPack
//! libbgcode's bytes for the same text (a `G` line that had an inline comment is the exception:
//! MeatPack drops the comment, yet it ends that line with one newline instead of two, and the
//! decoded text no longer shows it); Deflate (miniz_oxide, not zlib) gives a valid zlib stream
//! of other bytes. Either way `decode(&encode(b))` has the payloads of `b`, up to MeatPack's
//! own normalisation of G-code text.

mod ascii;
mod heatshrink;
mod meatpack;
pub mod stream;

pub use ascii::{from_ascii, BinarizeConfig};

use std::io::Read;

/// Most G-code text one block holds: libbgcode's `Binarizer` cache size, which PrusaSlicer uses.
pub const MAX_GCODE_BLOCK_TEXT: usize = 65536;

const MAGIC: &[u8; 4] = b"GCDE";
const VERSION: u32 = 1;
const FILE_HEADER_LEN: usize = 10;

/// Why a `.bgcode` file cannot be read. Offsets are byte offsets in the file; block indices
/// count from 0 in file order.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BgcodeError {
    #[error("not a binary G-code file: it does not start with \"GCDE\"")]
    BadMagic,
    #[error("cannot convert this text to binary G-code: {0}")]
    InvalidText(String),
    #[error("{0}")]
    Limit(String),
    #[error("binary G-code version {0} is not supported (only version 1 is)")]
    UnsupportedVersion(u32),
    #[error("binary G-code file header is truncated ({len} bytes, 10 needed)")]
    TruncatedHeader { len: usize },
    #[error("unknown checksum type {0} in the file header")]
    UnknownChecksumType(u16),
    #[error("block {block} at offset {offset} is truncated: it needs {needed} bytes, {available} are left")]
    TruncatedBlock {
        block: usize,
        offset: usize,
        needed: u64,
        available: usize,
    },
    #[error("block {block} at offset {offset} has unknown block type {kind}")]
    UnknownBlockType {
        block: usize,
        offset: usize,
        kind: u16,
    },
    #[error("block {block} at offset {offset} has unknown compression id {id}")]
    UnknownCompression {
        block: usize,
        offset: usize,
        id: u16,
    },
    #[error("block {block} at offset {offset} has unknown encoding {id} for a {kind} block")]
    UnknownEncoding {
        block: usize,
        offset: usize,
        kind: BlockKind,
        id: u16,
    },
    #[error("block {block} at offset {offset} is a thumbnail with unknown format {format}")]
    UnknownThumbnailFormat {
        block: usize,
        offset: usize,
        format: u16,
    },
    #[error("CRC mismatch in block {block} at offset {offset}: stored {stored:08x}, computed {computed:08x}")]
    CrcMismatch {
        block: usize,
        offset: usize,
        stored: u32,
        computed: u32,
    },
    #[error("block {block} at offset {offset} says it decodes to {size} bytes, more than the {limit} a binary G-code block may hold")]
    BlockTooLarge {
        block: usize,
        offset: usize,
        size: u64,
        limit: u64,
    },
    #[error("the blocks say they decode to more than {limit} bytes in all, far more than a file of {file} bytes can honestly hold")]
    TooLarge { limit: u64, file: u64 },
    #[error("block {block} at offset {offset} cannot be decompressed: {reason}")]
    Decompression {
        block: usize,
        offset: usize,
        reason: String,
    },
}

/// Checksum type of the file header; it applies to every block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChecksumType {
    None,
    Crc32,
}

impl ChecksumType {
    fn id(self) -> u16 {
        match self {
            ChecksumType::None => 0,
            ChecksumType::Crc32 => 1,
        }
    }
}

/// Block type, with the spec's ids.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlockKind {
    FileMetadata,
    GCode,
    SlicerMetadata,
    PrinterMetadata,
    PrintMetadata,
    Thumbnail,
}

impl BlockKind {
    fn from_id(id: u16) -> Option<Self> {
        Some(match id {
            0 => BlockKind::FileMetadata,
            1 => BlockKind::GCode,
            2 => BlockKind::SlicerMetadata,
            3 => BlockKind::PrinterMetadata,
            4 => BlockKind::PrintMetadata,
            5 => BlockKind::Thumbnail,
            _ => return None,
        })
    }

    fn id(self) -> u16 {
        match self {
            BlockKind::FileMetadata => 0,
            BlockKind::GCode => 1,
            BlockKind::SlicerMetadata => 2,
            BlockKind::PrinterMetadata => 3,
            BlockKind::PrintMetadata => 4,
            BlockKind::Thumbnail => 5,
        }
    }

    fn is_metadata(self) -> bool {
        !matches!(self, BlockKind::GCode | BlockKind::Thumbnail)
    }
}

impl std::fmt::Display for BlockKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BlockKind::FileMetadata => "file metadata",
            BlockKind::GCode => "G-code",
            BlockKind::SlicerMetadata => "slicer metadata",
            BlockKind::PrinterMetadata => "printer metadata",
            BlockKind::PrintMetadata => "print metadata",
            BlockKind::Thumbnail => "thumbnail",
        })
    }
}

/// Compression of a block's data, with the spec's ids 0-3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    None,
    Deflate,
    Heatshrink11_4,
    Heatshrink12_4,
}

impl Compression {
    pub const ALL: [Compression; 4] = [
        Compression::None,
        Compression::Deflate,
        Compression::Heatshrink11_4,
        Compression::Heatshrink12_4,
    ];

    fn from_id(id: u16) -> Option<Self> {
        Compression::ALL.get(id as usize).copied()
    }

    fn id(self) -> u16 {
        match self {
            Compression::None => 0,
            Compression::Deflate => 1,
            Compression::Heatshrink11_4 => 2,
            Compression::Heatshrink12_4 => 3,
        }
    }

    fn heatshrink(self) -> Option<heatshrink::Params> {
        let window_bits = match self {
            Compression::Heatshrink11_4 => 11,
            Compression::Heatshrink12_4 => 12,
            _ => return None,
        };
        Some(heatshrink::Params {
            window_bits,
            lookahead_bits: 4,
        })
    }
}

/// Encoding of a G-code block's text, with the spec's ids 0-2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GcodeEncoding {
    None,
    MeatPack,
    /// MeatPack keeping comment lines; what PrusaSlicer writes.
    MeatPackComments,
}

impl GcodeEncoding {
    pub const ALL: [GcodeEncoding; 3] = [
        GcodeEncoding::None,
        GcodeEncoding::MeatPack,
        GcodeEncoding::MeatPackComments,
    ];

    fn id(self) -> u16 {
        match self {
            GcodeEncoding::None => 0,
            GcodeEncoding::MeatPack => 1,
            GcodeEncoding::MeatPackComments => 2,
        }
    }
}

/// Encoding of a metadata block: INI (`key=value` lines, the spec's only one) or JSON (a single
/// document, which newer libbgcode writes as a second slicer metadata block).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MetadataEncoding {
    Ini,
    Json,
}

/// Image format of a thumbnail block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ThumbnailFormat {
    Png,
    Jpg,
    Qoi,
}

/// A block's parameters; which variant goes with which [`BlockKind`] is fixed by the spec.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlockParams {
    Metadata(MetadataEncoding),
    Thumbnail {
        format: ThumbnailFormat,
        width: u16,
        height: u16,
    },
    GCode(GcodeEncoding),
}

impl BlockParams {
    fn write(self, out: &mut Vec<u8>) {
        match self {
            BlockParams::Metadata(e) => out.extend_from_slice(&(e as u16).to_le_bytes()),
            BlockParams::GCode(e) => out.extend_from_slice(&e.id().to_le_bytes()),
            BlockParams::Thumbnail {
                format,
                width,
                height,
            } => {
                out.extend_from_slice(&(format as u16).to_le_bytes());
                out.extend_from_slice(&width.to_le_bytes());
                out.extend_from_slice(&height.to_le_bytes());
            }
        }
    }
}

/// The bytes a block had in its file, kept to write an unchanged block back exactly (a
/// Deflate stream from zlib cannot be reproduced by miniz_oxide).
#[derive(Debug, Clone, PartialEq, Eq)]
struct Stored {
    data: Vec<u8>,
    compression: Compression,
    params: BlockParams,
    uncompressed_len: usize,
    payload_len: usize,
    payload_crc: u32,
}

/// One block, decoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Block {
    pub kind: BlockKind,
    pub compression: Compression,
    pub params: BlockParams,
    /// Metadata: the INI (or JSON) text; thumbnail: the image file; G-code: the text as
    /// libbgcode decodes it (MeatPack puts spaces back and folds blank lines).
    pub payload: Vec<u8>,
    stored: Option<Stored>,
}

impl Block {
    /// A block with no stored bytes: [`encode`] compresses and encodes it afresh.
    pub fn new(
        kind: BlockKind,
        compression: Compression,
        params: BlockParams,
        payload: Vec<u8>,
    ) -> Self {
        Block {
            kind,
            compression,
            params,
            payload,
            stored: None,
        }
    }

    /// Drops the bytes read from the file, so that [`encode`] re-encodes this block.
    pub fn forget_stored(&mut self) {
        self.stored = None;
    }

    /// The metadata as `; key = value` comment lines, the way text G-code states them.
    pub fn metadata_as_comments(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for (k, v) in self.metadata() {
            out.extend_from_slice(b"; ");
            out.extend_from_slice(k);
            out.extend_from_slice(b" = ");
            out.extend_from_slice(v);
            out.push(b'\n');
        }
        out
    }

    /// `key = value` pairs of an INI metadata block, read as libbgcode reads them: one per
    /// line, split at the first '='; lines without '=' are skipped.
    pub fn metadata(&self) -> Vec<(&[u8], &[u8])> {
        self.payload
            .split(|&c| c == b'\n')
            .filter_map(|line| {
                let eq = line.iter().position(|&c| c == b'=')?;
                Some((&line[..eq], &line[eq + 1..]))
            })
            .collect()
    }

    /// The size the header records (encoded, before compression) and the data as it goes in
    /// the file (encoded, then compressed).
    fn data_bytes(&self) -> (usize, Vec<u8>) {
        if let Some(s) = &self.stored {
            if s.compression == self.compression
                && s.params == self.params
                && s.payload_len == self.payload.len()
                && s.payload_crc == crc32fast::hash(&self.payload)
            {
                return (s.uncompressed_len, s.data.clone());
            }
        }
        // libbgcode writes an empty payload as no data at all, whatever the compression.
        if self.payload.is_empty() {
            return (0, Vec::new());
        }
        let encoded = match self.params {
            BlockParams::GCode(GcodeEncoding::MeatPack) => meatpack::encode(&self.payload, false),
            BlockParams::GCode(GcodeEncoding::MeatPackComments) => {
                meatpack::encode(&self.payload, true)
            }
            _ => self.payload.clone(),
        };
        (encoded.len(), compress(&encoded, self.compression))
    }

    /// Header, parameters, data and checksum, as they go in the file.
    fn write(&self, checksum: ChecksumType, out: &mut Vec<u8>) {
        let (uncompressed_len, data) = self.data_bytes();
        let start = out.len();
        out.extend_from_slice(&self.kind.id().to_le_bytes());
        out.extend_from_slice(&self.compression.id().to_le_bytes());
        out.extend_from_slice(&(uncompressed_len as u32).to_le_bytes());
        if self.compression != Compression::None {
            out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        }
        self.params.write(out);
        out.extend_from_slice(&data);
        if checksum == ChecksumType::Crc32 {
            let crc = crc32fast::hash(&out[start..]);
            out.extend_from_slice(&crc.to_le_bytes());
        }
    }
}

/// A decoded `.bgcode` file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bgcode {
    pub version: u32,
    pub checksum: ChecksumType,
    pub blocks: Vec<Block>,
}

/// True when `head` (the first bytes of a file, 4 or more) starts with the bgcode magic.
pub fn is_bgcode(head: &[u8]) -> bool {
    head.starts_with(MAGIC)
}

fn compress(data: &[u8], compression: Compression) -> Vec<u8> {
    match compression {
        Compression::None => data.to_vec(),
        Compression::Deflate => {
            let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::new(6));
            // Writing into a Vec cannot fail.
            let _ = std::io::Write::write_all(&mut e, data);
            e.finish().unwrap_or_default()
        }
        Compression::Heatshrink11_4 | Compression::Heatshrink12_4 => {
            let p = compression.heatshrink().unwrap_or(heatshrink::Params {
                window_bits: 12,
                lookahead_bits: 4,
            });
            heatshrink::compress(data, p)
        }
    }
}

fn decompress(data: &[u8], compression: Compression, expected: usize) -> Result<Vec<u8>, String> {
    if expected == 0 && data.is_empty() {
        return Ok(Vec::new());
    }
    match compression {
        Compression::None => Ok(data.to_vec()),
        Compression::Deflate => {
            let mut out = Vec::with_capacity(expected.min(data.len().saturating_mul(16) + 64));
            // One byte more than expected shows a stream that is too long without inflating a
            // bomb.
            flate2::read::ZlibDecoder::new(data)
                .take(expected as u64 + 1)
                .read_to_end(&mut out)
                .map_err(|e| format!("Deflate: {e}"))?;
            if out.len() != expected {
                return Err(format!(
                    "Deflate stream holds {}{} bytes, the header says {expected}",
                    out.len().min(expected),
                    if out.len() > expected { "+" } else { "" }
                ));
            }
            Ok(out)
        }
        Compression::Heatshrink11_4 | Compression::Heatshrink12_4 => {
            let p = compression
                .heatshrink()
                .ok_or_else(|| "not heatshrink".to_string())?;
            heatshrink::decompress(data, p, expected).map_err(|e| match e {
                heatshrink::DecompressError::TooLong => {
                    format!(
                        "Heatshrink stream holds more than the {expected} bytes the header says"
                    )
                }
                heatshrink::DecompressError::TooShort(n) => {
                    format!("Heatshrink stream holds {n} bytes, the header says {expected}")
                }
            })
        }
    }
}

struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n)?;
        let s = self.data.get(self.pos..end)?;
        self.pos = end;
        Some(s)
    }

    fn u16(&mut self) -> Option<u16> {
        self.take(2).map(|b| u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self) -> Option<u32> {
        self.take(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// Most bytes one compressed block may decode to. PrusaSlicer and libbgcode write G-code blocks
/// of 64 KiB of text and metadata of a few KiB; a bigger claim is a damaged or hostile file,
/// refused before anything is inflated.
pub const MAX_BLOCK_DECODED: u64 = 16 << 20;

/// Most bytes a whole file may decode to, per byte of file: MeatPack and Heatshrink give
/// about 3-5 x on G-code and Deflate rarely more than 10 x; a file claiming more is refused.
pub const MAX_EXPANSION: u64 = 32;

/// Reads a whole `.bgcode` file. Blocks may come in any order; each one is checked on its own.
///
/// Long by design: the block-by-block parser of the format's layout, each block kind checked against its spec in order; split up, the cursor and limits would be passed around.
pub fn decode(data: &[u8]) -> Result<Bgcode, BgcodeError> {
    if data.len() >= 4 && !is_bgcode(data) {
        return Err(BgcodeError::BadMagic);
    }
    if data.len() < FILE_HEADER_LEN {
        if !is_bgcode(data) && !MAGIC.starts_with(data) {
            return Err(BgcodeError::BadMagic);
        }
        return Err(BgcodeError::TruncatedHeader { len: data.len() });
    }
    let version = u32::from_le_bytes([data[4], data[5], data[6], data[7]]);
    if version != VERSION {
        return Err(BgcodeError::UnsupportedVersion(version));
    }
    let checksum = match u16::from_le_bytes([data[8], data[9]]) {
        0 => ChecksumType::None,
        1 => ChecksumType::Crc32,
        other => return Err(BgcodeError::UnknownChecksumType(other)),
    };

    let mut cur = Cursor {
        data,
        pos: FILE_HEADER_LEN,
    };
    let mut blocks = Vec::new();
    let total_limit = (data.len() as u64).saturating_mul(MAX_EXPANSION) + (1 << 20);
    let mut total = 0u64;
    while cur.pos < data.len() {
        let block = blocks.len();
        let offset = cur.pos;
        let truncated = |needed: u64| BgcodeError::TruncatedBlock {
            block,
            offset,
            needed,
            available: data.len() - offset,
        };
        let (Some(kind_id), Some(comp_id), Some(uncompressed)) = (cur.u16(), cur.u16(), cur.u32())
        else {
            return Err(truncated(8));
        };
        let kind = BlockKind::from_id(kind_id).ok_or(BgcodeError::UnknownBlockType {
            block,
            offset,
            kind: kind_id,
        })?;
        let compression = Compression::from_id(comp_id).ok_or(BgcodeError::UnknownCompression {
            block,
            offset,
            id: comp_id,
        })?;
        let header_len = if compression == Compression::None {
            8
        } else {
            12
        };
        let stored_len = if compression == Compression::None {
            uncompressed
        } else {
            cur.u32().ok_or_else(|| truncated(12))?
        };
        if compression != Compression::None && u64::from(uncompressed) > MAX_BLOCK_DECODED {
            return Err(BgcodeError::BlockTooLarge {
                block,
                offset,
                size: uncompressed.into(),
                limit: MAX_BLOCK_DECODED,
            });
        }
        total += u64::from(uncompressed);
        if total > total_limit {
            return Err(BgcodeError::TooLarge {
                limit: total_limit,
                file: data.len() as u64,
            });
        }
        let params_len = if kind == BlockKind::Thumbnail { 6 } else { 2 };
        let crc_len = if checksum == ChecksumType::Crc32 {
            4
        } else {
            0
        };
        let needed = header_len + params_len + stored_len as u64 + crc_len;
        if ((data.len() - offset) as u64) < needed {
            return Err(truncated(needed));
        }
        let params = match kind {
            BlockKind::Thumbnail => {
                let (f, width, height) = (
                    cur.u16().unwrap_or(0),
                    cur.u16().unwrap_or(0),
                    cur.u16().unwrap_or(0),
                );
                let format = match f {
                    0 => ThumbnailFormat::Png,
                    1 => ThumbnailFormat::Jpg,
                    2 => ThumbnailFormat::Qoi,
                    _ => {
                        return Err(BgcodeError::UnknownThumbnailFormat {
                            block,
                            offset,
                            format: f,
                        })
                    }
                };
                BlockParams::Thumbnail {
                    format,
                    width,
                    height,
                }
            }
            _ => {
                let id = cur.u16().unwrap_or(0);
                let unknown = BgcodeError::UnknownEncoding {
                    block,
                    offset,
                    kind,
                    id,
                };
                if kind == BlockKind::GCode {
                    BlockParams::GCode(*GcodeEncoding::ALL.get(id as usize).ok_or(unknown)?)
                } else {
                    BlockParams::Metadata(match id {
                        0 => MetadataEncoding::Ini,
                        1 => MetadataEncoding::Json,
                        _ => return Err(unknown),
                    })
                }
            }
        };
        let stored = cur.take(stored_len as usize).unwrap_or_default();
        if checksum == ChecksumType::Crc32 {
            let computed = crc32fast::hash(&data[offset..cur.pos]);
            let stored_crc = cur.u32().unwrap_or(0);
            if computed != stored_crc {
                return Err(BgcodeError::CrcMismatch {
                    block,
                    offset,
                    stored: stored_crc,
                    computed,
                });
            }
        }
        let unpacked =
            decompress(stored, compression, uncompressed as usize).map_err(|reason| {
                BgcodeError::Decompression {
                    block,
                    offset,
                    reason,
                }
            })?;
        let payload = match params {
            BlockParams::GCode(GcodeEncoding::MeatPack | GcodeEncoding::MeatPackComments) => {
                meatpack::decode(&unpacked)
            }
            _ => unpacked,
        };
        debug_assert!(kind.is_metadata() == matches!(params, BlockParams::Metadata(_)));
        blocks.push(Block {
            kind,
            compression,
            params,
            stored: Some(Stored {
                data: stored.to_vec(),
                compression,
                params,
                uncompressed_len: uncompressed as usize,
                payload_len: payload.len(),
                payload_crc: crc32fast::hash(&payload),
            }),
            payload,
        });
    }
    Ok(Bgcode {
        version,
        checksum,
        blocks,
    })
}

/// Writes `b` as a `.bgcode` file: unchanged blocks as they were read, others encoded afresh
/// with their own compression and encoding; CRCs recomputed when the file has them.
pub fn encode(b: &Bgcode) -> Vec<u8> {
    let mut out = Vec::with_capacity(
        FILE_HEADER_LEN
            + b.blocks
                .iter()
                .map(|bl| bl.payload.len() / 2 + 20)
                .sum::<usize>(),
    );
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&b.version.to_le_bytes());
    out.extend_from_slice(&b.checksum.id().to_le_bytes());
    for block in &b.blocks {
        block.write(b.checksum, &mut out);
    }
    out
}

/// Cuts G-code text into block-sized pieces at line ends, as libbgcode's `Binarizer` does: a
/// line goes to the next block when it would push this one past [`MAX_GCODE_BLOCK_TEXT`].
fn split_gcode(text: &[u8]) -> Vec<Vec<u8>> {
    let mut pieces = Vec::new();
    let mut cache: Vec<u8> = Vec::new();
    for line in text.split_inclusive(|&c| c == b'\n') {
        if line.len() + cache.len() > MAX_GCODE_BLOCK_TEXT && !cache.is_empty() {
            pieces.push(std::mem::take(&mut cache));
        }
        cache.extend_from_slice(line);
        // libbgcode only takes whole lines; the last one may lack its newline here.
        if cache.last() != Some(&b'\n') {
            cache.push(b'\n');
        }
    }
    if !cache.is_empty() {
        pieces.push(cache);
    }
    pieces
}

/// `b` with its G-code blocks replaced by `new_gcode`, cut into blocks of at most
/// [`MAX_GCODE_BLOCK_TEXT`] bytes of text (longer lines get a block of their own). The new blocks
/// take the place, compression and encoding of the first old G-code block (Heatshrink 12/4 and
/// MeatPack with comments, as PrusaSlicer writes, when there was none); other blocks are kept.
pub fn with_gcode(b: &Bgcode, new_gcode: &[u8]) -> Bgcode {
    let first = b.blocks.iter().position(|bl| bl.kind == BlockKind::GCode);
    let (compression, params) = first.map_or(
        (
            Compression::Heatshrink12_4,
            BlockParams::GCode(GcodeEncoding::MeatPackComments),
        ),
        |i| (b.blocks[i].compression, b.blocks[i].params),
    );
    let new_blocks = split_gcode(new_gcode)
        .into_iter()
        .map(|text| Block::new(BlockKind::GCode, compression, params, text));
    let at = first.unwrap_or(b.blocks.len());
    let mut blocks: Vec<Block> = Vec::with_capacity(b.blocks.len() + 4);
    blocks.extend(
        b.blocks[..at]
            .iter()
            .filter(|bl| bl.kind != BlockKind::GCode)
            .cloned(),
    );
    blocks.extend(new_blocks);
    blocks.extend(
        b.blocks[at..]
            .iter()
            .filter(|bl| bl.kind != BlockKind::GCode)
            .cloned(),
    );
    Bgcode {
        version: b.version,
        checksum: b.checksum,
        blocks,
    }
}

fn trim(s: &[u8]) -> &[u8] {
    let is_ws = |c: &u8| *c == b' ' || *c == b'\t';
    let start = s.iter().position(|c| !is_ws(c)).unwrap_or(s.len());
    let end = s.iter().rposition(|c| !is_ws(c)).map_or(start, |e| e + 1);
    &s[start..end.max(start)]
}

/// libbgcode's test for a line worth writing: something left after trimming and dropping a
/// leading ';'.
fn is_blank_or_empty_comment(line: &[u8]) -> bool {
    let t = trim(line);
    match t.strip_prefix(b";") {
        Some(rest) => trim(rest).is_empty(),
        None => t.is_empty(),
    }
}

fn base64(data: &[u8]) -> Vec<u8> {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = Vec::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = ((b[0] as u32) << 16) | ((b[1] as u32) << 8) | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize]);
            } else {
                out.push(b'=');
            }
        }
    }
    out
}

impl Bgcode {
    fn first(&self, kind: BlockKind) -> Option<&Block> {
        self.blocks.iter().find(|b| b.kind == kind)
    }

    fn blocks_of(&self, kind: BlockKind) -> impl Iterator<Item = &Block> {
        self.blocks.iter().filter(move |b| b.kind == kind)
    }

    /// The G-code blocks' text, concatenated, as libbgcode's text conversion writes it: lines
    /// that are blank or only ';' are dropped, every line ends in `\n`.
    pub fn gcode_text(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for block in self.blocks_of(BlockKind::GCode) {
            write_gcode_lines(&block.payload, &mut out);
        }
        out
    }

    /// The whole file as text G-code, byte for byte what libbgcode's `from_binary_to_ascii`
    /// writes: "; generated by" line, printer metadata, thumbnails in base64, G-code, print
    /// metadata, then the slicer configuration block.
    pub fn to_ascii(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.ascii_head(&mut out);
        out.extend_from_slice(&self.gcode_text());
        self.ascii_tail(&mut out);
        out
    }

    /// What [`Bgcode::to_ascii`] writes before the G-code text: "; generated by" line, printer
    /// metadata, thumbnails in base64 and the blank line after them. Only blocks that are not
    /// G-code are read, so a [`stream::Layout`]'s `other` gives the same head as the whole file.
    fn ascii_head(&self, out: &mut Vec<u8>) {
        if let Some(file_meta) = self.first(BlockKind::FileMetadata) {
            let meta = file_meta.metadata();
            let get = |key: &[u8]| meta.iter().find(|(k, _)| *k == key).map(|(_, v)| *v);
            out.extend_from_slice(b"; generated by ");
            out.extend_from_slice(get(b"Producer").unwrap_or(b"Unknown"));
            if let Some(on) = get(b"Produced on") {
                out.extend_from_slice(b" on ");
                out.extend_from_slice(on);
            }
            if let Some(by) = get(b"Prepared by") {
                out.extend_from_slice(b"\n; prepared by ");
                out.extend_from_slice(by);
            }
            out.extend_from_slice(b"\n\n\n");
        }
        if let Some(printer) = self.first(BlockKind::PrinterMetadata) {
            out.extend_from_slice(&printer.metadata_as_comments());
        }
        for thumb in self.blocks_of(BlockKind::Thumbnail) {
            let BlockParams::Thumbnail {
                format,
                width,
                height,
            } = thumb.params
            else {
                continue;
            };
            let tag: &[u8] = match format {
                ThumbnailFormat::Png => b"thumbnail",
                ThumbnailFormat::Jpg => b"thumbnail_JPG",
                ThumbnailFormat::Qoi => b"thumbnail_QOI",
            };
            let encoded = base64(&thumb.payload);
            out.extend_from_slice(b"\n;\n; ");
            out.extend_from_slice(tag);
            out.extend_from_slice(
                format!(" begin {width}x{height} {}\n", encoded.len()).as_bytes(),
            );
            for row in encoded.chunks(78) {
                out.extend_from_slice(b"; ");
                out.extend_from_slice(row);
                out.push(b'\n');
            }
            out.extend_from_slice(b"; ");
            out.extend_from_slice(tag);
            out.extend_from_slice(b" end\n;\n");
        }
        out.push(b'\n');
    }

    /// What [`Bgcode::to_ascii`] writes after the G-code text: a blank line, print metadata,
    /// then the slicer configuration (JSON, then INI). Like [`Bgcode::ascii_head`], it reads
    /// no G-code block.
    fn ascii_tail(&self, out: &mut Vec<u8>) {
        out.push(b'\n');
        if let Some(print) = self.first(BlockKind::PrintMetadata) {
            out.extend_from_slice(&print.metadata_as_comments());
        }
        let slicer: Vec<&Block> = self.blocks_of(BlockKind::SlicerMetadata).collect();
        let is_json = |b: &&Block| b.params == BlockParams::Metadata(MetadataEncoding::Json);
        if let Some(json) = slicer.iter().find(|b| is_json(b)) {
            out.extend_from_slice(b"\n; prusaslicer_json_config = begin\n; ");
            out.extend_from_slice(&json.payload);
            out.extend_from_slice(b"\n; prusaslicer_json_config = end\n");
        }
        if let Some(ini) = slicer.iter().find(|b| !is_json(b)) {
            out.extend_from_slice(b"\n; prusaslicer_config = begin\n");
            out.extend_from_slice(&ini.metadata_as_comments());
            out.extend_from_slice(b"; prusaslicer_config = end\n\n");
        }
    }
}

fn write_gcode_lines(text: &[u8], out: &mut Vec<u8>) {
    let mut lines = text.split(|&c| c == b'\n');
    // A text ending in '\n' leaves an empty last piece that libbgcode never visits.
    if text.last() == Some(&b'\n') || text.is_empty() {
        lines.next_back();
    }
    for line in lines {
        if !is_blank_or_empty_comment(line) {
            out.extend_from_slice(line);
            out.push(b'\n');
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Heatshrink encoder must give the C library's bytes; PrusaSlicer's own G-code blocks
    /// are the evidence: every one, decompressed and compressed again, is unchanged.
    #[test]
    fn heatshrink_reproduces_prusaslicers_blocks() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/reference/bgcode-samples");
        if !dir.is_dir() {
            // Past the test harness's capture, so the skip shows.
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "note: heatshrink_reproduces_prusaslicers_blocks skipped: it reads libbgcode's samples from ../shared, which is absent"
            );
            return;
        }
        let mut checked = 0;
        for name in ["mini_cube_b.bgcode", "mini_cube_ps2.8.1.bgcode"] {
            let data = std::fs::read(dir.join(name)).expect("sample");
            let b = decode(&data).expect("decodes");
            for block in &b.blocks {
                let (Some(stored), Some(p)) = (&block.stored, block.compression.heatshrink())
                else {
                    continue;
                };
                let raw = heatshrink::decompress(&stored.data, p, stored.uncompressed_len)
                    .expect("decompresses");
                assert!(heatshrink::compress(&raw, p) == stored.data, "{name}");
                checked += 1;
            }
        }
        assert_eq!(checked, 11);
    }
}
