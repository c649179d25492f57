//! The mutator: AFL's "havoc" stack of small edits (bit flips, interesting integers and
//! floats, block insertions, deletions and copies, crossover with another input), with
//! the target's dictionary and the values its code compared against spliced in, raw or
//! as decimal text for the text formats.

use super::coverage;

/// A small fast generator (xorshift64*): the search is reproducible from its seed.
pub struct Rng(u64);

impl Rng {
    /// A generator from `seed` (any value).
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// The next 64 random bits.
    pub fn bits(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// A number below `n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.bits() % n as u64) as usize
        }
    }

    /// True one time in `n`.
    pub fn one_in(&mut self, n: usize) -> bool {
        self.below(n) == 0
    }
}

const INTERESTING_8: [u8; 9] = [0, 1, 2, 16, 32, 64, 100, 127, 128];
const INTERESTING_32: [u32; 12] = [
    0xffff_ffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff,
    0x8000,
    0x7fff,
    256,
    1024,
    4096,
    65536,
    1 << 24,
    2_000_000_000,
];
const INTERESTING_F32: [f32; 10] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    -0.0,
    1e30,
    -1e30,
    1e-40,
    f32::MAX,
    65504.0,
    0.5,
];
const NUMBER_TEXT: [&str; 14] = [
    "0",
    "-1",
    "1",
    "-0",
    "nan",
    "inf",
    "-inf",
    "1e39",
    "1e-45",
    "4294967295",
    "4294967296",
    "2147483648",
    "18446744073709551616",
    "0.000001",
];

/// Mutates `data` in place with 1 to 16 stacked edits; `dictionary` holds the target's
/// tokens, `other` another input for crossover, `text` whether the format is text (numbers
/// are then also tried as decimal words).
pub fn havoc(
    rng: &mut Rng,
    data: &mut Vec<u8>,
    max_len: usize,
    dictionary: &[&[u8]],
    other: &[u8],
    text: bool,
) {
    let edits = 1 << rng.below(5);
    for _ in 0..edits {
        edit(rng, data, dictionary, other, text);
    }
    data.truncate(max_len);
}

fn edit(rng: &mut Rng, data: &mut Vec<u8>, dictionary: &[&[u8]], other: &[u8], text: bool) {
    let len = data.len();
    match rng.below(15) {
        0 if len > 0 => {
            let i = rng.below(len);
            data[i] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let i = rng.below(len);
            data[i] = rng.bits() as u8;
        }
        2 if len > 0 => {
            let i = rng.below(len);
            data[i] = INTERESTING_8[rng.below(INTERESTING_8.len())];
        }
        3 => {
            let v = INTERESTING_32[rng.below(INTERESTING_32.len())];
            let bytes = if rng.one_in(2) {
                v.to_le_bytes()
            } else {
                v.to_be_bytes()
            };
            let width = [1, 2, 4][rng.below(3)];
            put(rng, data, &bytes[..width]);
        }
        4 if len > 0 => {
            // Add or subtract a little to a byte or a little-endian u32.
            let delta = rng.below(35) as u32 + 1;
            let i = rng.below(len);
            if i + 4 <= len && rng.one_in(2) {
                let mut w = u32::from_le_bytes(data[i..i + 4].try_into().expect("4 bytes"));
                w = if rng.one_in(2) {
                    w.wrapping_add(delta)
                } else {
                    w.wrapping_sub(delta)
                };
                data[i..i + 4].copy_from_slice(&w.to_le_bytes());
            } else {
                data[i] = if rng.one_in(2) {
                    data[i].wrapping_add(delta as u8)
                } else {
                    data[i].wrapping_sub(delta as u8)
                };
            }
        }
        5 if len > 1 => {
            let n = 1 + rng.below(len.min(64));
            let at = rng.below(len - n + 1);
            data.drain(at..at + n);
        }
        6 => {
            // Insert a block: copied from the input itself, or one repeated byte.
            let n = 1 + rng.below(32);
            let block: Vec<u8> = if len > 0 && rng.one_in(2) {
                let from = rng.below(len);
                data[from..(from + n).min(len)].to_vec()
            } else {
                vec![rng.bits() as u8; n]
            };
            let at = rng.below(len + 1);
            data.splice(at..at, block);
        }
        7 if len > 1 => {
            let n = 1 + rng.below(len.min(32));
            let from = rng.below(len - n + 1);
            let to = rng.below(len - n + 1);
            data.copy_within(from..from + n, to);
        }
        8 | 9 if !dictionary.is_empty() => {
            let token = dictionary[rng.below(dictionary.len())];
            if rng.one_in(2) {
                let at = rng.below(len + 1);
                data.splice(at..at, token.iter().copied());
            } else {
                put(rng, data, token);
            }
        }
        10 => {
            if let Some((value, width)) = coverage::comparison_value(rng.bits() as usize) {
                if text && rng.one_in(2) {
                    put_text(rng, data, &value.to_string());
                } else {
                    let bytes = value.to_le_bytes();
                    put(rng, data, &bytes[..width.clamp(1, 8)]);
                }
            }
        }
        11 if !other.is_empty() => {
            // Crossover: our head, the other input's tail (or a block of it inserted).
            let cut = rng.below(len + 1);
            let from = rng.below(other.len());
            if rng.one_in(2) {
                data.truncate(cut);
                data.extend_from_slice(&other[from..]);
            } else {
                let n = 1 + rng.below((other.len() - from).min(64));
                data.splice(cut..cut, other[from..from + n].iter().copied());
            }
        }
        12 if text => {
            let word = NUMBER_TEXT[rng.below(NUMBER_TEXT.len())];
            put_text(rng, data, word);
        }
        13 => {
            let f = INTERESTING_F32[rng.below(INTERESTING_F32.len())];
            put(rng, data, &f.to_le_bytes());
        }
        _ if len > 0 => {
            // Truncate: shorter inputs reach the "too short" paths.
            data.truncate(rng.below(len));
        }
        _ => data.push(rng.bits() as u8),
    }
}

/// Overwrites (or, one time in four, inserts) `bytes` at a random place.
fn put(rng: &mut Rng, data: &mut Vec<u8>, bytes: &[u8]) {
    let len = data.len();
    if len < bytes.len() || rng.one_in(4) {
        let at = rng.below(len + 1);
        data.splice(at..at, bytes.iter().copied());
    } else {
        let at = rng.below(len - bytes.len() + 1);
        data[at..at + bytes.len()].copy_from_slice(bytes);
    }
}

/// Replaces a run of number characters (or, without one, inserts) with `word`.
fn put_text(rng: &mut Rng, data: &mut Vec<u8>, word: &str) {
    let is_number = |b: u8| b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'e' | b'+');
    let len = data.len();
    let start = rng.below(len + 1);
    let Some(begin) = (start..len).find(|&i| is_number(data[i])) else {
        data.splice(start..start, word.bytes());
        return;
    };
    let end = (begin..len).find(|&i| !is_number(data[i])).unwrap_or(len);
    data.splice(begin..end, word.bytes());
}
