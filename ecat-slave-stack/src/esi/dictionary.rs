//! The dictionary part of the ESI: data types (`DataTypes`) and objects (`Objects`).

use super::*;

/// The ESI type name of an entry ("UDINT", "STRING(16)").
pub(super) struct TypeName<'a>(pub(super) &'a Entry);

impl fmt::Display for TypeName<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0.data_type {
            DataType::VisibleString => write!(f, "STRING({})", self.0.bits() / 8),
            DataType::OctetString => write!(f, "OCTET_STRING({})", self.0.bits() / 8),
            t => f.write_str(t.esi_name()),
        }
    }
}

/// Hex bytes ("0A1B"), little-endian, of a default value of `len` bytes.
pub(super) struct Hex<'a>(pub(super) &'a [u8]);

impl fmt::Display for Hex<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in self.0 {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

fn pdo_flag(p: PdoMappable) -> Option<&'static str> {
    match p {
        PdoMappable::No => None,
        PdoMappable::Rx => Some("R"),
        PdoMappable::Tx => Some("T"),
        PdoMappable::RxTx => Some("RT"),
    }
}

fn write_access<W: Write>(out: &mut W, a: Access) -> fmt::Result {
    let restriction = if a == Access::RW_PREOP {
        Some("PreOP")
    } else if a == Access::RW_PREOP_SAFEOP {
        Some("PreOP_SafeOP")
    } else {
        None
    };
    match restriction {
        Some(r) => write!(
            out,
            "<Access WriteRestrictions=\"{r}\">{}</Access>",
            a.esi()
        ),
        None => write!(out, "<Access>{}</Access>", a.esi()),
    }
}

fn write_flags<W: Write>(out: &mut W, e: &Entry) -> fmt::Result {
    out.write_str("<Flags>")?;
    write_access(out, e.access)?;
    if let Some(p) = pdo_flag(e.pdo_mappable()) {
        write!(out, "<PdoMapping>{p}</PdoMapping>")?;
    }
    out.write_str("</Flags>")
}

fn write_default<W: Write>(out: &mut W, e: &Entry) -> fmt::Result {
    match e.default_value() {
        DefaultValue::None => Ok(()),
        // An entry whose value the application supplies (0x10F3 messages): none.
        DefaultValue::Text("") => Ok(()),
        DefaultValue::Text(t) => write!(out, "<DefaultString>{}</DefaultString>", Esc(t)),
        DefaultValue::Int(v) => {
            let bytes = v.to_le_bytes();
            let n = e.byte_len().clamp(1, 8);
            write!(out, "<DefaultData>{}</DefaultData>", Hex(&bytes[..n]))
        }
    }
}

/// Bit offsets of a record's entries: sub 0 at 0, the next at 16, then packed, an
/// entry of a byte or more starting on a byte (0x10F3: BOOL at 40, UINT at 48).
fn bit_offsets(
    o: &Object,
    mut f: impl FnMut(&Entry, u32) -> fmt::Result,
) -> Result<u32, fmt::Error> {
    let mut off = 0u32;
    for (i, e) in o.entries().iter().enumerate() {
        if e.bits() >= 8 {
            off = off.next_multiple_of(8);
        }
        f(e, off)?;
        off += e.bits() as u32;
        if i == 0 && o.entries().len() > 1 {
            off = off.max(16);
        }
    }
    Ok(off)
}

pub(super) fn write_data_types<W: Write>(out: &mut W, objects: &[Object]) -> fmt::Result {
    out.write_str("<DataTypes>\n")?;
    let all = || objects.iter().flat_map(|o| o.entries().iter());
    // Fixed-size base types, each once.
    for t in DataType::ALL {
        if t.is_variable_length() || !all().any(|e| e.data_type == t) {
            continue;
        }
        let (bits, _, _) = crate::od::type_range(t);
        writeln!(
            out,
            "<DataType><Name>{}</Name><BitSize>{bits}</BitSize></DataType>",
            t.esi_name()
        )?;
    }
    // Strings, one per distinct (type, length).
    for (i, e) in all().enumerate() {
        if !e.data_type.is_variable_length() {
            continue;
        }
        if all()
            .take(i)
            .any(|p| p.data_type == e.data_type && p.bits() == e.bits())
        {
            continue;
        }
        writeln!(
            out,
            "<DataType><Name>{}</Name><BitSize>{}</BitSize></DataType>",
            TypeName(e),
            e.bits()
        )?;
    }
    // Records and arrays.
    for o in objects.iter().filter(|o| o.code() != ObjectCode::Var) {
        write!(out, "<DataType><Name>DT{:04X}</Name>", o.index)?;
        let total = bit_offsets(o, |_, _| Ok(()))?;
        writeln!(out, "<BitSize>{total}</BitSize>")?;
        bit_offsets(o, |e, off| {
            write!(
                out,
                "<SubItem><SubIdx>{}</SubIdx><Name>{}</Name><Type>{}</Type><BitSize>{}</BitSize><BitOffs>{off}</BitOffs>",
                e.sub,
                Esc(e.name()),
                TypeName(e),
                e.bits()
            )?;
            write_flags(out, e)?;
            out.write_str("</SubItem>\n")
        })?;
        out.write_str("</DataType>\n")?;
    }
    out.write_str("</DataTypes>\n")
}

pub(super) fn write_objects<W: Write>(out: &mut W, objects: &[Object]) -> fmt::Result {
    out.write_str("<Objects>\n")?;
    for o in objects {
        write!(
            out,
            "<Object><Index>#x{:04X}</Index><Name>{}</Name>",
            o.index,
            Esc(o.name())
        )?;
        match (o.code(), o.entries().first()) {
            (ObjectCode::Var, Some(e)) => {
                write!(
                    out,
                    "<Type>{}</Type><BitSize>{}</BitSize>",
                    TypeName(e),
                    e.bits()
                )?;
                out.write_str("<Info>")?;
                write_default(out, e)?;
                out.write_str("</Info>")?;
                write_flags(out, e)?;
            }
            _ => {
                let total = bit_offsets(o, |_, _| Ok(()))?;
                write!(
                    out,
                    "<Type>DT{:04X}</Type><BitSize>{total}</BitSize><Info>",
                    o.index
                )?;
                for e in o.entries() {
                    write!(out, "<SubItem><Name>{}</Name><Info>", Esc(e.name()))?;
                    write_default(out, e)?;
                    out.write_str("</Info></SubItem>")?;
                }
                out.write_str("</Info><Flags><Access>ro</Access></Flags>")?;
            }
        }
        out.write_str("</Object>\n")?;
    }
    out.write_str("</Objects>\n")
}
