//! The Markdown reference of the object dictionary (`cargo xtask od-doc`).

use super::*;

/// Writes a Markdown reference of the object dictionary (`cargo xtask od-doc`): one
/// section per object with its description and a table of its entries (sub-index, name,
/// type, bits, access per ESM state, PDO mapping, range, default, unit, saved).
pub fn write_reference(objects: &[Object], w: &mut impl core::fmt::Write) -> core::fmt::Result {
    writeln!(w, "# Object dictionary\n")?;
    writeln!(
        w,
        "Access: `r`/`w` followed by the ESM states where it applies \
         (P = Pre-Op, S = Safe-Op, O = Op). PDO: Rx/Tx mappable.\n"
    )?;
    writeln!(w, "| Index | Name | Object code | Entries |")?;
    writeln!(w, "|---|---|---|---|")?;
    for o in objects {
        write!(w, "| 0x{:04X} | ", o.index)?;
        write_md(w, o.name().chars())?;
        writeln!(
            w,
            " | {} | {} |",
            object_code_name(o.code()),
            o.entries().len()
        )?;
    }
    for o in objects {
        write!(w, "\n## 0x{:04X} ", o.index)?;
        write_md(w, o.name().chars())?;
        writeln!(w, " ({})\n", object_code_name(o.code()))?;
        if !o.description().is_empty() {
            write_md(w, o.description().chars())?;
            writeln!(w, "\n")?;
        }
        writeln!(
            w,
            "| Sub | Name | Type | Bits | Access | PDO | Min | Max | Default | Unit | Saved |"
        )?;
        writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|")?;
        for e in o.entries() {
            write!(w, "| {} | ", e.sub)?;
            write_md(w, e.name().chars())?;
            write!(w, " | {} | {} | ", e.data_type.esi_name(), e.bits())?;
            write_access(w, e.access)?;
            let pdo = match e.pdo_mappable() {
                PdoMappable::No => "-",
                PdoMappable::Rx => "Rx",
                PdoMappable::Tx => "Tx",
                PdoMappable::RxTx => "Rx/Tx",
            };
            write!(w, " | {} | ", pdo)?;
            if has_numeric_range(e.data_type) {
                write!(w, "{} | {} | ", e.min(), e.max())?;
            } else {
                write!(w, "- | - | ")?;
            }
            match e.default_value() {
                DefaultValue::None => write!(w, "-")?,
                // Codes, identities and mapping words also in hex.
                DefaultValue::Int(v) if shows_hex(e, v) => write!(w, "{} (0x{:X})", v, v)?,
                DefaultValue::Int(v) => write!(w, "{}", v)?,
                DefaultValue::Text(t) => {
                    write!(w, "\"")?;
                    write_md(w, t.chars())?;
                    write!(w, "\"")?;
                }
            }
            write!(w, " | ")?;
            if e.unit_text().is_empty() {
                write!(w, "-")?;
            } else {
                write_md(w, e.unit_text().chars())?;
            }
            writeln!(w, " | {} |", if e.is_saved() { "yes" } else { "no" })?;
        }
    }
    Ok(())
}

/// True for a default worth showing in hex too: an unsigned entry of 16 bits or
/// more without a unit (a code, an identity or a mapping word) of at least 0x100.
fn shows_hex(e: &Entry, v: i64) -> bool {
    matches!(
        e.data_type,
        DataType::Unsigned16 | DataType::Unsigned32 | DataType::Unsigned64
    ) && e.unit_text().is_empty()
        && v >= 0x100
}

fn object_code_name(c: ObjectCode) -> &'static str {
    match c {
        ObjectCode::Var => "VAR",
        ObjectCode::Array => "ARRAY",
        ObjectCode::Record => "RECORD",
    }
}

fn write_access(w: &mut impl core::fmt::Write, a: Access) -> core::fmt::Result {
    const STATES: [(EsmState, char); 3] = [
        (EsmState::PreOp, 'P'),
        (EsmState::SafeOp, 'S'),
        (EsmState::Op, 'O'),
    ];
    let mut any = false;
    for (kind, test) in [
        ('r', Access::readable_in as fn(Access, EsmState) -> bool),
        ('w', Access::writable_in),
    ] {
        if STATES.iter().any(|(s, _)| test(a, *s)) {
            if any {
                write!(w, " ")?;
            }
            write!(w, "{}", kind)?;
            for (s, c) in STATES {
                if test(a, s) {
                    write!(w, "{}", c)?;
                }
            }
            any = true;
        }
    }
    if !any {
        write!(w, "-")?;
    }
    Ok(())
}

/// Writes text into a Markdown table cell: `|` escaped, line breaks as spaces.
fn write_md(w: &mut impl core::fmt::Write, s: impl IntoIterator<Item = char>) -> core::fmt::Result {
    for c in s {
        match c {
            '|' => w.write_str("\\|")?,
            '\n' | '\r' => w.write_char(' ')?,
            c => w.write_char(c)?,
        }
    }
    Ok(())
}
