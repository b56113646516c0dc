//! Stage 1: lossless G-code syntax.
//!
//! Input: a byte stream (any bytes, not necessarily UTF-8). Output: [`RawLine`]s, each holding
//! the exact bytes of one line including its terminator, and on demand a [`Parsed`] view of the
//! line's syntax (words, comment, `N` number, checksum, Klipper-style extended command).
//!
//! Invariants: concatenating the `raw` bytes of every line yields the input byte for byte
//! (CRLF, missing final newline, trailing blanks and invalid UTF-8 included). Parsing never
//! fails: anything the parser does not understand is kept as [`Command::Unknown`] text.
//! Nothing here knows what a command means; modal state belongs to [`crate::machine`].

use std::io::{self, BufRead};

use nom::IResult;
use smallvec::SmallVec;

/// One physical line of the file, exactly as read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawLine {
    /// 1-based line number in the file.
    pub number: u64,
    /// Every byte of the line, including `\n` / `\r\n` when present.
    pub raw: Vec<u8>,
}

impl RawLine {
    /// The line without its terminator.
    pub fn content(&self) -> &[u8] {
        strip_terminator(&self.raw)
    }

    pub fn parse(&self) -> Parsed<'_> {
        parse_line(self.content())
    }
}

/// The bytes of a line without a trailing `\n` or `\r\n`.
pub fn strip_terminator(raw: &[u8]) -> &[u8] {
    let mut s = raw;
    if let Some(rest) = s.strip_suffix(b"\n") {
        s = rest;
        if let Some(rest) = s.strip_suffix(b"\r") {
            s = rest;
        }
    }
    s
}

/// A letter and its number: `X10.5`, `E-.02`, `G1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Word {
    /// Upper-cased letter.
    pub letter: u8,
    pub value: f64,
}

/// What kind of statement a line holds.
#[derive(Debug, Clone, PartialEq)]
pub enum Command<'a> {
    /// Blank line or comment only.
    Empty,
    /// A classic command word (`G1`, `M104`, `T0`) with its parameters in [`Parsed::words`].
    Code { letter: u8, number: f64 },
    /// Klipper / RepRapFirmware extended command: `EXCLUDE_OBJECT_START NAME=part_1`.
    Extended { name: &'a [u8], params: &'a [u8] },
    /// Text that is not valid G-code syntax; kept verbatim.
    Unknown(&'a [u8]),
}

/// The syntax of one line. Borrows from the line's bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Parsed<'a> {
    /// `N` line number, when the line carries one.
    pub line_number: Option<i64>,
    pub command: Command<'a>,
    /// Parameter words after the command word, in file order. Inline storage: a line rarely
    /// has more than eight words, and this is the hottest allocation otherwise.
    pub words: SmallVec<[Word; 8]>,
    /// Comment text without its delimiters (`;` comment, or the last `( )` comment).
    pub comment: Option<&'a [u8]>,
    /// `*nn` checksum, when present.
    pub checksum: Option<u8>,
    /// Whether the checksum matches the Marlin XOR of the bytes before `*`.
    pub checksum_ok: Option<bool>,
}

impl<'a> Parsed<'a> {
    /// The value of a parameter word, if present.
    pub fn get(&self, letter: u8) -> Option<f64> {
        self.words
            .iter()
            .find(|w| w.letter == letter)
            .map(|w| w.value)
    }

    pub fn has(&self, letter: u8) -> bool {
        self.words.iter().any(|w| w.letter == letter)
    }

    /// `true` for `G<n>` exactly (e.g. `is_g(1.0)` for G1 / G01).
    pub fn is_code(&self, letter: u8, number: f64) -> bool {
        matches!(self.command, Command::Code { letter: l, number: n } if l == letter && n == number)
    }

    /// The comment as (lossy) text, trimmed.
    pub fn comment_str(&self) -> Option<std::borrow::Cow<'a, str>> {
        self.comment.map(|c| match String::from_utf8_lossy(c) {
            std::borrow::Cow::Borrowed(s) => std::borrow::Cow::Borrowed(s.trim()),
            std::borrow::Cow::Owned(s) => std::borrow::Cow::Owned(s.trim().to_string()),
        })
    }
}

/// Longest line poa reads. Slicers write lines of under a hundred bytes (thumbnails' base64 and
/// Klipper's object polygons stay far below this); a longer one is damaged or hostile input,
/// refused instead of held in memory.
pub const MAX_LINE: usize = 1 << 20;

/// The error for a line longer than [`MAX_LINE`].
pub fn line_too_long(line: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "line {line} is longer than {} MiB, which no slicer writes; the file is damaged",
            MAX_LINE >> 20
        ),
    )
}

/// Reads lines from any [`BufRead`] without losing a byte.
pub struct LineReader<R> {
    inner: R,
    next_number: u64,
}

impl<R: BufRead> LineReader<R> {
    pub fn new(inner: R) -> Self {
        LineReader {
            inner,
            next_number: 1,
        }
    }

    /// Reads the next line into `buf` (cleared first). Returns the line number, or `None` at
    /// end of input. Reusing one buffer keeps the hot loop free of allocations.
    pub fn read_into(&mut self, buf: &mut Vec<u8>) -> io::Result<Option<u64>> {
        buf.clear();
        let n = io::Read::take(&mut self.inner, MAX_LINE as u64 + 1).read_until(b'\n', buf)?;
        if n == 0 {
            return Ok(None);
        }
        if n > MAX_LINE {
            return Err(line_too_long(self.next_number));
        }
        let number = self.next_number;
        self.next_number += 1;
        Ok(Some(number))
    }
}

impl<R: BufRead> Iterator for LineReader<R> {
    type Item = io::Result<RawLine>;

    fn next(&mut self) -> Option<Self::Item> {
        let mut raw = Vec::new();
        match self.read_into(&mut raw) {
            Ok(Some(number)) => Some(Ok(RawLine { number, raw })),
            Ok(None) => None,
            Err(e) => Some(Err(e)),
        }
    }
}

/// Splits an in-memory buffer into lines (each slice keeps its terminator).
pub fn split_lines(data: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = data;
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let end = memchr_nl(rest).map(|i| i + 1).unwrap_or(rest.len());
        let (line, tail) = rest.split_at(end);
        rest = tail;
        Some(line)
    })
}

fn memchr_nl(s: &[u8]) -> Option<usize> {
    memchr::memchr(b'\n', s)
}

fn is_blank(b: u8) -> bool {
    b == b' ' || b == b'\t'
}

fn skip_blanks(s: &[u8]) -> &[u8] {
    let n = s.iter().take_while(|&&b| is_blank(b)).count();
    &s[n..]
}

/// A G-code number: optional sign, digits, optional fraction, optional lowercase exponent
/// (`10`, `-.5`, `+3.`, `1e3`); an uppercase `E` ends it (`60E9` is 60, then the word `E9`).
/// Plain decimals take an exact fast path; anything else goes through the standard parser.
pub fn number(input: &[u8]) -> IResult<&[u8], f64> {
    match scan_number(input) {
        Some((end, value)) => Ok((&input[end..], value)),
        None => Err(nom::Err::Error(nom::error::Error::new(
            input,
            nom::error::ErrorKind::Float,
        ))),
    }
}

/// [`number`]'s work: where the number ends in `input`, and its value. Inlined into the
/// tokenizer, it costs no call and no result in memory per word (a sixth of the parse).
#[inline(always)]
fn scan_number(input: &[u8]) -> Option<(usize, f64)> {
    let len = input.len();
    let mut i = 0;
    let negative = match input.first() {
        Some(b'-') => {
            i = 1;
            true
        }
        Some(b'+') => {
            i = 1;
            false
        }
        _ => false,
    };
    let int_start = i;
    let mut mantissa: u64 = 0;
    while i < len && input[i].is_ascii_digit() {
        mantissa = mantissa
            .wrapping_mul(10)
            .wrapping_add(u64::from(input[i] - b'0'));
        i += 1;
    }
    let int_digits = i - int_start;
    let mut frac_digits = 0;
    if i < len && input[i] == b'.' {
        i += 1;
        let frac_start = i;
        while i < len && input[i].is_ascii_digit() {
            mantissa = mantissa
                .wrapping_mul(10)
                .wrapping_add(u64::from(input[i] - b'0'));
            i += 1;
        }
        frac_digits = i - frac_start;
    }
    if int_digits + frac_digits == 0 {
        return None;
    }
    let mut end = i;
    let mut exact = int_digits + frac_digits <= 15;
    // `E` is a word's letter, never an exponent: files written without blanks
    // (`G1X60E9F1000`, as MeatPack sends them) are X 60 and E 9 to every firmware (Marlin
    // stops a number at `E`, Klipper and RepRapFirmware split words at letters), not X 60e9.
    // A lowercase `e` and digits is the exponent generators print (`E1e-05`: 0.00001).
    if i < len && input[i] == b'e' {
        let mut j = i + 1;
        if j < len && (input[j] == b'-' || input[j] == b'+') {
            j += 1;
        }
        let k = input[j..].iter().take_while(|b| b.is_ascii_digit()).count();
        if k > 0 {
            end = j + k;
            exact = false;
        }
    }
    let value = if exact {
        // With at most 15 digits both operands are exact in f64 (< 2^53), so the one division
        // is correctly rounded: the same value `str::parse` gives.
        // (Through i64, the same value under 2^53: one conversion instruction, where u64
        // takes a sequence of them on the baseline target.)
        let v = mantissa as i64 as f64 / POW10[frac_digits];
        if negative {
            -v
        } else {
            v
        }
    } else {
        std::str::from_utf8(&input[..end])
            .ok()
            .and_then(|s| s.parse::<f64>().ok())?
    };
    Some((end, value))
}

const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Whether `text` starts with a move command's word (G0-G3, G92) followed by a blank.
pub fn is_move_word(text: &[u8]) -> bool {
    match word(text) {
        Some((rest, w)) => {
            w.letter == b'G'
                && [0.0, 1.0, 2.0, 3.0, 92.0].contains(&w.value)
                && rest.first().is_some_and(|&b| is_blank(b))
        }
        None => false,
    }
}

/// A word at the start of `input` and what follows it.
#[inline(always)]
fn word(input: &[u8]) -> Option<(&[u8], Word)> {
    match input.first() {
        Some(&c) if c.is_ascii_alphabetic() => {
            // Blanks between letter and number are rare: a loop, not nom's `take_while`,
            // whose split is an out-of-line call for every word of every line (3 % of a
            // rewrite's time).
            let digits = skip_blanks(&input[1..]);
            let (end, value) = scan_number(digits)?;
            Some((
                &digits[end..],
                Word {
                    letter: c.to_ascii_uppercase(),
                    value,
                },
            ))
        }
        _ => None,
    }
}

/// Marlin's checksum: XOR of every byte before the `*`.
pub fn marlin_checksum(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |acc, b| acc ^ b)
}

/// Splits off the comment: `;` to end of line, or parenthesised comments anywhere. Returns the
/// code part (with parenthesised comments still inside it) and the comment text.
fn split_comment(content: &[u8]) -> (&[u8], Option<&[u8]>) {
    match memchr::memchr(b';', content) {
        Some(i) => (&content[..i], Some(&content[i + 1..])),
        None => (content, None),
    }
}

/// Parses one line's content (without terminator). Never fails.
///
/// Long by design: the hand-tuned tokenizer of the hot path (every byte of every file goes through it); splitting it costs speed measured in benchmarks.
pub fn parse_line(content: &[u8]) -> Parsed<'_> {
    let (code, mut comment) = split_comment(content);
    let mut parsed = Parsed {
        line_number: None,
        command: Command::Empty,
        words: SmallVec::new(),
        comment: None,
        checksum: None,
        checksum_ok: None,
    };

    // Checksum: `*nn` at the end of the code part.
    let mut code = code;
    // A checksum's `*` lies among the last four bytes before trailing blanks (`*` and one to
    // three digits): a `*` farther back leaves a longer tail, which is no checksum, so only
    // those bytes are searched (a search of the whole line cost every line a call).
    let trimmed = trim_end(code);
    let near_end = trimmed.len().saturating_sub(4);
    if let Some(star) = trimmed[near_end..]
        .iter()
        .rposition(|&b| b == b'*')
        .map(|i| near_end + i)
    {
        let tail = trim_end(&code[star + 1..]);
        if !tail.is_empty() && tail.len() <= 3 && tail.iter().all(|b| b.is_ascii_digit()) {
            if let Ok(v) = std::str::from_utf8(tail).unwrap_or("x").parse::<u16>() {
                if v <= 255 {
                    parsed.checksum = Some(v as u8);
                    parsed.checksum_ok = Some(marlin_checksum(&code[..star]) == v as u8);
                    code = &code[..star];
                }
            }
        }
    }

    let mut rest = skip_blanks(code);
    if rest.is_empty() {
        parsed.comment = comment;
        return parsed;
    }

    // `N123` line number.
    if matches!(rest.first(), Some(b'N' | b'n')) {
        if let Some((r, w)) = word(rest) {
            parsed.line_number = Some(w.value as i64);
            rest = skip_blanks(r);
        }
    }

    // Extended command: a name of two or more identifier characters starting with a letter,
    // e.g. `EXCLUDE_OBJECT_START`, `SET_PRESSURE_ADVANCE`, `M486`-style words excluded.
    let ident_len = rest
        .iter()
        .take_while(|b| b.is_ascii_alphanumeric() || **b == b'_')
        .count();
    if ident_len >= 2
        && rest[0].is_ascii_alphabetic()
        && !(rest[1].is_ascii_digit() || rest[1] == b'-' || rest[1] == b'.' || rest[1] == b'+')
    {
        let name = &rest[..ident_len];
        let params = trim_end(skip_blanks(&rest[ident_len..]));
        parsed.command = Command::Extended { name, params };
        parsed.comment = comment;
        return parsed;
    }

    let mut first = true;
    let body_start = rest;
    loop {
        rest = skip_blanks(rest);
        if rest.is_empty() {
            break;
        }
        if rest[0] == b'(' {
            // Parenthesised comment; an unbalanced one runs to the end of the line.
            match rest.iter().position(|&b| b == b')') {
                Some(close) => {
                    if comment.is_none() {
                        comment = Some(&rest[1..close]);
                    }
                    rest = &rest[close + 1..];
                }
                None => {
                    if comment.is_none() {
                        comment = Some(&rest[1..]);
                    }
                    rest = &[];
                }
            }
            continue;
        }
        match word(rest) {
            Some((r, w)) => {
                if first {
                    parsed.command = Command::Code {
                        letter: w.letter,
                        number: w.value,
                    };
                    first = false;
                } else {
                    parsed.words.push(w);
                }
                rest = r;
            }
            None => {
                // Not G-code syntax: keep the whole statement as text.
                parsed.command = Command::Unknown(trim_end(body_start));
                parsed.words.clear();
                break;
            }
        }
    }
    parsed.comment = comment;
    parsed
}

fn trim_end(s: &[u8]) -> &[u8] {
    let n = s.iter().rev().take_while(|&&b| is_blank(b)).count();
    &s[..s.len() - n]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(data: &[u8]) -> Vec<RawLine> {
        LineReader::new(data).map(|l| l.unwrap()).collect()
    }

    #[test]
    fn round_trip_keeps_every_byte() {
        let data: &[u8] = b"G1 X1\r\n; caf\xe9 \xff\n  \n\nG1 Y2 ; trailing  \t\nno newline";
        let got: Vec<u8> = lines(data).into_iter().flat_map(|l| l.raw).collect();
        assert_eq!(got, data);
        assert_eq!(lines(data).len(), 6);
        assert_eq!(lines(data)[5].number, 6);
    }

    #[test]
    fn parses_words_and_comment() {
        let p = parse_line(b"G1 X10.5 Y-3 E.02 F1800 ; perimeter");
        assert!(p.is_code(b'G', 1.0));
        assert_eq!(p.get(b'X'), Some(10.5));
        assert_eq!(p.get(b'Y'), Some(-3.0));
        assert_eq!(p.get(b'E'), Some(0.02));
        assert_eq!(p.get(b'F'), Some(1800.0));
        assert_eq!(p.comment_str().as_deref(), Some("perimeter"));
    }

    #[test]
    fn lowercase_spaces_and_leading_zeros() {
        let p = parse_line(b"g01 x 1.5 y2");
        assert!(p.is_code(b'G', 1.0));
        assert_eq!(p.get(b'X'), Some(1.5));
        assert_eq!(p.get(b'Y'), Some(2.0));
    }

    #[test]
    fn line_number_and_checksum() {
        let body = b"N12 G1 X1";
        let cs = marlin_checksum(body);
        let line = format!("N12 G1 X1*{cs}");
        let p = parse_line(line.as_bytes());
        assert_eq!(p.line_number, Some(12));
        assert_eq!(p.checksum, Some(cs));
        assert_eq!(p.checksum_ok, Some(true));
        assert_eq!(p.get(b'X'), Some(1.0));
        let bad = parse_line(b"N12 G1 X1*0");
        assert_eq!(bad.checksum_ok, Some(cs == 0));
        // Trailing blanks and a comment after the checksum; a `*` that is no checksum (four
        // digits, a word after it, a blank before its digits, two stars) stays in the code.
        let noted = format!("N12 G1 X1*{cs}  ; note");
        let p = parse_line(noted.as_bytes());
        assert_eq!((p.checksum, p.get(b'X')), (Some(cs), Some(1.0)));
        for text in ["G1 X1*1234", "G1 X1*2 Y3", "G1 X1* 12", "G1 X1*1*"] {
            let p = parse_line(text.as_bytes());
            assert_eq!(p.checksum, None, "{text}");
            assert!(matches!(p.command, Command::Unknown(_)), "{text}");
        }
        let p = parse_line(b"G1 X1**12");
        assert_eq!(p.checksum, Some(12));
        assert!(matches!(p.command, Command::Unknown(_)));
    }

    #[test]
    fn parenthesised_comments() {
        let p = parse_line(b"G1 (move) X2 (unbalanced");
        assert_eq!(p.get(b'X'), Some(2.0));
        assert_eq!(p.comment, Some(&b"move"[..]));
        let q = parse_line(b"(only comment");
        assert_eq!(q.command, Command::Empty);
        assert_eq!(q.comment, Some(&b"only comment"[..]));
    }

    #[test]
    fn extended_commands() {
        let p = parse_line(b"EXCLUDE_OBJECT_START NAME=part_1 ; c");
        assert_eq!(
            p.command,
            Command::Extended {
                name: b"EXCLUDE_OBJECT_START",
                params: b"NAME=part_1"
            }
        );
        let m = parse_line(b"M486 S1");
        assert!(m.is_code(b'M', 486.0));
        assert_eq!(m.get(b'S'), Some(1.0));
    }

    #[test]
    fn unknown_text_is_kept() {
        let p = parse_line(b"G1 X1 Y=3");
        assert_eq!(p.command, Command::Unknown(b"G1 X1 Y=3"));
        assert!(p.words.is_empty());
    }

    #[test]
    fn a_line_without_blanks_reads_as_firmware_reads_it() {
        let spaced = parse_line(b"G1 X60 E9 F1000");
        let packed = parse_line(b"G1X60E9F1000");
        assert_eq!(packed.command, spaced.command);
        assert_eq!(packed.words, spaced.words);
        let w: Vec<(u8, f64)> = packed.words.iter().map(|w| (w.letter, w.value)).collect();
        assert_eq!(w, [(b'X', 60.0), (b'E', 9.0), (b'F', 1000.0)]);
    }

    #[test]
    fn numbers() {
        for (s, v) in [
            ("1", 1.0),
            ("-.5", -0.5),
            ("+3.", 3.0),
            ("0.1", 0.1),
            ("123.456", 123.456),
            ("12345678901234567890.5", 12345678901234567890.5),
        ] {
            let (rest, got) = number(s.as_bytes()).unwrap();
            assert!(rest.is_empty(), "{s}");
            assert_eq!(got, v, "{s}");
        }
        assert_eq!(number(b"1e3").unwrap(), (&b""[..], 1000.0));
        // `E` ends a number, as firmware reads it: the next word's letter.
        assert_eq!(number(b"60E9").unwrap(), (&b"E9"[..], 60.0));
        assert!(number(b"-").is_err());
        assert!(number(b".").is_err());
        assert!(number(b"x").is_err());
    }

    #[test]
    fn fast_path_matches_std_parser() {
        for s in [
            "0.2",
            "10.200",
            "-0.04152",
            "219.789",
            "0.00001",
            "7.0000001",
        ] {
            let (_, got) = number(s.as_bytes()).unwrap();
            assert_eq!(got, s.parse::<f64>().unwrap(), "{s}");
        }
    }
}
