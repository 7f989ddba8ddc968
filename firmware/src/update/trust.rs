//! The key a build trusts for update files ([`TRUST`], see the module docs of
//! [`super`], "The trusted key"): from `ECS_UPDATE_PUBLIC_KEY`, the cargo feature
//! `dev-key`, `ECS_UPDATE_ALLOW_DEV_KEY` and the build profile, decided at compile
//! time.

/// The key update files must be signed with (see the module docs, "The trusted
/// key"): from `ECS_UPDATE_PUBLIC_KEY`, the cargo feature `dev-key`,
/// `ECS_UPDATE_ALLOW_DEV_KEY` and the build profile.
pub const TRUST: Trust = trust(
    option_env!("ECS_UPDATE_PUBLIC_KEY"),
    cfg!(feature = "dev-key") || is_one(option_env!("ECS_UPDATE_ALLOW_DEV_KEY")),
    !cfg!(debug_assertions),
);

/// The public key of [`TRUST`] (`None`: every update file is refused).
pub const PUBLIC_KEY: Option<[u8; 32]> = TRUST.key();

/// The key a build trusts for update files.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Trust {
    /// The repository's development key (`keys/`): anyone can sign with it.
    Development([u8; 32]),
    /// A manufacturer's own key (`ECS_UPDATE_PUBLIC_KEY`).
    Production([u8; 32]),
    /// No key: a release build that was not given one (every file is refused).
    None,
}

impl Trust {
    /// The public key, if any.
    pub const fn key(self) -> Option<[u8; 32]> {
        match self {
            Trust::Development(k) | Trust::Production(k) => Some(k),
            Trust::None => None,
        }
    }
    /// Its name in [`INFO_FILE`](super::INFO_FILE).
    pub const fn name(self) -> &'static str {
        match self {
            Trust::Development(_) => "development",
            Trust::Production(_) => "production",
            Trust::None => "none",
        }
    }
}

/// The decision of [`TRUST`]: `env_key` (`ECS_UPDATE_PUBLIC_KEY`, 64 hex digits),
/// `allow_dev` (feature `dev-key` or `ECS_UPDATE_ALLOW_DEV_KEY=1`), `release` (a
/// build without debug assertions). A release build trusts the development key only
/// when `allow_dev`.
pub const fn trust(env_key: Option<&str>, allow_dev: bool, release: bool) -> Trust {
    let dev = parse_key(DEV_PUBLIC_KEY_HEX);
    let key = match env_key {
        Some(k) => parse_key(k),
        None => dev,
    };
    let mut same = true;
    let mut i = 0;
    while i < 32 {
        same &= key[i] == dev[i];
        i += 1;
    }
    if !same {
        Trust::Production(key)
    } else if release && !allow_dev {
        Trust::None
    } else {
        Trust::Development(key)
    }
}

/// `Some("1")`.
const fn is_one(v: Option<&str>) -> bool {
    matches!(v, Some(s) if s.len() == 1 && s.as_bytes()[0] == b'1')
}

const fn parse_key(hex: &str) -> [u8; 32] {
    let b = hex.as_bytes();
    assert!(b.len() == 64, "ECS_UPDATE_PUBLIC_KEY: 64 hex digits");
    let mut out = [0u8; 32];
    let mut i = 0;
    while i < 32 {
        out[i] = nibble(b[2 * i]) << 4 | nibble(b[2 * i + 1]);
        i += 1;
    }
    out
}

const fn nibble(c: u8) -> u8 {
    match c {
        b'0'..=b'9' => c - b'0',
        b'a'..=b'f' => c - b'a' + 10,
        b'A'..=b'F' => c - b'A' + 10,
        _ => panic!("ECS_UPDATE_PUBLIC_KEY: not a hex digit"),
    }
}

/// The public key of the repository's development key pair (DEVELOPMENT ONLY: its
/// secret half is public in `keys/`; `cargo xtask update-image` checks that the two
/// belong together).
pub const DEV_PUBLIC_KEY_HEX: &str = include_str!("../../../keys/dev-public-key.hex").trim_ascii();
