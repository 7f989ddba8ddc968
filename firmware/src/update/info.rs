//! The running image's information file ([`super::INFO_FILE`], `firmware.info`):
//! the version formats and the text written without `core::fmt`.

use super::{Update, Updater};

/// `major.minor.patch` of a version word (major << 16 | minor << 8 | patch) into
/// `buf`; returns the length (0 when `buf` is too short).
pub fn format_version(version: u32, buf: &mut [u8]) -> usize {
    let mut n = 0;
    for (k, part) in [version >> 16, (version >> 8) & 0xFF, version & 0xFF]
        .into_iter()
        .enumerate()
    {
        if k > 0 {
            let Some(b) = buf.get_mut(n) else { return 0 };
            *b = b'.';
            n += 1;
        }
        let mut digits = [0u8; 5];
        let mut d = 0;
        let mut v = part;
        loop {
            digits[d] = b'0' + (v % 10) as u8;
            d += 1;
            v /= 10;
            if v == 0 {
                break;
            }
        }
        for &c in digits[..d].iter().rev() {
            let Some(b) = buf.get_mut(n) else { return 0 };
            *b = c;
            n += 1;
        }
    }
    n
}

impl<U: Updater> Update<U> {
    /// Writes the text of [`super::INFO_FILE`] into the update's buffer: its length.
    pub(super) fn build_info(&mut self) -> usize {
        let e = self.expected;
        let boot = self.boot_state();
        let running = self.running.header;
        let (security, trust) = (self.expected.min_security_version, self.trust);
        let mut b = Text {
            buf: &mut self.info,
            len: 0,
        };
        b.str("vendor=0x").hex(e.vendor_id, 8, true);
        b.str("\nproduct=0x").hex(e.product_code, 8, true);
        b.str("\nesc=").str(e.esc.name()).str("\n");
        match running {
            Some(h) => {
                b.str("version=").dec(h.version >> 16).str(".");
                b.dec((h.version >> 8) & 0xFF)
                    .str(".")
                    .dec(h.version & 0xFF);
                // The build: the start of the image signature, unique to the signed
                // image.
                b.str("\nbuild=").bytes_hex(&h.image_signature[..8]);
                b.str("\nimage-length=").dec(h.image_len);
                b.str("\nsignature=valid\n");
            }
            None => {
                b.str("version=").str(crate::identity::SOFTWARE_VERSION);
                b.str("\nbuild=none\nsignature=none\n");
            }
        }
        b.str("security-version=").dec(security);
        b.str("\nkey=").str(trust.name()).str("\n");
        if let Some(k) = trust.key() {
            b.str("key-fingerprint=")
                .bytes_hex(&efw::image_digest(&k)[..8])
                .str("\n");
        }
        b.str("boot=").str(boot.name()).str("\n");
        b.len
    }
}
/// A text written into a fixed buffer, cut at its end (`firmware.info`): the few
/// number formats it needs without `core::fmt` in the image.
struct Text<'a> {
    buf: &'a mut [u8],
    len: usize,
}

impl Text<'_> {
    fn byte(&mut self, c: u8) -> &mut Self {
        if let Some(d) = self.buf.get_mut(self.len) {
            *d = c;
            self.len += 1;
        }
        self
    }
    // Not inlined: inlined, each of the 23 calls in `build_info` carried its own
    // copy loop (measured with `cargo xtask size`: 364 B more in the board image).
    #[inline(never)]
    fn str(&mut self, s: &str) -> &mut Self {
        for &c in s.as_bytes() {
            self.byte(c);
        }
        self
    }
    /// `v` in decimal.
    fn dec(&mut self, v: u32) -> &mut Self {
        let mut digits = [0u8; 10];
        let (mut n, mut i) = (v, digits.len());
        loop {
            i -= 1;
            digits[i] = b'0' + (n % 10) as u8;
            n /= 10;
            if n == 0 {
                break;
            }
        }
        for &c in &digits[i..] {
            self.byte(c);
        }
        self
    }
    /// The low `digits` hex digits of `v`, most significant first.
    fn hex(&mut self, v: u32, digits: u32, upper: bool) -> &mut Self {
        let set: &[u8; 16] = if upper {
            b"0123456789ABCDEF"
        } else {
            b"0123456789abcdef"
        };
        for i in (0..digits).rev() {
            self.byte(set[((v >> (4 * i)) & 0xF) as usize]);
        }
        self
    }
    /// Each byte as two lower-case hex digits.
    fn bytes_hex(&mut self, bytes: &[u8]) -> &mut Self {
        for &x in bytes {
            self.hex(u32::from(x), 2, false);
        }
        self
    }
}
