//! `cargo xtask update-image`: the signed firmware update files of the board, one per
//! ESC flavour, `target/update/ecs-<flavour>.efw` ([`efw`] format).
//!
//! Each board image is built as `size` builds it, its loadable segments are laid out
//! from the active partition's start ([`firmware::flash_layout::ACTIVE`]) as they are
//! flashed (gaps erased, 0xFF), and the file is signed with the secret key from
//! `ECS_SIGNING_KEY_FILE` (64 hex digits), or the repository's development key
//! `keys/dev-signing-key.hex`. The public key the board builds embed
//! ([`firmware::update::PUBLIC_KEY`]) must belong to that key: the command refuses
//! to write files the boards would refuse. A release board trusts the development
//! key only when built with `ECS_UPDATE_ALLOW_DEV_KEY=1` (or the firmware's cargo
//! feature `dev-key`): without `ECS_UPDATE_PUBLIC_KEY` set, the command asks for it.
//!
//! The header's security version (anti-rollback, [`efw`]) is `ECS_SECURITY_VERSION`
//! (a decimal `u32`, default 0): raise it for a release that fixes a security flaw,
//! and the drives that accepted it refuse every older file.

use std::path::Path;

use firmware::flash_layout::{ACTIVE, IMAGE_MAX};

/// Development secret key (public in the repository: DEVELOPMENT ONLY).
const DEV_KEY_FILE: &str = "keys/dev-signing-key.hex";

/// The 32-byte key written as 64 hex digits in `text`.
pub fn parse_key(text: &str) -> Result<[u8; 32], String> {
    efw::sign::key_from_hex(text).ok_or_else(|| "a key is 64 hex digits".into())
}

/// `major.minor.patch` → major << 16 | minor << 8 | patch.
pub fn version_word(v: &str) -> Result<u32, String> {
    let parts: Vec<&str> = v.split('.').collect();
    let [a, b, c] = parts[..] else {
        return Err(format!("version '{v}' is not major.minor.patch"));
    };
    let n = |s: &str, max: u32| -> Result<u32, String> {
        match s.parse::<u32>() {
            Ok(x) if x <= max => Ok(x),
            _ => Err(format!("version '{v}': '{s}' out of range")),
        }
    };
    Ok(n(a, 0xFFFF)? << 16 | n(b, 0xFF)? << 8 | n(c, 0xFF)?)
}

/// The flash contents of an ELF32 little-endian file: its PT_LOAD segments with
/// bytes in the file, at their load (physical) addresses, from `base`; gaps are
/// erased flash (0xFF). Fails on a segment below `base` or beyond `base + max`.
pub fn flash_image(elf: &[u8], base: u32, max: u32) -> Result<Vec<u8>, String> {
    let u16_at = |o: usize| -> Result<u16, String> {
        elf.get(o..o + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .ok_or_else(|| "ELF too short".to_string())
    };
    let u32_at = |o: usize| -> Result<u32, String> {
        elf.get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(|| "ELF too short".to_string())
    };
    if elf.get(..6) != Some(&[0x7F, b'E', b'L', b'F', 1, 1][..]) {
        return Err("not an ELF32 little-endian file".into());
    }
    let phoff = u32_at(0x1C)? as usize;
    let phentsize = usize::from(u16_at(0x2A)?);
    let phnum = usize::from(u16_at(0x2C)?);
    let mut image: Vec<u8> = Vec::new();
    for i in 0..phnum {
        let ph = phoff + i * phentsize;
        let (kind, offset, paddr, filesz) = (
            u32_at(ph)?,
            u32_at(ph + 4)?,
            u32_at(ph + 12)?,
            u32_at(ph + 16)?,
        );
        const PT_LOAD: u32 = 1;
        if kind != PT_LOAD || filesz == 0 {
            continue;
        }
        let end = paddr.checked_add(filesz).ok_or("segment overflows")?;
        if paddr < base || end > base + max {
            return Err(format!(
                "segment {paddr:#010x}..{end:#010x} outside {base:#010x}..{:#010x}: is the \
                 firmware linked for the active partition (memory.x)?",
                base + max
            ));
        }
        let data = elf
            .get(offset as usize..(offset + filesz) as usize)
            .ok_or("segment outside the file")?;
        let at = (paddr - base) as usize;
        if image.len() < at + data.len() {
            image.resize(at + data.len(), 0xFF);
        }
        image[at..at + data.len()].copy_from_slice(data);
    }
    if image.is_empty() {
        return Err("no loadable segment".into());
    }
    Ok(image)
}

/// The signing key: `ECS_SIGNING_KEY_FILE` or the development key.
fn signing_key(root: &Path) -> Result<([u8; 32], String), String> {
    let (path, name) = match std::env::var("ECS_SIGNING_KEY_FILE") {
        Ok(p) => (Path::new(&p).to_path_buf(), p),
        Err(_) => (
            root.join(DEV_KEY_FILE),
            format!("{DEV_KEY_FILE} (DEVELOPMENT key)"),
        ),
    };
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((
        parse_key(&text).map_err(|e| format!("{}: {e}", path.display()))?,
        name,
    ))
}

/// The public key (64 hex digits) of the secret key in `file` (default: the
/// development key).
pub fn public_key_of(file: Option<&str>) -> Result<String, String> {
    let path = file.unwrap_or(DEV_KEY_FILE);
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let seed = parse_key(&text).map_err(|e| format!("{path}: {e}"))?;
    Ok(efw::sign::public_key(&seed)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

/// Builds the board image of each flavour (`build(flavour)` returns its ELF path) and
/// writes its update file into `target/update/`.
pub fn run(
    root: &Path,
    flavours: &[(&str, efw::Esc)],
    build: impl Fn(&str) -> Result<String, String>,
) -> Result<(), String> {
    let (seed, key_name) = signing_key(root)?;
    // What the release board built now trusts (firmware::update, "The trusted key").
    let env_key = std::env::var("ECS_UPDATE_PUBLIC_KEY").ok();
    if env_key
        .as_deref()
        .is_some_and(|k| k.len() != 64 || !k.bytes().all(|c| c.is_ascii_hexdigit()))
    {
        return Err("ECS_UPDATE_PUBLIC_KEY: not 64 hex digits".into());
    }
    let allow_dev = std::env::var("ECS_UPDATE_ALLOW_DEV_KEY").is_ok_and(|v| v == "1");
    match firmware::update::trust(env_key.as_deref(), allow_dev, true).key() {
        None => {
            return Err(format!(
                "a release board built without ECS_UPDATE_PUBLIC_KEY trusts no update key: \
                 set ECS_UPDATE_PUBLIC_KEY to the public key of {key_name}, or \
                 ECS_UPDATE_ALLOW_DEV_KEY=1 to build boards that trust the public \
                 development key"
            ))
        }
        Some(k) if k != efw::sign::public_key(&seed) => {
            return Err(format!(
                "the key {key_name} does not belong to the public key the board embeds \
                 (ECS_UPDATE_PUBLIC_KEY or keys/dev-public-key.hex): the boards would \
                 refuse these files"
            ))
        }
        Some(_) => {}
    }
    let version = version_word(firmware::identity::SOFTWARE_VERSION)?;
    let security_version = match std::env::var("ECS_SECURITY_VERSION") {
        Ok(v) => v
            .trim()
            .parse::<u32>()
            .map_err(|_| format!("ECS_SECURITY_VERSION: not a u32: {v}"))?,
        Err(_) => 0,
    };
    let variant = firmware::identity::BOARD_VARIANT;
    let out_dir = root.join("target/update");
    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    for &(flavour, esc) in flavours {
        let elf_path = build(flavour)?;
        let elf = std::fs::read(&elf_path).map_err(|e| format!("{elf_path}: {e}"))?;
        let image = flash_image(&elf, ACTIVE.start(), IMAGE_MAX)?;
        let file = efw::sign::update_file_secured(
            &seed,
            firmware::identity::VENDOR_ID,
            variant.product_code(),
            esc,
            version,
            security_version,
            &image,
        );
        let path = out_dir.join(format!("ecs-{}.efw", esc.name()));
        std::fs::write(&path, &file).map_err(|e| format!("{}: {e}", path.display()))?;
        println!(
            "update image ({flavour}): {} — version {}, security version {security_version}, \
             image {} B of {} B, signed with {key_name}",
            path.display(),
            firmware::identity::SOFTWARE_VERSION,
            image.len(),
            IMAGE_MAX
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minimal ELF32 with two PT_LOAD segments (and one without file bytes).
    fn elf(segments: &[(u32, &[u8])]) -> Vec<u8> {
        let phoff = 52usize;
        let data_at = phoff + 32 * (segments.len() + 1);
        let mut e = vec![0u8; data_at];
        e[..6].copy_from_slice(&[0x7F, b'E', b'L', b'F', 1, 1]);
        e[0x1C..0x20].copy_from_slice(&(phoff as u32).to_le_bytes());
        e[0x2A..0x2C].copy_from_slice(&32u16.to_le_bytes());
        e[0x2C..0x2E].copy_from_slice(&(segments.len() as u16 + 1).to_le_bytes());
        let mut at = data_at;
        for (i, (addr, bytes)) in segments.iter().enumerate() {
            let ph = phoff + 32 * i;
            e[ph..ph + 4].copy_from_slice(&1u32.to_le_bytes());
            e[ph + 4..ph + 8].copy_from_slice(&(at as u32).to_le_bytes());
            e[ph + 12..ph + 16].copy_from_slice(&addr.to_le_bytes());
            e[ph + 16..ph + 20].copy_from_slice(&(bytes.len() as u32).to_le_bytes());
            at += bytes.len();
        }
        // A .bss-like segment: PT_LOAD without file bytes.
        let ph = phoff + 32 * segments.len();
        e[ph..ph + 4].copy_from_slice(&1u32.to_le_bytes());
        e[ph + 12..ph + 16].copy_from_slice(&0x2000_0000u32.to_le_bytes());
        for (_, bytes) in segments {
            e.extend_from_slice(bytes);
        }
        e
    }

    #[test]
    fn segments_are_laid_out_from_the_base_with_erased_gaps() {
        let e = elf(&[(0x0800_9000, &[1, 2, 3]), (0x0800_9008, &[9, 9])]);
        let img = flash_image(&e, 0x0800_9000, 0x1000).unwrap();
        assert_eq!(img, vec![1, 2, 3, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 9, 9]);
        let low = elf(&[(0x0800_0000, &[1])]);
        assert!(
            flash_image(&low, 0x0800_9000, 0x1000).is_err(),
            "below the partition"
        );
        let big = elf(&[(0x0800_9000, &[0; 16])]);
        assert!(flash_image(&big, 0x0800_9000, 8).is_err(), "too long");
        assert!(flash_image(b"not an elf", 0, 8).is_err());
        assert!(
            flash_image(&e[..40], 0x0800_9000, 0x1000).is_err(),
            "truncated"
        );
    }

    #[test]
    fn versions_and_keys() {
        assert_eq!(version_word("1.2.3"), Ok(0x0001_0203));
        assert_eq!(version_word("0.1.0"), Ok(0x0000_0100));
        assert!(version_word("1.2").is_err() && version_word("1.2.256").is_err());
        assert!(parse_key("00").is_err());
        let dev = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../",
            "keys/dev-signing-key.hex"
        ))
        .unwrap();
        let seed = parse_key(&dev).unwrap();
        assert_eq!(
            Some(efw::sign::public_key(&seed)),
            firmware::update::PUBLIC_KEY
        );
        // A release board trusts it only when asked for.
        let dev_hex = firmware::update::DEV_PUBLIC_KEY_HEX;
        use firmware::update::{trust, Trust};
        assert_eq!(trust(None, false, true), Trust::None);
        assert_eq!(trust(Some(dev_hex), false, true), Trust::None);
        assert!(matches!(trust(None, true, true), Trust::Development(_)));
    }
}
