//! Heatshrink (LZSS) as bgcode uses it: window of 2^W bytes, back-references of up to 2^L bytes.
//!
//! Input: a byte slice and the (W, L) pair of the block's compression id (11/4 or 12/4).
//! Output: the MSB-first bit stream of the reference C library (heatshrink 0.4, indexed search):
//! tag bit 1 + 8-bit literal, or tag bit 0 + (distance - 1) in W bits + (length - 1) in L bits,
//! the last byte padded with zero bits.
//!
//! Invariant: `compress` makes the same choices as the C encoder, so its output is identical
//! byte for byte: greedy parsing, the longest match within the last 2^W bytes, the nearest one
//! among equally long matches, and only matches longer than (1 + W + L) / 8 bytes. The window
//! starts out as 2^W zero bytes, on both sides, so a back-reference may reach before the start.

/// Bits of the window and of the length field, as named by the compression id.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Params {
    pub window_bits: u8,
    pub lookahead_bits: u8,
}

const HASH_BITS: u32 = 16;

fn hash3(b: &[u8]) -> usize {
    let v = (b[0] as u32) | ((b[1] as u32) << 8) | ((b[2] as u32) << 16);
    (v.wrapping_mul(0x9E37_79B1) >> (32 - HASH_BITS)) as usize
}

struct BitWriter {
    out: Vec<u8>,
    current: u8,
    used: u8,
}

impl BitWriter {
    fn push(&mut self, count: u8, bits: u32) {
        for i in (0..count).rev() {
            if (bits >> i) & 1 == 1 {
                self.current |= 0x80 >> self.used;
            }
            self.used += 1;
            if self.used == 8 {
                self.out.push(self.current);
                self.current = 0;
                self.used = 0;
            }
        }
    }

    fn finish(mut self) -> Vec<u8> {
        if self.used > 0 {
            self.out.push(self.current);
        }
        self.out
    }
}

pub(crate) fn compress(data: &[u8], p: Params) -> Vec<u8> {
    let window = 1usize << p.window_bits;
    let max_len = 1usize << p.lookahead_bits;
    // The C encoder keeps a match only if it saves bits: length > break-even / 8.
    let min_len = (1 + p.window_bits as usize + p.lookahead_bits as usize) / 8 + 1;
    debug_assert!(min_len >= 3, "hash chains key on 3 bytes");

    // The zero prefix stands for the encoder's zeroed backlog, which it also searches.
    let mut buf = vec![0u8; window];
    buf.extend_from_slice(data);
    let n = buf.len();

    let mut head = vec![usize::MAX; 1 << HASH_BITS];
    let mut prev = vec![usize::MAX; n];
    let insert = |pos: usize, head: &mut Vec<usize>, prev: &mut Vec<usize>| {
        if pos + 3 <= n {
            let h = hash3(&buf[pos..]);
            prev[pos] = head[h];
            head[h] = pos;
        }
    };
    for pos in 0..window {
        insert(pos, &mut head, &mut prev);
    }

    let mut w = BitWriter {
        out: Vec::with_capacity(data.len() / 2 + 8),
        current: 0,
        used: 0,
    };
    let mut i = window;
    while i < n {
        let limit = max_len.min(n - i);
        let mut best_len = 0usize;
        let mut best_pos = 0usize;
        if limit >= min_len {
            let lowest = i - window;
            let mut cand = head[hash3(&buf[i..])];
            while cand != usize::MAX && cand >= lowest {
                // Only a candidate that also matches at best_len can beat the current best.
                if buf[cand + best_len] == buf[i + best_len] {
                    let len = (0..limit)
                        .find(|&k| buf[cand + k] != buf[i + k])
                        .unwrap_or(limit);
                    if len > best_len {
                        best_len = len;
                        best_pos = cand;
                        if len == limit {
                            break;
                        }
                    }
                }
                cand = prev[cand];
            }
        }
        if best_len >= min_len {
            w.push(1, 0);
            w.push(p.window_bits, (i - best_pos - 1) as u32);
            w.push(p.lookahead_bits, (best_len - 1) as u32);
            for pos in i..i + best_len {
                insert(pos, &mut head, &mut prev);
            }
            i += best_len;
        } else {
            w.push(1, 1);
            w.push(8, buf[i] as u32);
            insert(i, &mut head, &mut prev);
            i += 1;
        }
    }
    w.finish()
}

/// Why a heatshrink stream could not be expanded to the size its block header states.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum DecompressError {
    TooLong,
    TooShort(usize),
}

pub(crate) fn decompress(
    data: &[u8],
    p: Params,
    expected: usize,
) -> Result<Vec<u8>, DecompressError> {
    let total_bits = data.len() * 8;
    let mut bit = 0usize;
    let read = |bit: &mut usize, count: u8| -> Option<u32> {
        if *bit + count as usize > total_bits {
            return None;
        }
        let mut v = 0u32;
        for _ in 0..count {
            let b = (data[*bit / 8] >> (7 - (*bit % 8))) & 1;
            v = (v << 1) | b as u32;
            *bit += 1;
        }
        Some(v)
    };
    // A corrupt header may claim gigabytes; grow with the output instead of trusting it.
    let mut out: Vec<u8> = Vec::with_capacity(expected.min(data.len() * 8 + 64));
    while let Some(tag) = read(&mut bit, 1) {
        if tag == 1 {
            let Some(lit) = read(&mut bit, 8) else { break };
            out.push(lit as u8);
        } else {
            let Some(index) = read(&mut bit, p.window_bits) else {
                break;
            };
            let Some(count) = read(&mut bit, p.lookahead_bits) else {
                break;
            };
            let dist = index as usize + 1;
            for _ in 0..=count {
                let b = if out.len() >= dist {
                    out[out.len() - dist]
                } else {
                    0
                };
                out.push(b);
            }
        }
        if out.len() > expected {
            return Err(DecompressError::TooLong);
        }
    }
    if out.len() != expected {
        return Err(DecompressError::TooShort(out.len()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const P12: Params = Params {
        window_bits: 12,
        lookahead_bits: 4,
    };
    const P11: Params = Params {
        window_bits: 11,
        lookahead_bits: 4,
    };

    #[test]
    fn round_trips() {
        let samples: [&[u8]; 5] = [
            b"",
            b"a",
            b"G1 X10 Y10\nG1 X10 Y10\nG1 X10 Y10\n",
            &[0u8; 100],
            &[7u8; 5000],
        ];
        for s in samples {
            for p in [P11, P12] {
                let c = compress(s, p);
                assert_eq!(decompress(&c, p, s.len()).unwrap(), s);
            }
        }
    }

    #[test]
    fn zero_prefix_is_part_of_the_window() {
        // Leading zeros match the zeroed window: one back-reference, not 16 literals.
        let c = compress(&[0u8; 16], P12);
        assert_eq!(c.len(), 3);
    }
}
