//! The stable runner's mutator: byte edits for any input, and for text
//! the edits a hand makes (a character, a line dropped, doubled or
//! swapped, a number replaced by NaN, an infinity, 1e308 or a negative).

use crate::Target;

/// xorshift64*: a fixed sequence from a seed, so every input replays.
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn bits(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform below `n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.bits() % n.max(1) as u64) as usize
    }
}

/// Numbers a reader must refuse or hold.
const NUMBERS: [&str; 12] =
    ["nan", "inf", "-inf", "1e308", "-1e308", "-1", "0", "1e-320", "99999999999", "", "1e999", "18446744073709551616"];

/// Characters that change a text's structure.
const PUNCTUATION: &[u8] = b"=[]{}\",.-09eE#x \t\n<>/";

/// One to four stacked edits of `input`; `others` are spliced from. Text
/// gets line edits as well as byte edits, and a binary glTF's JSON chunk
/// gets them with the chunk's length kept right.
pub fn mutate(target: Target, input: &[u8], others: &[&[u8]], rng: &mut Rng) -> Vec<u8> {
    let mut out = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        out = match (target.is_text(), glb_json(&out)) {
            (true, _) if rng.below(2) == 0 => edit_text(&out, rng),
            (_, Some((json, rest))) if rng.below(2) == 0 => glb(&edit_text(json, rng), rest),
            _ => edit_bytes(&out, others, rng),
        };
    }
    out
}

/// A binary glTF's JSON chunk and what follows it.
fn glb_json(bytes: &[u8]) -> Option<(&[u8], &[u8])> {
    let word = |at: usize| Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?) as usize);
    if bytes.get(..4) != Some(b"glTF") || bytes.get(16..20) != Some(b"JSON") {
        return None;
    }
    let end = 20usize.checked_add(word(12)?)?;
    Some((bytes.get(20..end)?, &bytes[end..]))
}

/// A binary glTF of a JSON chunk (padded to four bytes) and the rest.
fn glb(json: &[u8], rest: &[u8]) -> Vec<u8> {
    let mut json = json.to_vec();
    json.resize(json.len().next_multiple_of(4), b' ');
    let total = (20 + json.len() + rest.len()) as u32;
    let mut out = [&b"glTF"[..], &2u32.to_le_bytes(), &total.to_le_bytes()].concat();
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.extend(rest);
    out
}

fn edit_bytes(input: &[u8], others: &[&[u8]], rng: &mut Rng) -> Vec<u8> {
    let mut out = input.to_vec();
    let n = out.len();
    match rng.below(7) {
        0 if n > 0 => out[rng.below(n)] ^= 1 << rng.below(8),
        1 if n > 0 => out[rng.below(n)] = rng.bits() as u8,
        2 => {
            let at = rng.below(n + 1);
            let new: Vec<u8> = (0..1 + rng.below(8)).map(|_| rng.bits() as u8).collect();
            out.splice(at..at, new);
        }
        3 if n > 0 => {
            let at = rng.below(n);
            let end = (at + 1 + rng.below(32)).min(n);
            out.drain(at..end);
        }
        4 if n > 0 => {
            let at = rng.below(n);
            let end = (at + 1 + rng.below(64)).min(n);
            let copy = out[at..end].to_vec();
            let to = rng.below(n + 1);
            out.splice(to..to, copy);
        }
        5 if !others.is_empty() => {
            // The head of this input, the tail of another.
            let other = others[rng.below(others.len())];
            out.truncate(rng.below(n + 1));
            out.extend_from_slice(&other[rng.below(other.len() + 1)..]);
        }
        _ => out.truncate(rng.below(n + 1)),
    }
    out
}

fn edit_text(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    let text = String::from_utf8_lossy(input);
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if lines.is_empty() {
        return input.to_vec();
    }
    let k = rng.below(lines.len());
    match rng.below(5) {
        0 => {
            let chars: Vec<char> = lines[k].chars().collect();
            if !chars.is_empty() {
                let at = rng.below(chars.len());
                let new = PUNCTUATION[rng.below(PUNCTUATION.len())] as char;
                lines[k] = chars[..at].iter().chain(std::iter::once(&new)).chain(&chars[at + 1..]).collect();
            }
        }
        1 => {
            lines.remove(k);
        }
        2 => {
            let copy = lines[k].clone();
            lines.insert(k, copy);
        }
        3 => {
            // A number-like token of the line, replaced.
            let line = &lines[k];
            let starts: Vec<usize> = line.char_indices().filter(|(_, c)| c.is_ascii_digit()).map(|(i, _)| i).collect();
            if !starts.is_empty() {
                let start = starts[rng.below(starts.len())];
                let end = line[start..]
                    .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
                    .map_or(line.len(), |e| start + e);
                lines[k] = format!("{}{}{}", &line[..start], NUMBERS[rng.below(NUMBERS.len())], &line[end..]);
            }
        }
        _ => {
            let j = rng.below(lines.len());
            lines.swap(k, j);
        }
    }
    lines.join("\n").into_bytes()
}
