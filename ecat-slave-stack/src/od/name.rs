//! Object and entry names, and their packed form.
//!
//! SDO information must answer every object and entry name, so the names stay in
//! flash; most of them repeat a few words ("Mapping entry 7", "Fault 3 snapshot",
//! "Touch probe 1 positive edge"). [`pack_into`] stores a name with each word of a
//! vocabulary replaced by one byte `0x80 + k` (bytes below 0x80 are the name's own
//! ASCII characters); [`Name`] reads a packed name back through the same vocabulary,
//! stored as length-prefixed words ([`words_into`]). The vocabulary is the
//! application's: the words that repeat in its dictionary (the argument of
//! [`crate::packed_dictionary!`]); [`COE_WORDS`] holds the ones of the objects this
//! stack describes itself.
//!
//! Matching is on word boundaries only, so decoding is a plain concatenation: a word
//! of the vocabulary is used where the name has it at a word start and either the
//! vocabulary word ends with a space or the name ends with it.

use core::fmt;

/// The words of the names of the stack's own objects (PDO mapping and assignment,
/// sync manager parameters, timing diagnostics): the vocabulary of a dictionary with
/// no words of its own.
pub const COE_WORDS: &[&str] = &[
    "Mapping entry ",
    "communication ",
    "Number of ",
    "Assigned PDO ",
    "SYNC0 ",
    "period",
    "time",
    "cycle ",
];

/// First byte value that stands for a vocabulary word.
const WORD: u8 = 0x80;

/// Bytes of `list` stored as length-prefixed texts ([`prefixed_into`]).
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

/// Writes `list` as length-prefixed texts into `out`: one byte of length, then the
/// bytes, for each.
pub(crate) const fn prefixed_into(list: &[&str], out: &mut [u8]) {
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
}

/// `list` as length-prefixed texts ([`prefixed_into`]) in an array of its size.
#[cfg(test)]
pub(crate) const fn prefixed_list<const N: usize>(list: &[&str]) -> [u8; N] {
    let mut out = [0u8; N];
    prefixed_into(list, &mut out);
    out
}

/// Text `k` of a length-prefixed list (empty past its end).
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

/// Bytes of `words` as the length-prefixed list [`Name`] decodes with; a vocabulary
/// of more than 128 words, an empty word or one that is not ASCII is a compile-time
/// error for the constant tables.
pub const fn words_len(words: &[&str]) -> usize {
    assert!(words.len() <= 128, "od name vocabulary over 128 words");
    let mut i = 0;
    while i < words.len() {
        let w = words[i].as_bytes();
        assert!(!w.is_empty(), "od vocabulary word empty");
        let mut j = 0;
        while j < w.len() {
            assert!(w[j] < WORD, "od vocabulary words are ASCII");
            j += 1;
        }
        i += 1;
    }
    prefixed_len(words)
}

/// Writes `words` into `out` ([`words_len`] bytes) as [`Name`] reads them.
pub const fn words_into(words: &[&str], out: &mut [u8]) {
    assert!(out.len() == words_len(words), "od: vocabulary buffer size");
    prefixed_into(words, out);
}

/// The vocabulary word that `s` has at `i` (a word start), longest first.
const fn word_at(s: &[u8], i: usize, words: &[&str]) -> Option<(u8, usize)> {
    let mut best: Option<(u8, usize)> = None;
    let mut k = 0;
    while k < words.len() {
        let w = words[k].as_bytes();
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

/// Walks `s` packing it with `words`; writes into `out` at `at` when given. Returns
/// the packed length.
const fn pack_walk(s: &str, words: &[&str], mut out: Option<(&mut [u8], usize)>) -> usize {
    let s = s.as_bytes();
    let mut n = 0;
    let mut i = 0;
    while i < s.len() {
        if let Some((k, len)) = word_at(s, i, words) {
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

/// Length of `s` packed with `words`.
pub const fn packed_len(s: &str, words: &[&str]) -> usize {
    pack_walk(s, words, None)
}

/// Writes `s` packed with `words` into `out` at `at`; returns the packed length.
pub const fn pack_into(s: &str, words: &[&str], out: &mut [u8], at: usize) -> usize {
    pack_walk(s, words, Some((out, at)))
}

/// An object or entry name: plain text, or packed (see the module documentation).
/// Compare it with text, print it, or read its bytes with [`Name::bytes`].
#[derive(Clone, Copy)]
pub struct Name(Form);

#[derive(Clone, Copy)]
enum Form {
    Plain(&'static str),
    /// Packed bytes and the vocabulary ([`words_into`]) they were packed with.
    Packed {
        raw: &'static [u8],
        words: &'static [u8],
    },
}

impl Name {
    /// A plain name.
    pub const fn plain(s: &'static str) -> Self {
        Name(Form::Plain(s))
    }
    /// A name packed by [`pack_into`] with the vocabulary `words` ([`words_into`]).
    pub const fn packed(raw: &'static [u8], words: &'static [u8]) -> Self {
        Name(Form::Packed { raw, words })
    }
    /// The text, when the name is stored plain (packed names are read with
    /// [`Name::bytes`]).
    pub const fn as_plain(self) -> Option<&'static str> {
        match self.0 {
            Form::Plain(s) => Some(s),
            Form::Packed { .. } => None,
        }
    }
    /// Bytes the name takes in flash (packed or plain).
    pub const fn stored_len(self) -> usize {
        match self.0 {
            Form::Plain(s) => s.len(),
            Form::Packed { raw, .. } => raw.len(),
        }
    }
    /// The name's bytes (UTF-8; ASCII for a packed name).
    pub fn bytes(self) -> NameBytes {
        let (rest, words) = match self.0 {
            Form::Plain(s) => (s.as_bytes(), None),
            Form::Packed { raw, words } => (raw, Some(words)),
        };
        NameBytes {
            rest,
            word: &[],
            words,
        }
    }
    /// Length in bytes of the name's text.
    pub fn len(self) -> usize {
        match self.0 {
            Form::Plain(s) => s.len(),
            Form::Packed { raw, words } => raw
                .iter()
                .map(|&b| {
                    if b >= WORD {
                        prefixed(words, b - WORD).len()
                    } else {
                        1
                    }
                })
                .sum(),
        }
    }
    /// True for the empty name.
    pub fn is_empty(self) -> bool {
        self.stored_len() == 0
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
    /// The vocabulary of a packed name; `None` for a plain one.
    words: Option<&'static [u8]>,
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
            match self.words {
                Some(words) if b >= WORD => self.word = prefixed(words, b - WORD),
                _ => return Some(b),
            }
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

    /// A vocabulary for the tests: the stack's words and a few of a drive's.
    const WORDS: &[&str] = &[
        "Mapping entry ",
        "Fault ",
        "snapshot",
        "time",
        "Touch probe ",
        "positive edge",
        "time ",
    ];
    static WORD_BYTES: [u8; words_len(WORDS)] = prefixed_list(WORDS);

    fn roundtrip(s: &'static str) -> usize {
        let n = packed_len(s, WORDS);
        let buf: &'static mut [u8] = Box::leak(vec![0u8; n + 3].into_boxed_slice());
        assert_eq!(pack_into(s, WORDS, buf, 3), n);
        let name = Name::packed(&buf[3..], &WORD_BYTES);
        assert_eq!(name, s, "{s}");
        assert_eq!(name.len(), s.len(), "{s}");
        assert_eq!(name.stored_len(), n, "{s}");
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
        for w in WORDS {
            assert_eq!(roundtrip(w), 1, "{w}");
        }
        // Without a vocabulary a name is its text.
        assert_eq!(packed_len("Mapping entry 7", &[]), 15);
    }

    #[test]
    fn vocabulary_bytes_and_unknown_words() {
        let mut bytes = [0u8; words_len(WORDS)];
        words_into(WORDS, &mut bytes);
        assert_eq!(bytes, WORD_BYTES);
        for (k, w) in WORDS.iter().enumerate() {
            assert_eq!(prefixed(&WORD_BYTES, k as u8), w.as_bytes());
        }
        assert_eq!(prefixed(&WORD_BYTES, WORDS.len() as u8), b"");
        assert_eq!(prefixed(&WORD_BYTES, 127), b"");
        // Bytes no packer writes (unknown word numbers) read as nothing, no panic.
        let odd = Name::packed(&[b'a', 0xFF, 0xF0, b'b'], &WORD_BYTES);
        assert_eq!(odd, "ab");
        assert_eq!(odd.len(), 2);
        // The same packed bytes read through another vocabulary are other text.
        static TWO: [u8; 2] = [0x80, 0x81];
        assert_eq!(Name::packed(&TWO, &WORD_BYTES), "Mapping entry Fault ");
        static COE: [u8; words_len(COE_WORDS)] = prefixed_list(COE_WORDS);
        assert_eq!(Name::packed(&TWO, &COE), "Mapping entry communication ");
    }

    #[test]
    fn plain_names() {
        let n = Name::plain("Größe");
        assert_eq!(n.as_plain(), Some("Größe"));
        assert_eq!(n, "Größe");
        assert_eq!(n.len(), "Größe".len());
        assert_eq!(n.stored_len(), "Größe".len());
        assert_eq!(n.to_string(), "Größe");
        assert_eq!(n.chars().collect::<String>(), "Größe");
        assert_eq!(format!("{n:?}"), "\"Größe\"");
        assert!(Name::plain("").is_empty());
        // Bytes of 0x80 and up are the text's own in a plain name.
        assert_eq!(n.bytes().collect::<Vec<u8>>(), "Größe".as_bytes());
    }
}
