//! The dictionary as the drive describes it over SDO information (ETG.1000.6 5.6.3),
//! and values of its CoE data types as text.

use serde::Serialize;

/// An object from "get object description".
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ObjectInfo {
    /// Index.
    pub index: u16,
    /// Data type (RECORD: 0x002A).
    pub data_type: u16,
    /// Highest sub-index.
    pub max_sub: u8,
    /// Object code (7 VAR, 8 ARRAY, 9 RECORD).
    pub code: u8,
    /// Name.
    pub name: String,
}

/// An entry from "get entry description" with default, minimum and maximum.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct EntryInfo {
    /// Sub-index.
    pub sub: u8,
    /// Data type.
    pub data_type: u16,
    /// Bit length.
    pub bits: u16,
    /// Access word (bits 0-2 read in Pre-Op / Safe-Op / Op, 3-5 write, 6 RxPDO, 7
    /// TxPDO mappable).
    pub access: u16,
    /// Access in words ("rw", "ro", "wo") with the PDO direction.
    pub access_text: String,
    /// Name (with the unit as "name [unit]" where the entry has one).
    pub name: String,
    /// Data type name.
    pub type_name: String,
    /// Default, minimum, maximum as text (when the drive gives them).
    pub default: Option<String>,
    /// Minimum.
    pub min: Option<String>,
    /// Maximum.
    pub max: Option<String>,
}

fn u16_at(d: &[u8], i: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*d.get(i)?, *d.get(i + 1)?]))
}

/// The indices of an OD list answer (list type first).
pub fn parse_list(d: &[u8]) -> Vec<u16> {
    d.chunks_exact(2)
        .skip(1)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect()
}

/// An object description answer.
pub fn parse_object(d: &[u8]) -> Option<ObjectInfo> {
    Some(ObjectInfo {
        index: u16_at(d, 0)?,
        data_type: u16_at(d, 2)?,
        max_sub: *d.get(4)?,
        code: *d.get(5)?,
        name: String::from_utf8_lossy(d.get(6..)?).into_owned(),
    })
}

/// An entry description answer.
pub fn parse_entry(d: &[u8]) -> Option<EntryInfo> {
    let sub = *d.get(2)?;
    let vi = *d.get(3)?;
    let data_type = u16_at(d, 4)?;
    let bits = u16_at(d, 6)?;
    let access = u16_at(d, 8)?;
    let mut at = 10;
    let n = usize::from(bits).div_ceil(8);
    let mut take = |flag: u8| -> Option<Option<String>> {
        if vi & flag == 0 {
            return Some(None);
        }
        let v = d.get(at..at + n)?;
        at += n;
        Some(Some(format_value(data_type, v)))
    };
    let default = take(0x10)?;
    let min = take(0x20)?;
    let max = take(0x40)?;
    let name = String::from_utf8_lossy(d.get(at..)?).into_owned();
    let (r, w) = (access & 0x07 != 0, access & 0x38 != 0);
    let mut access_text = match (r, w) {
        (true, true) => "rw",
        (true, false) => "ro",
        (false, true) => "wo",
        _ => "-",
    }
    .to_string();
    if access & 0x40 != 0 {
        access_text.push_str(", RxPDO");
    }
    if access & 0x80 != 0 {
        access_text.push_str(", TxPDO");
    }
    Some(EntryInfo {
        sub,
        data_type,
        bits,
        access,
        access_text,
        name,
        type_name: type_name(data_type).into(),
        default,
        min,
        max,
    })
}

/// The name of a CoE data type.
pub fn type_name(t: u16) -> &'static str {
    match t {
        0x0001 => "BOOL",
        0x0002 => "INT8",
        0x0003 => "INT16",
        0x0004 => "INT32",
        0x0005 => "UINT8",
        0x0006 => "UINT16",
        0x0007 => "UINT32",
        0x0008 => "REAL32",
        0x0009 => "VISIBLE_STRING",
        0x000A => "OCTET_STRING",
        0x0015 => "INT64",
        0x001B => "UINT64",
        0x002A => "RECORD",
        _ => "other",
    }
}

/// (signed, bytes) of an integer data type.
fn int_type(t: u16) -> Option<(bool, usize)> {
    Some(match t {
        0x0001 | 0x0005 => (false, 1),
        0x0002 => (true, 1),
        0x0003 => (true, 2),
        0x0004 => (true, 4),
        0x0006 => (false, 2),
        0x0007 => (false, 4),
        0x0015 => (true, 8),
        0x001B => (false, 8),
        _ => return None,
    })
}

/// A value of data type `t` as text (integers in decimal, strings as text, other
/// types as hex bytes).
pub fn format_value(t: u16, v: &[u8]) -> String {
    if let Some((signed, n)) = int_type(t) {
        let mut b = [0u8; 8];
        let k = n.min(v.len());
        b[..k].copy_from_slice(&v[..k]);
        let u = u64::from_le_bytes(b);
        if signed {
            let shift = 64 - 8 * n as u32;
            return (((u << shift) as i64) >> shift).to_string();
        }
        return u.to_string();
    }
    match t {
        0x0008 if v.len() >= 4 => f32::from_le_bytes([v[0], v[1], v[2], v[3]]).to_string(),
        0x0009 => String::from_utf8_lossy(v)
            .trim_end_matches('\0')
            .to_string(),
        _ => v
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<Vec<_>>()
            .join(" "),
    }
}

/// The bytes of `text` as a value of data type `t` (`bits` long): the check before
/// anything goes to the drive. An error says why in words.
pub fn parse_value(t: u16, bits: u16, text: &str) -> Result<Vec<u8>, String> {
    let s = text.trim();
    if let Some((signed, n)) = int_type(t) {
        let n = n.min(usize::from(bits).div_ceil(8).max(1));
        let v: i128 = match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
            Some(h) => i128::from_str_radix(h, 16),
            None => s.parse(),
        }
        .map_err(|_| format!("'{s}' is not a whole number"))?;
        let bits = 8 * n as u32;
        let (lo, hi) = if signed {
            (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
        } else {
            (0, (1i128 << bits) - 1)
        };
        if v < lo || v > hi {
            return Err(format!("{v} does not fit {} ({lo}..{hi})", type_name(t)));
        }
        return Ok((v as i64).to_le_bytes()[..n].to_vec());
    }
    match t {
        0x0008 => s
            .parse::<f32>()
            .map(|f| f.to_le_bytes().to_vec())
            .map_err(|_| format!("'{s}' is not a number")),
        0x0009 => Ok(s.as_bytes().to_vec()),
        _ => s
            .split_whitespace()
            .map(|b| u8::from_str_radix(b, 16).map_err(|_| format!("'{b}' is not a hex byte")))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_round_trip_and_bad_text_is_refused() {
        assert_eq!(parse_value(0x0003, 16, "-2").unwrap(), vec![0xFE, 0xFF]);
        assert_eq!(format_value(0x0003, &[0xFE, 0xFF]), "-2");
        assert_eq!(parse_value(0x0007, 32, "0x10").unwrap(), vec![16, 0, 0, 0]);
        assert_eq!(format_value(0x0009, b"1.2\0"), "1.2");
        assert!(parse_value(0x0005, 8, "256")
            .unwrap_err()
            .contains("does not fit"));
        assert!(parse_value(0x0004, 32, "x1")
            .unwrap_err()
            .contains("whole number"));
    }

    #[test]
    fn entry_description_with_range() {
        // 0x2000:0, UINT16, 16 bits, rw, default 3200, min 100, max 6000, name.
        let mut d = vec![0x00, 0x20, 0, 0x70, 6, 0, 16, 0, 0x3F, 0];
        for v in [3200u16, 100, 6000] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.extend_from_slice(b"Current [mA]");
        let e = parse_entry(&d).unwrap();
        assert_eq!(e.default.as_deref(), Some("3200"));
        assert_eq!(
            (e.min.as_deref(), e.max.as_deref()),
            (Some("100"), Some("6000"))
        );
        assert_eq!(e.name, "Current [mA]");
        assert_eq!(e.access_text, "rw");
    }
}
