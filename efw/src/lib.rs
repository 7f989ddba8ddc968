//! The drive's firmware update image, `.efw`: a signed header followed by the board
//! image, as `cargo xtask update-image` writes it and the drive's FoE update checks it.
//!
//! # Layout (little endian)
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `ECSU` |
//! | 4 | 2 | format version ([`FORMAT_VERSION`]) |
//! | 6 | 2 | header length ([`HEADER_LEN`]) |
//! | 8 | 4 | vendor ID (0x1018:01) |
//! | 12 | 4 | product code (0x1018:02) |
//! | 16 | 1 | ESC flavour ([`Esc`]) |
//! | 17 | 3 | reserved, 0 |
//! | 20 | 4 | firmware version (major << 16 \| minor << 8 \| patch) |
//! | 24 | 4 | image length, bytes |
//! | 28 | 4 | security version (anti-rollback; 0 in files written before it existed) |
//! | 32 | 64 | image signature: ed25519 over the SHA-512 digest of the image |
//! | 96 | 64 | header signature: ed25519 over bytes 0..96 |
//! | 160 | image length | the board image, as it is written to the DFU partition |
//!
//! # Example
//!
//! Anything that is not an update image is refused before a byte of it is trusted:
//!
//! ```
//! use efw::{check_header, Esc, Expected, ImageError};
//!
//! let drive = Expected {
//!     vendor_id: 0x0000_0F00,
//!     product_code: 0x0000_0001,
//!     esc: Esc::Lan9252,
//!     capacity: 230 * 1024,
//!     public_key: [0; 32],
//!     min_security_version: 0,
//! };
//! assert_eq!(check_header(b"ECS", &drive).unwrap_err(), ImageError::Truncated);
//! assert_eq!(check_header(&[0u8; 200], &drive).unwrap_err(), ImageError::BadMagic);
//! ```
//!
//! The image signature is exactly what embassy-boot's
//! `FirmwareUpdater::verify_and_mark_updated` checks over the DFU partition (ed25519
//! over the 64-byte SHA-512 digest of the first `image length` bytes), so the drive
//! hands it over unchanged. The header signature, with the same key, lets the drive
//! refuse a foreign or forged file at its first packet, before it erases anything:
//! the product, the ESC flavour and the length it checks are then authentic.
//!
//! The security version is the anti-rollback counter: a drive keeps the highest one it
//! accepted ([`Expected::min_security_version`]) and refuses a signed file below it
//! ([`ImageError::Rollback`]), so an old, correctly signed image with a known flaw
//! cannot be installed again. It is raised by the signer only for a release that
//! fixes such a flaw; the firmware version may go down at an equal security version.
//!
//! The image check can run in bounded steps ([`ImageDigest`], then
//! [`verify_digest`]), so a drive can spread it over several polls.
//!
//! Nothing here panics on any input: every check returns an [`ImageError`].

#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![deny(clippy::undocumented_unsafe_blocks)]

#[cfg(feature = "std")]
extern crate std;

use ed25519_dalek::{Signature, Verifier, VerifyingKey};
use sha2::{Digest, Sha512};

/// `ECSU`.
pub const MAGIC: [u8; 4] = *b"ECSU";
/// The format this crate reads and writes.
pub const FORMAT_VERSION: u16 = 1;
/// Header length, bytes (the image starts here).
pub const HEADER_LEN: usize = 160;
/// Bytes covered by the header signature.
pub const SIGNED_HEADER_LEN: usize = 96;

mod field {
    use core::ops::Range;
    pub const MAGIC: Range<usize> = 0..4;
    pub const FORMAT: Range<usize> = 4..6;
    pub const HEADER_LEN: Range<usize> = 6..8;
    pub const VENDOR: Range<usize> = 8..12;
    pub const PRODUCT: Range<usize> = 12..16;
    pub const ESC: usize = 16;
    pub const VERSION: Range<usize> = 20..24;
    pub const IMAGE_LEN: Range<usize> = 24..28;
    pub const SECURITY_VERSION: Range<usize> = 28..32;
    pub const IMAGE_SIGNATURE: Range<usize> = 32..96;
    pub const HEADER_SIGNATURE: Range<usize> = 96..160;
}

/// The EtherCAT slave controller a board image is built for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Esc {
    /// Microchip LAN9252 (SPI).
    Lan9252 = 1,
    /// Beckhoff ET1100 (SPI).
    Et1100 = 2,
}

impl Esc {
    /// The flavour of code `b`.
    pub const fn from_code(b: u8) -> Option<Esc> {
        match b {
            1 => Some(Esc::Lan9252),
            2 => Some(Esc::Et1100),
            _ => None,
        }
    }

    /// File name stem of the flavour's update image (`ecs-<name>.efw`).
    pub const fn name(self) -> &'static str {
        match self {
            Esc::Lan9252 => "lan9252",
            Esc::Et1100 => "et1100",
        }
    }
}

/// Why an update image is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageError {
    /// Fewer bytes than the header, or than the image length it states.
    Truncated,
    /// Not an update image (magic).
    BadMagic,
    /// A format version or header length this drive does not know.
    UnknownFormat,
    /// The header signature does not verify with the drive's key (another key, a
    /// changed byte, no signature).
    BadHeaderSignature,
    /// Another vendor or product.
    WrongProduct,
    /// Built for the other ESC, or an unknown flavour.
    WrongEsc,
    /// Longer than the partition it must go to.
    TooLong,
    /// The image does not match its signature.
    BadImageSignature,
    /// Its security version is below the lowest the drive accepts (anti-rollback).
    Rollback,
}

/// A read/write view of an update image's header (smoltcp style).
#[derive(Debug, Clone, Copy)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// A view of `buffer` without checking its length.
    pub const fn new_unchecked(buffer: T) -> Frame<T> {
        Frame { buffer }
    }

    /// A view of `buffer`, checked to hold a whole header.
    pub fn new_checked(buffer: T) -> Result<Frame<T>, ImageError> {
        let f = Self::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }

    /// The buffer holds a whole header.
    pub fn check_len(&self) -> Result<(), ImageError> {
        if self.buffer.as_ref().len() < HEADER_LEN {
            Err(ImageError::Truncated)
        } else {
            Ok(())
        }
    }

    fn bytes<const N: usize>(&self, r: core::ops::Range<usize>) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some(b) = self.buffer.as_ref().get(r) {
            if b.len() == N {
                out.copy_from_slice(b);
            }
        }
        out
    }

    /// Magic.
    pub fn magic(&self) -> [u8; 4] {
        self.bytes(field::MAGIC)
    }
    /// Format version.
    pub fn format_version(&self) -> u16 {
        u16::from_le_bytes(self.bytes(field::FORMAT))
    }
    /// Header length.
    pub fn header_len(&self) -> u16 {
        u16::from_le_bytes(self.bytes(field::HEADER_LEN))
    }
    /// Vendor ID.
    pub fn vendor_id(&self) -> u32 {
        u32::from_le_bytes(self.bytes(field::VENDOR))
    }
    /// Product code.
    pub fn product_code(&self) -> u32 {
        u32::from_le_bytes(self.bytes(field::PRODUCT))
    }
    /// ESC flavour code.
    pub fn esc(&self) -> u8 {
        self.buffer.as_ref().get(field::ESC).copied().unwrap_or(0)
    }
    /// Firmware version.
    pub fn version(&self) -> u32 {
        u32::from_le_bytes(self.bytes(field::VERSION))
    }
    /// Image length.
    pub fn image_len(&self) -> u32 {
        u32::from_le_bytes(self.bytes(field::IMAGE_LEN))
    }
    /// Security version (anti-rollback).
    pub fn security_version(&self) -> u32 {
        u32::from_le_bytes(self.bytes(field::SECURITY_VERSION))
    }
    /// Image signature.
    pub fn image_signature(&self) -> [u8; 64] {
        self.bytes(field::IMAGE_SIGNATURE)
    }
    /// Header signature.
    pub fn header_signature(&self) -> [u8; 64] {
        self.bytes(field::HEADER_SIGNATURE)
    }
    /// The bytes the header signature covers.
    pub fn signed_part(&self) -> &[u8] {
        self.buffer.as_ref().get(..SIGNED_HEADER_LEN).unwrap_or(&[])
    }
}

/// The contents of a header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Vendor ID (0x1018:01).
    pub vendor_id: u32,
    /// Product code (0x1018:02).
    pub product_code: u32,
    /// ESC flavour.
    pub esc: Esc,
    /// Firmware version (major << 16 | minor << 8 | patch).
    pub version: u32,
    /// Image length, bytes.
    pub image_len: u32,
    /// Security version (anti-rollback, see the crate docs).
    pub security_version: u32,
    /// ed25519 over SHA-512 of the image.
    pub image_signature: [u8; 64],
}

impl Header {
    /// Parses a header without checking its signature (see [`check_header`]).
    pub fn parse<T: AsRef<[u8]>>(f: &Frame<T>) -> Result<Header, ImageError> {
        f.check_len()?;
        if f.magic() != MAGIC {
            return Err(ImageError::BadMagic);
        }
        if f.format_version() != FORMAT_VERSION || usize::from(f.header_len()) != HEADER_LEN {
            return Err(ImageError::UnknownFormat);
        }
        Ok(Header {
            vendor_id: f.vendor_id(),
            product_code: f.product_code(),
            esc: Esc::from_code(f.esc()).ok_or(ImageError::WrongEsc)?,
            version: f.version(),
            image_len: f.image_len(),
            security_version: f.security_version(),
            image_signature: f.image_signature(),
        })
    }

    /// Writes the header's first [`SIGNED_HEADER_LEN`] bytes (everything but the
    /// header signature) into `buf`.
    pub fn emit_signed_part(&self, buf: &mut [u8; SIGNED_HEADER_LEN]) {
        buf.fill(0);
        buf[field::MAGIC].copy_from_slice(&MAGIC);
        buf[field::FORMAT].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        buf[field::HEADER_LEN].copy_from_slice(&(HEADER_LEN as u16).to_le_bytes());
        buf[field::VENDOR].copy_from_slice(&self.vendor_id.to_le_bytes());
        buf[field::PRODUCT].copy_from_slice(&self.product_code.to_le_bytes());
        buf[field::ESC] = self.esc as u8;
        buf[field::VERSION].copy_from_slice(&self.version.to_le_bytes());
        buf[field::IMAGE_LEN].copy_from_slice(&self.image_len.to_le_bytes());
        buf[field::SECURITY_VERSION].copy_from_slice(&self.security_version.to_le_bytes());
        buf[field::IMAGE_SIGNATURE].copy_from_slice(&self.image_signature);
    }
}

/// What the drive accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Expected {
    /// Its vendor ID.
    pub vendor_id: u32,
    /// Its product code.
    pub product_code: u32,
    /// Its ESC.
    pub esc: Esc,
    /// Size of the DFU partition, bytes.
    pub capacity: u32,
    /// The public key its update images are signed with.
    pub public_key: [u8; 32],
    /// The lowest security version it accepts (the highest it accepted before).
    pub min_security_version: u32,
}

fn verify(key: &[u8; 32], message: &[u8], signature: &[u8; 64]) -> bool {
    let Ok(k) = VerifyingKey::from_bytes(key) else {
        return false;
    };
    k.verify(message, &Signature::from_bytes(signature)).is_ok()
}

/// Checks the header at the start of `file` for a drive that `expects` it: the format,
/// the header signature (before the fields are trusted), the product, the ESC and the
/// length. The image itself is checked by [`verify_image`] (or by
/// embassy-boot over the DFU partition) once it has arrived.
pub fn check_header(file: &[u8], expected: &Expected) -> Result<Header, ImageError> {
    let f = Frame::new_checked(file)?;
    let h = Header::parse(&f)?;
    if !verify(&expected.public_key, f.signed_part(), &f.header_signature()) {
        return Err(ImageError::BadHeaderSignature);
    }
    if h.vendor_id != expected.vendor_id || h.product_code != expected.product_code {
        return Err(ImageError::WrongProduct);
    }
    if h.esc != expected.esc {
        return Err(ImageError::WrongEsc);
    }
    if h.image_len > expected.capacity {
        return Err(ImageError::TooLong);
    }
    if h.security_version < expected.min_security_version {
        return Err(ImageError::Rollback);
    }
    Ok(h)
}

/// The SHA-512 digest of an image, fed in pieces of any size ([`ImageDigest::update`]),
/// so the check of a large image can be split into bounded steps.
#[derive(Clone, Default)]
pub struct ImageDigest(Sha512);

impl ImageDigest {
    /// An empty digest.
    pub fn new() -> Self {
        ImageDigest(Sha512::new())
    }
    /// Hashes the next `bytes` of the image.
    pub fn update(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }
    /// The digest of everything fed.
    pub fn finish(self) -> [u8; 64] {
        self.0.finalize().into()
    }
}

/// Checks the digest of the whole image ([`ImageDigest`]) against the header's image
/// signature: the last, fixed-cost step of [`verify_image`].
pub fn verify_digest(
    header: &Header,
    digest: &[u8; 64],
    public_key: &[u8; 32],
) -> Result<(), ImageError> {
    if verify(public_key, digest, &header.image_signature) {
        Ok(())
    } else {
        Err(ImageError::BadImageSignature)
    }
}

/// SHA-512 of `image`: the message of the image signature.
pub fn image_digest(image: &[u8]) -> [u8; 64] {
    let mut d = ImageDigest::new();
    d.update(image);
    d.finish()
}

/// Checks `image` (exactly `header.image_len` bytes) against the header's image
/// signature, as embassy-boot does over the DFU partition.
pub fn verify_image(
    header: &Header,
    image: &[u8],
    public_key: &[u8; 32],
) -> Result<(), ImageError> {
    if image.len() != header.image_len as usize {
        return Err(ImageError::Truncated);
    }
    verify_digest(header, &image_digest(image), public_key)
}

/// Checks a whole update file: [`check_header`], then [`verify_image`].
pub fn check_file(file: &[u8], expected: &Expected) -> Result<Header, ImageError> {
    let h = check_header(file, expected)?;
    let image = file.get(HEADER_LEN..).ok_or(ImageError::Truncated)?;
    if image.len() < h.image_len as usize {
        return Err(ImageError::Truncated);
    }
    verify_image(&h, &image[..h.image_len as usize], &expected.public_key)?;
    Ok(h)
}

/// Signing (host tools).
#[cfg(feature = "sign")]
pub mod sign {
    use super::*;
    use ed25519_dalek::{Signer, SigningKey};
    use std::vec::Vec;

    /// The 32-byte key written as 64 hex digits in `text` (surrounding white space
    /// ignored).
    pub fn key_from_hex(text: &str) -> Option<[u8; 32]> {
        let t = text.trim();
        if t.len() != 64 || !t.bytes().all(|c| c.is_ascii_hexdigit()) {
            return None;
        }
        let mut k = [0u8; 32];
        for (i, b) in k.iter_mut().enumerate() {
            *b = u8::from_str_radix(&t[2 * i..2 * i + 2], 16).ok()?;
        }
        Some(k)
    }

    /// The repository's DEVELOPMENT secret key (`keys/dev-signing-key.hex`, public:
    /// it proves nothing), for the tests and the default of `cargo xtask update-image`.
    pub fn dev_key() -> [u8; 32] {
        key_from_hex(include_str!("../../keys/dev-signing-key.hex"))
            .unwrap_or_else(|| panic!("keys/dev-signing-key.hex is not 64 hex digits"))
    }

    /// The public key of the 32-byte secret key `seed`.
    pub fn public_key(seed: &[u8; 32]) -> [u8; 32] {
        SigningKey::from_bytes(seed).verifying_key().to_bytes()
    }

    /// The update file of `image` for `esc`: header (with both signatures) and image,
    /// security version 0.
    pub fn update_file(
        seed: &[u8; 32],
        vendor_id: u32,
        product_code: u32,
        esc: Esc,
        version: u32,
        image: &[u8],
    ) -> Vec<u8> {
        update_file_secured(seed, vendor_id, product_code, esc, version, 0, image)
    }

    /// [`update_file`] with a security version (anti-rollback, see the crate docs).
    pub fn update_file_secured(
        seed: &[u8; 32],
        vendor_id: u32,
        product_code: u32,
        esc: Esc,
        version: u32,
        security_version: u32,
        image: &[u8],
    ) -> Vec<u8> {
        let key = SigningKey::from_bytes(seed);
        let h = Header {
            vendor_id,
            product_code,
            esc,
            version,
            image_len: image.len() as u32,
            security_version,
            image_signature: key.sign(&image_digest(image)).to_bytes(),
        };
        let mut signed = [0u8; SIGNED_HEADER_LEN];
        h.emit_signed_part(&mut signed);
        let mut out = Vec::with_capacity(HEADER_LEN + image.len());
        out.extend_from_slice(&signed);
        out.extend_from_slice(&key.sign(&signed).to_bytes());
        out.extend_from_slice(image);
        out
    }
}

#[cfg(all(test, feature = "sign"))]
mod tests {
    use super::sign::{public_key, update_file};
    use super::*;
    use std::vec::Vec;

    const SEED: [u8; 32] = [7; 32];
    const OTHER: [u8; 32] = [9; 32];

    fn expected() -> Expected {
        Expected {
            vendor_id: 0x0000_0ECA,
            product_code: 0x0000_5702,
            esc: Esc::Lan9252,
            capacity: 4096,
            public_key: public_key(&SEED),
            min_security_version: 0,
        }
    }

    fn file(esc: Esc, image: &[u8]) -> Vec<u8> {
        update_file(&SEED, 0x0ECA, 0x5702, esc, 0x0001_0203, image)
    }

    fn image() -> Vec<u8> {
        (0..1000u32).map(|i| (i * 7 + 3) as u8).collect()
    }

    #[test]
    fn a_signed_file_round_trips() {
        let f = file(Esc::Lan9252, &image());
        assert_eq!(f.len(), HEADER_LEN + 1000);
        let h = check_file(&f, &expected()).expect("accepted");
        assert_eq!(
            (h.vendor_id, h.product_code, h.esc, h.version, h.image_len),
            (0x0ECA, 0x5702, Esc::Lan9252, 0x0001_0203, 1000)
        );
        let fr = Frame::new_checked(&f[..]).unwrap();
        assert_eq!(Header::parse(&fr), Ok(h));
        let mut signed = [0u8; SIGNED_HEADER_LEN];
        h.emit_signed_part(&mut signed);
        assert_eq!(&signed[..], &f[..SIGNED_HEADER_LEN]);
    }

    #[test]
    fn every_refusal_has_its_reason() {
        let e = expected();
        let good = file(Esc::Lan9252, &image());
        assert_eq!(check_file(&good[..100], &e), Err(ImageError::Truncated));
        assert_eq!(
            check_file(&good[..good.len() - 1], &e),
            Err(ImageError::Truncated)
        );
        assert_eq!(
            check_file(&file(Esc::Et1100, &image()), &e),
            Err(ImageError::WrongEsc)
        );
        let other_product = update_file(&SEED, 0x0ECA, 0x5703, Esc::Lan9252, 1, &image());
        assert_eq!(
            check_file(&other_product, &e),
            Err(ImageError::WrongProduct)
        );
        let other_key = update_file(&OTHER, 0x0ECA, 0x5702, Esc::Lan9252, 1, &image());
        assert_eq!(
            check_file(&other_key, &e),
            Err(ImageError::BadHeaderSignature)
        );
        let big = file(Esc::Lan9252, &[0u8; 5000]);
        assert_eq!(check_file(&big, &e), Err(ImageError::TooLong));
        let mut no_sig = good.clone();
        no_sig[96..160].fill(0);
        assert_eq!(check_file(&no_sig, &e), Err(ImageError::BadHeaderSignature));
        let mut magic = good.clone();
        magic[0] = b'X';
        assert_eq!(check_file(&magic, &e), Err(ImageError::BadMagic));
        let mut format = good.clone();
        format[4] = 2;
        assert_eq!(check_file(&format, &e), Err(ImageError::UnknownFormat));
    }

    #[test]
    fn a_security_version_below_the_floor_is_refused() {
        use super::sign::update_file_secured;
        let img = image();
        let e = Expected {
            min_security_version: 3,
            ..expected()
        };
        for (sv, want) in [
            (0, Err(ImageError::Rollback)),
            (2, Err(ImageError::Rollback)),
            (3, Ok(3)),
            (7, Ok(7)),
        ] {
            let f = update_file_secured(&SEED, 0x0ECA, 0x5702, Esc::Lan9252, 9, sv, &img);
            assert_eq!(
                check_file(&f, &e).map(|h| h.security_version),
                want,
                "sv {sv}"
            );
        }
        // The field is signed: raising it in the file breaks the header signature.
        let mut f = update_file_secured(&SEED, 0x0ECA, 0x5702, Esc::Lan9252, 9, 1, &img);
        f[28] = 3;
        assert_eq!(check_file(&f, &e), Err(ImageError::BadHeaderSignature));
    }

    #[test]
    fn the_digest_in_pieces_is_the_digest_of_the_whole() {
        let img = image();
        let f = file(Esc::Lan9252, &img);
        let h = check_header(&f, &expected()).unwrap();
        for piece in [1usize, 7, 64, 333, 1000] {
            let mut d = ImageDigest::new();
            for c in img.chunks(piece) {
                d.update(c);
            }
            let d = d.finish();
            assert_eq!(d, image_digest(&img));
            assert_eq!(verify_digest(&h, &d, &public_key(&SEED)), Ok(()));
        }
        assert_eq!(
            verify_digest(&h, &image_digest(&img[1..]), &public_key(&SEED)),
            Err(ImageError::BadImageSignature)
        );
    }

    #[test]
    fn a_changed_byte_anywhere_is_refused() {
        let e = expected();
        let good = file(Esc::Lan9252, &image());
        for at in (0..good.len()).step_by(7) {
            let mut f = good.clone();
            f[at] ^= 0x20;
            let r = check_file(&f, &e);
            assert!(r.is_err(), "byte {at} changed: accepted");
            if at >= HEADER_LEN {
                assert_eq!(r, Err(ImageError::BadImageSignature), "byte {at}");
            }
        }
    }

    #[test]
    fn garbage_never_panics() {
        let e = expected();
        let mut x = 0x1234_5678u32;
        for len in [0usize, 1, 95, 96, 159, 160, 161, 400] {
            for _ in 0..50 {
                let f: Vec<u8> = (0..len)
                    .map(|_| {
                        x ^= x << 13;
                        x ^= x >> 17;
                        x ^= x << 5;
                        x as u8
                    })
                    .collect();
                assert!(check_file(&f, &e).is_err());
            }
        }
    }
}
