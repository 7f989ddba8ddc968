//! Object and entry names, and their packed form.
//!
//! SDO information must answer every object and entry name, so the names stay in
//! flash; most of them repeat a few words ("Mapping entry 7", "Fault 3 snapshot",
//! "Touch probe 1 positive edge"). [`pack_into`] stores a name with each word of
//! [`VOCABULARY`] replaced by one byte `0x80 + k` (bytes below 0x80 are the name's own
//! ASCII characters); [`Name`] reads either form back. A packed dictionary
//! ([`super::pack`]) keeps only the packed bytes: about 45 % of the plain text.
//!
//! Matching is on word boundaries only, so decoding is a plain concatenation: a word
//! of the vocabulary is used where the name has it at a word start and either the
//! vocabulary word ends with a space or the name ends with it.

use core::fmt;

/// The words replaced by one byte (at most 128, each at most 255 ASCII bytes). Chosen
/// by how many bytes they save in CoE / CiA 402 object names (the product dictionary
/// of this project is what they were measured on); a name with other words is packed
/// as far as it has these and keeps the rest as it is.
const VOCABULARY: [&str; 102] = [
    "Mapping entry ",
    "Fault ",
    "Position ",
    "communication ",
    "Standard error ",
    "Input ",
    "function",
    "Touch probe ",
    "option code",
    "mapping ",
    "Velocity ",
    "Following error ",
    "actual value",
    "time",
    "parameters",
    "Assigned PDO ",
    "Interpolation time ",
    "Current ",
    "snapshot",
    "filter",
    "current",
    "Command ",
    "velocity",
    "Restore ",
    "Number of ",
    "position limit",
    "RxPDO ",
    "field ",
    "acceleration",
    "deceleration",
    "type",
    "Encoder ",
    "Fault code ",
    "SYNC0 ",
    "TxPDO ",
    "Max ",
    "Output ",
    "value",
    "time ",
    "offset",
    "Motor ",
    "Phase ",
    "Profile ",
    "defaults",
    "since power-up",
    "during search ",
    "loop ",
    "Save ",
    "Sync ",
    "Homing ",
    "period ",
    "demand ",
    "negative edge",
    "positive edge",
    "application ",
    "error ",
    "Error ",
    "window",
    "cycle ",
    "period",
    "Speed ",
    "revolutions",
    "current set",
    "Quick stop ",
    "all ",
    "operation ",
    "resolution",
    "Calc and ",
    "Modes of ",
    "internal ",
    "parameter",
    "Software ",
    "Digital ",
    "profile ",
    "Minimum ",
    "filter ",
    "pulses ",
    "Device ",
    "outputs",
    "counts ",
    "version",
    "output ",
    "window ",
    "Target ",
    "Cycle ",
    "clear ",
    "assign",
    "number",
    "Shift ",
    "limit",
    "SM ",
    "copy ",
    "level",
    "error",
    "code",
    "mask",
    "high",
    "mode",
    "too ",
    "PDI ",
    "(E5)",
    "for ",
];

/// First byte value that stands for a vocabulary word.
const WORD: u8 = 0x80;

/// Bytes of `list` stored as length-prefixed texts ([`prefixed_list`]).
pub(crate) const fn prefixed_len(list: &[&str]) -> usize {
    let mut n = 0;
    let mut i = 0;
    while i < list.len() {
        assert!(
            list[i].len() <= 255,
            "od: text in a length-prefixed list over 255 bytes"
        );
        n += 1 + list[i].len();
        i += 1;
    }
    n
}

/// `list` as length-prefixed texts: one byte of length, then the bytes, for each.
pub(crate) const fn prefixed_list<const N: usize>(list: &[&str]) -> [u8; N] {
    let mut out = [0u8; N];
    let mut at = 0;
    let mut i = 0;
    while i < list.len() {
        let w = list[i].as_bytes();
        out[at] = w.len() as u8;
        let mut j = 0;
        while j < w.len() {
            out[at + 1 + j] = w[j];
            j += 1;
        }
        at += 1 + w.len();
        i += 1;
    }
    out
}

/// Text `k` of a [`prefixed_list`] (empty past its end).
pub(crate) fn prefixed(list: &'static [u8], k: u8) -> &'static [u8] {
    let mut at = 0usize;
    for _ in 0..k {
        match list.get(at) {
            Some(&len) => at += 1 + len as usize,
            None => return &[],
        }
    }
    let len = list.get(at).map_or(0, |&l| l as usize);
    list.get(at + 1..at + 1 + len).unwrap_or(&[])
}

const fn vocabulary_checked() -> usize {
    assert!(VOCABULARY.len() <= 128, "od name vocabulary over 128 words");
    let mut i = 0;
    while i < VOCABULARY.len() {
        let w = VOCABULARY[i].as_bytes();
        assert!(!w.is_empty(), "od vocabulary word empty");
        let mut j = 0;
        while j < w.len() {
            assert!(w[j] < WORD, "od vocabulary words are ASCII");
            j += 1;
        }
        i += 1;
    }
    prefixed_len(&VOCABULARY)
}

const WORDS_LEN: usize = vocabulary_checked();

/// The vocabulary as length-prefixed words: what decoding reads (the `&str` table
/// itself is only used at compile time).
static WORDS: [u8; WORDS_LEN] = prefixed_list(&VOCABULARY);

/// Word `k` of the vocabulary (empty for an unknown `k`: never produced by
/// [`pack_into`]).
fn word(k: u8) -> &'static [u8] {
    prefixed(&WORDS, k)
}

/// The vocabulary word that `s` has at `i` (a word start), longest first.
const fn word_at(s: &[u8], i: usize) -> Option<(u8, usize)> {
    let mut best: Option<(u8, usize)> = None;
    let mut k = 0;
    while k < VOCABULARY.len() {
        let w = VOCABULARY[k].as_bytes();
        let fits = i + w.len() <= s.len()
            && (w[w.len() - 1] == b' ' || i + w.len() == s.len())
            && match best {
                Some((_, l)) => w.len() > l,
                None => true,
            };
        if fits {
            let mut j = 0;
            while j < w.len() && s[i + j] == w[j] {
                j += 1;
            }
            if j == w.len() {
                best = Some((k as u8, w.len()));
            }
        }
        k += 1;
    }
    best
}

/// Walks `s` packing it; writes into `out` at `at` when given. Returns the packed length.
const fn pack_walk(s: &str, mut out: Option<(&mut [u8], usize)>) -> usize {
    let s = s.as_bytes();
    let mut n = 0;
    let mut i = 0;
    while i < s.len() {
        if let Some((k, len)) = word_at(s, i) {
            if let Some((o, at)) = &mut out {
                o[*at + n] = WORD + k;
            }
            n += 1;
            i += len;
        } else {
            // The rest of this word, with its space.
            loop {
                let b = s[i];
                assert!(b < WORD, "packed od names are ASCII");
                if let Some((o, at)) = &mut out {
                    o[*at + n] = b;
                }
                n += 1;
                i += 1;
                if b == b' ' || i == s.len() {
                    break;
                }
            }
        }
    }
    n
}

/// Length of `s` packed.
pub const fn packed_len(s: &str) -> usize {
    pack_walk(s, None)
}

/// Writes `s` packed into `out` at `at`; returns the packed length.
pub const fn pack_into(s: &str, out: &mut [u8], at: usize) -> usize {
    pack_walk(s, Some((out, at)))
}

/// An object or entry name: plain text, or packed (see the module documentation).
/// Compare it with text, print it, or read its bytes with [`Name::bytes`].
#[derive(Clone, Copy)]
pub struct Name {
    raw: &'static [u8],
    packed: bool,
}

impl Name {
    /// A plain name.
    pub const fn plain(s: &'static str) -> Self {
        Name {
            raw: s.as_bytes(),
            packed: false,
        }
    }
    /// A name packed by [`pack_into`].
    pub(crate) const fn packed(raw: &'static [u8]) -> Self {
        Name { raw, packed: true }
    }
    /// The text, when the name is stored plain (packed names are read with
    /// [`Name::bytes`]).
    pub const fn as_plain(self) -> Option<&'static str> {
        if self.packed {
            None
        } else {
            // SAFETY: plain names are only made by `Name::plain` from a `&'static str`.
            Some(unsafe { core::str::from_utf8_unchecked(self.raw) })
        }
    }
    /// The name's bytes (UTF-8; ASCII for a packed name).
    pub fn bytes(self) -> NameBytes {
        NameBytes {
            rest: self.raw,
            word: &[],
            packed: self.packed,
        }
    }
    /// Length in bytes of the name's text.
    pub fn len(self) -> usize {
        if self.packed {
            self.raw
                .iter()
                .map(|&b| if b >= WORD { word(b - WORD).len() } else { 1 })
                .sum()
        } else {
            self.raw.len()
        }
    }
    /// True for the empty name.
    pub fn is_empty(self) -> bool {
        self.raw.is_empty()
    }
    /// The name's characters.
    pub fn chars(self) -> impl Iterator<Item = char> {
        let (plain, packed) = match self.as_plain() {
            Some(s) => (s, None),
            None => ("", Some(self.bytes())),
        };
        plain
            .chars()
            .chain(packed.into_iter().flatten().map(char::from))
    }
}

/// The bytes of a [`Name`], packed words expanded.
#[derive(Clone)]
pub struct NameBytes {
    rest: &'static [u8],
    word: &'static [u8],
    packed: bool,
}

impl Iterator for NameBytes {
    type Item = u8;
    fn next(&mut self) -> Option<u8> {
        loop {
            if let Some((&b, w)) = self.word.split_first() {
                self.word = w;
                return Some(b);
            }
            let (&b, rest) = self.rest.split_first()?;
            self.rest = rest;
            if !self.packed || b < WORD {
                return Some(b);
            }
            self.word = word(b - WORD);
        }
    }
}

impl PartialEq for Name {
    fn eq(&self, other: &Self) -> bool {
        self.bytes().eq(other.bytes())
    }
}

impl Eq for Name {}

impl PartialEq<str> for Name {
    fn eq(&self, other: &str) -> bool {
        self.bytes().eq(other.bytes())
    }
}

impl PartialEq<&str> for Name {
    fn eq(&self, other: &&str) -> bool {
        self.bytes().eq(other.bytes())
    }
}

impl PartialEq<Name> for &str {
    fn eq(&self, other: &Name) -> bool {
        other == self
    }
}

impl fmt::Display for Name {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.as_plain() {
            Some(s) => f.write_str(s),
            None => self.chars().try_for_each(|c| fmt::Write::write_char(f, c)),
        }
    }
}

impl fmt::Debug for Name {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "\"{self}\"")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip(s: &'static str) -> usize {
        let n = packed_len(s);
        let buf: &'static mut [u8] = Box::leak(vec![0u8; n + 3].into_boxed_slice());
        assert_eq!(pack_into(s, buf, 3), n);
        let name = Name::packed(&buf[3..]);
        assert_eq!(name, s, "{s}");
        assert_eq!(name.len(), s.len(), "{s}");
        assert_eq!(name.to_string(), s);
        assert_eq!(name.chars().collect::<String>(), s);
        assert_eq!(name.bytes().collect::<Vec<u8>>(), s.as_bytes());
        n
    }

    #[test]
    fn packed_names_read_back() {
        assert_eq!(roundtrip("Mapping entry 7"), 2);
        assert_eq!(roundtrip("Fault 3 snapshot"), 4);
        // A vocabulary word inside a longer word, or not at a word start, stays text.
        assert_eq!(roundtrip("Timeout"), 7);
        assert_eq!(roundtrip("Xtime"), 5);
        assert_eq!(roundtrip("timer"), 5);
        // A word without its space only at the end of the name.
        assert_eq!(roundtrip("time"), 1);
        assert_eq!(roundtrip("time x"), 2);
        assert_eq!(roundtrip(""), 0);
        assert_eq!(roundtrip(" "), 1);
        assert_eq!(roundtrip("a  b "), 5);
        for w in VOCABULARY {
            assert_eq!(roundtrip(w), 1, "{w}");
        }
    }

    #[test]
    fn vocabulary_bytes_and_unknown_words() {
        for (k, w) in VOCABULARY.iter().enumerate() {
            assert_eq!(word(k as u8), w.as_bytes());
        }
        assert_eq!(word(VOCABULARY.len() as u8), b"");
        assert_eq!(word(127), b"");
        // Bytes no packer writes (unknown word numbers) read as nothing, no panic.
        let odd = Name::packed(&[b'a', 0xFF, 0xF0, b'b']);
        assert_eq!(odd, "ab");
        assert_eq!(odd.len(), 2);
    }

    #[test]
    fn plain_names() {
        let n = Name::plain("Größe");
        assert_eq!(n.as_plain(), Some("Größe"));
        assert_eq!(n, "Größe");
        assert_eq!(n.len(), "Größe".len());
        assert_eq!(n.to_string(), "Größe");
        assert_eq!(n.chars().collect::<String>(), "Größe");
        assert_eq!(format!("{n:?}"), "\"Größe\"");
        assert!(Name::plain("").is_empty());
    }
}
