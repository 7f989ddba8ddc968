//! Symbol names: the legacy and the v0 Rust manglings, plain paths only.

/// Legacy Rust mangling (`_ZN` length-prefixed parts `E`) → readable path, without the
/// `17h<hash>` part. Other names are returned unchanged.
pub fn demangle(name: &str) -> String {
    if let Some(v0) = name.strip_prefix("_R") {
        return demangle_v0(v0).unwrap_or_else(|| name.to_string());
    }
    let Some(rest) = name.strip_prefix("_ZN") else {
        return name.to_string();
    };
    let b = rest.as_bytes();
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < b.len() && b[i] != b'E' {
        let start = i;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
        let Ok(len) = rest[start..i].parse::<usize>() else {
            return name.to_string();
        };
        let Some(part) = rest.get(i..i + len) else {
            return name.to_string();
        };
        i += len;
        let is_hash =
            len == 17 && part.starts_with('h') && part[1..].bytes().all(|c| c.is_ascii_hexdigit());
        if !is_hash {
            parts.push(unescape(part));
        }
    }
    parts.join("::")
}

/// The v0 mangling (`_R`), plain paths only: crate roots (`C`) and nested paths (`N`);
/// anything else (impls, generic arguments, back references) → `None`.
fn demangle_v0(s: &str) -> Option<String> {
    fn ident(b: &[u8], i: &mut usize) -> Option<String> {
        if b.get(*i) == Some(&b's') {
            // disambiguator: s <base62> _
            *i += 1;
            while *b.get(*i)? != b'_' {
                *i += 1;
            }
            *i += 1;
        }
        if b.get(*i) == Some(&b'u') {
            return None; // punycode
        }
        let start = *i;
        while b.get(*i)?.is_ascii_digit() {
            *i += 1;
        }
        let len: usize = std::str::from_utf8(&b[start..*i]).ok()?.parse().ok()?;
        if b.get(*i) == Some(&b'_') {
            *i += 1;
        }
        let id = std::str::from_utf8(b.get(*i..*i + len)?).ok()?.to_string();
        *i += len;
        Some(id)
    }
    fn path(b: &[u8], i: &mut usize, depth: u32) -> Option<String> {
        if depth > 64 {
            return None;
        }
        let tag = *b.get(*i)?;
        *i += 1;
        match tag {
            b'C' => ident(b, i),
            b'N' => {
                let ns = *b.get(*i)?;
                *i += 1;
                let inner = path(b, i, depth + 1)?;
                let id = ident(b, i)?;
                Some(match (ns.is_ascii_uppercase(), id.is_empty()) {
                    (true, _) if ns == b'C' => format!("{inner}::{{closure}}"),
                    (true, true) => format!("{inner}::{{{}}}", ns as char),
                    _ => format!("{inner}::{id}"),
                })
            }
            _ => None,
        }
    }
    let b = s.as_bytes();
    let mut i = 0;
    let out = path(b, &mut i, 0)?;
    // A trailing instantiating crate is allowed; anything else is not understood.
    (i == b.len() || b[i] == b'C').then_some(out)
}

fn unescape(part: &str) -> String {
    let part = part
        .strip_prefix("_$")
        .map_or(part.to_string(), |p| format!("${p}"));
    let mut out = String::new();
    let mut rest = part.as_str();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("..") {
            out.push_str("::");
            rest = r;
        } else if let Some(r) = rest.strip_prefix('$') {
            let Some(end) = r.find('$') else {
                out.push_str(rest);
                break;
            };
            let code = &r[..end];
            let s = match code {
                "LT" => "<".to_string(),
                "GT" => ">".to_string(),
                "RF" => "&".to_string(),
                "BP" => "*".to_string(),
                "C" => ",".to_string(),
                "SP" => "@".to_string(),
                "LP" => "(".to_string(),
                "RP" => ")".to_string(),
                _ => code
                    .strip_prefix('u')
                    .and_then(|h| u32::from_str_radix(h, 16).ok())
                    .and_then(char::from_u32)
                    .map_or_else(|| format!("${code}$"), String::from),
            };
            out.push_str(&s);
            rest = &r[end + 1..];
        } else {
            let c = rest.chars().next().unwrap_or(' ');
            out.push(c);
            rest = &rest[c.len_utf8()..];
        }
    }
    out
}
