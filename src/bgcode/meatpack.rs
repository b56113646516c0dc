//! MeatPack as libbgcode applies it to G-code blocks (encodings 1 and 2).
//!
//! Input of `encode`: G-code text whose lines all end in `\n`. Output: MeatPack bytes, in the
//! "no spaces" mode libbgcode always uses (the 4-bit code of ' ' stands for 'E'). `decode` is the
//! inverse as libbgcode writes it, including its repairs: it puts a space back before each
//! parameter letter of a `G` line and folds runs of newlines into one.
//!
//! Invariant: `encode` is libbgcode's binarizer, quirks included, because the point is to
//! write what PrusaSlicer writes. It is lossy: inline comments and blank lines are dropped,
//! spaces of `G` lines removed, `e`/`x`/`g` upper-cased there; with `keep_comments` false,
//! comment lines go too. Lines starting with ';' are stored raw, packing switched off around
//! them.

const SIGNAL: u8 = 0xFF;
const CMD_ENABLE_PACKING: u8 = 251;
const CMD_DISABLE_PACKING: u8 = 250;
const CMD_RESET_ALL: u8 = 249;
const CMD_ENABLE_NO_SPACES: u8 = 247;
const CMD_DISABLE_NO_SPACES: u8 = 246;
const BOTH_UNPACKABLE: u8 = 0xFF;
/// The 4-bit code that marks "the next full byte is this character".
const FULL: u8 = 0xF;

/// 4-bit code of a character in no-spaces mode, where ' ' is not packable and 'E' takes its code.
fn code(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'.' => Some(0b1010),
        b'E' => Some(0b1011),
        b'\n' => Some(0b1100),
        b'G' => Some(0b1101),
        b'X' => Some(0b1110),
        _ => None,
    }
}

fn append_command(cmd: u8, dst: &mut Vec<u8>) {
    dst.extend_from_slice(&[SIGNAL, SIGNAL, cmd]);
}

fn trim(s: &[u8]) -> &[u8] {
    let is_ws = |c: &u8| *c == b' ' || *c == b'\t';
    let start = s.iter().position(|c| !is_ws(c)).unwrap_or(s.len());
    let end = s.iter().rposition(|c| !is_ws(c)).map_or(start, |e| e + 1);
    &s[start..end.max(start)]
}

/// libbgcode's normalisation of a line holding `G<digit>`: spaces out, some letters upper-cased,
/// a `*` checksum recomputed, and a newline appended even when the line still has its own (it
/// has one unless an inline comment was cut off; the decoder folds the doubled newline).
fn unify(line: &[u8]) -> Vec<u8> {
    let Some(g) = line.iter().position(|&c| c == b'G') else {
        return line.to_vec();
    };
    if !line.get(g + 1).is_some_and(u8::is_ascii_digit) {
        return line.to_vec();
    }
    let mut result: Vec<u8> = line
        .iter()
        .filter(|&&c| c != b' ')
        .map(|&c| match c {
            b'e' => b'E',
            b'x' => b'X',
            b'g' => b'G',
            c => c,
        })
        .collect();
    if result.contains(&b'*') {
        result.retain(|&c| c != b'*');
        let checksum = result.iter().fold(0u8, |acc, &c| acc ^ c);
        result.push(b'*');
        result.extend_from_slice(checksum.to_string().as_bytes());
    }
    result.push(b'\n');
    result
}

/// One block's encoder; a fresh one per block, as libbgcode does.
struct Encoder {
    keep_comments: bool,
    packing: bool,
}

impl Encoder {
    fn line(&mut self, line: &[u8], dst: &mut Vec<u8>) {
        if line.is_empty() {
            return;
        }
        if self.keep_comments && line[0] == b';' {
            if self.packing {
                append_command(CMD_DISABLE_PACKING, dst);
                self.packing = false;
            }
            dst.extend_from_slice(line);
            return;
        }
        if line[0] == b';' || line[0] == b'\n' || line[0] == b'\r' || line.len() < 2 {
            return;
        }
        let code_part = match line.iter().position(|&c| c == b';') {
            Some(p) => &line[..p],
            None => line,
        };
        let trimmed = trim(code_part);
        if trimmed.is_empty() {
            return;
        }
        let mut modified = unify(trimmed);
        if modified.last() != Some(&b'\n') {
            modified.push(b'\n');
        }
        let mut packed = Vec::with_capacity(modified.len());
        for pair in modified.chunks(2) {
            let c1 = pair[0];
            // An odd line ends in "\n\n": the decoder drops what follows a packed newline.
            let c2 = pair.get(1).copied().unwrap_or(b'\n');
            match (code(c1), code(c2)) {
                (Some(a), Some(b)) => packed.push((b << 4) | a),
                (Some(a), None) => packed.extend_from_slice(&[(FULL << 4) | a, c2]),
                (None, Some(b)) => packed.extend_from_slice(&[(b << 4) | FULL, c1]),
                (None, None) => packed.extend_from_slice(&[BOTH_UNPACKABLE, c1, c2]),
            }
        }
        if !self.packing && !packed.is_empty() {
            append_command(CMD_ENABLE_PACKING, dst);
            self.packing = true;
        }
        dst.extend_from_slice(&packed);
    }
}

/// Encodes one block's text; `keep_comments` is encoding 2, otherwise encoding 1.
pub(crate) fn encode(text: &[u8], keep_comments: bool) -> Vec<u8> {
    let mut dst = Vec::with_capacity(text.len() / 2 + 8);
    append_command(CMD_ENABLE_PACKING, &mut dst);
    append_command(CMD_ENABLE_NO_SPACES, &mut dst);
    let mut enc = Encoder {
        keep_comments,
        packing: true,
    };
    for line in text.split_inclusive(|&c| c == b'\n') {
        enc.line(line, &mut dst);
    }
    if !keep_comments {
        append_command(CMD_RESET_ALL, &mut dst);
    }
    dst
}

fn decode_code(c: u8, no_spaces: bool) -> u8 {
    match c {
        0..=9 => b'0' + c,
        0b1010 => b'.',
        0b1011 if no_spaces => b'E',
        0b1011 => b' ',
        0b1100 => b'\n',
        0b1101 => b'G',
        0b1110 => b'X',
        _ => 0,
    }
}

/// Letters before which the decoder puts back the space the encoder removed from `G` lines.
fn is_g_parameter(c: u8) -> bool {
    matches!(
        c,
        b'X' | b'Y'
            | b'Z'
            | b'E'
            | b'F'
            | b'I'
            | b'J'
            | b'R'
            | b'G'
            | b'P'
            | b'W'
            | b'H'
            | b'C'
            | b'A'
    )
}

/// Decodes one block's MeatPack bytes to text, as libbgcode's reader does.
///
/// Long by design: the MeatPack decoder's state machine (signals, packed pairs, full-width escapes), kept as one loop like the reference implementation.
pub(crate) fn decode(src: &[u8]) -> Vec<u8> {
    let mut unpacking = false;
    let mut no_spaces = false;
    let mut cmd_active = false;
    let mut cmd_count = 0usize;
    // A packed character waiting for the full character that precedes it in the text.
    let mut char_buf = 0u8;
    let mut full_char_queue = 0usize;

    let mut out: Vec<u8> = Vec::with_capacity(src.len() * 2);
    let mut add_space = false;
    let mut emit = |c: u8, out: &mut Vec<u8>| {
        let mut new_line = false;
        if c == b'G' && out.last().is_none_or(|&p| p == b'\n') {
            add_space = true;
            new_line = true;
        } else if c == b'\n' {
            add_space = false;
        }
        if !new_line && add_space && out.last() != Some(&b' ') && is_g_parameter(c) {
            out.push(b' ');
        }
        if c != b'\n' || out.last() != Some(&b'\n') {
            out.push(c);
        }
    };

    let mut rx = |c: u8, out: &mut Vec<u8>, unpacking: bool, no_spaces: bool| {
        if !unpacking {
            emit(c, out);
            return;
        }
        if full_char_queue > 0 {
            emit(c, out);
            if char_buf > 0 {
                emit(char_buf, out);
                char_buf = 0;
            }
            full_char_queue -= 1;
            return;
        }
        let low = c & 0xF;
        let high = c >> 4;
        if low == FULL {
            full_char_queue += 1;
            if high == FULL {
                full_char_queue += 1;
            } else {
                char_buf = decode_code(high, no_spaces);
            }
        } else {
            let first = decode_code(low, no_spaces);
            emit(first, out);
            if first != b'\n' {
                if high == FULL {
                    full_char_queue += 1;
                } else {
                    emit(decode_code(high, no_spaces), out);
                }
            }
        }
    };

    for &b in src {
        if b == SIGNAL {
            if cmd_count > 0 {
                cmd_active = true;
                cmd_count = 0;
            } else {
                cmd_count += 1;
            }
        } else if cmd_active {
            match b {
                CMD_ENABLE_PACKING => unpacking = true,
                CMD_DISABLE_PACKING | CMD_RESET_ALL => unpacking = false,
                CMD_ENABLE_NO_SPACES => no_spaces = true,
                CMD_DISABLE_NO_SPACES => no_spaces = false,
                _ => {}
            }
            cmd_active = false;
        } else {
            if cmd_count > 0 {
                rx(SIGNAL, &mut out, unpacking, no_spaces);
                cmd_count = 0;
            }
            rx(b, &mut out, unpacking, no_spaces);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn g_lines_lose_spaces_and_get_them_back() {
        let text = b"G1 X10.5 Y20 E.3 F1200\nM104 S215\n;LAYER_CHANGE\nG4 S0\n";
        let packed = encode(text, true);
        assert_eq!(
            decode(&packed),
            b"G1 X10.5 Y20 E.3 F1200\nM104 S215\n;LAYER_CHANGE\nG4S0\n".to_vec()
        );
    }

    #[test]
    fn inline_comments_and_blank_lines_are_dropped() {
        let packed = encode(b"G1 X1 ; move\n\nM107\n; kept\n", true);
        assert_eq!(decode(&packed), b"G1 X1\nM107\n; kept\n".to_vec());
        let packed = encode(b"G1 X1 ; move\n\nM107\n; kept\n", false);
        assert_eq!(decode(&packed), b"G1 X1\nM107\n".to_vec());
    }
}
