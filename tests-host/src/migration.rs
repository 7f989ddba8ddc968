//! Migration guides from the drives this one replaces (`docs/migration/<drive>.md`,
//! `cargo xtask migration`).
//!
//! Each guide is one [`Guide`]: per seed drive, every object, parameter, DIP switch,
//! LED code and alarm its manual documents, with this drive's equivalent. A row names
//! either a dictionary entry — with the access and PDO mapping the guide promises,
//! which `tests/migration_guides.rs` checks against `firmware::dictionary::OBJECTS` —
//! or a fault, an AL status code or a DIP setting of this firmware, whose details
//! (emergency code, LED pattern, current table) are read from the firmware's own
//! tables when the guide is written. Only the column "there" and the notes are
//! written by hand.

use std::fmt::Write as _;

use ecat_slave_stack::leds::{ErrCondition, Pattern};
use ecat_slave_stack::od::{self, Object, ObjectKey, PdoMappable};
use firmware::faults::FaultKind;

mod dp3cl;
mod e5;
mod est584;
mod hiwin;

/// The four guides.
pub const GUIDES: [&Guide; 4] = [&e5::GUIDE, &est584::GUIDE, &dp3cl::GUIDE, &hiwin::GUIDE];

/// One migration guide.
#[derive(Debug)]
pub struct Guide {
    /// File name under `docs/migration/`.
    pub file: &'static str,
    /// The drive replaced.
    pub drive: &'static str,
    /// What the drive is, one line.
    pub summary: &'static str,
    /// Tables, in order.
    pub sections: &'static [Section],
    /// Start-up list (SDO writes, PDO maps) of a master configured for that drive:
    /// what to change.
    pub startup: &'static [Change],
    /// What a table cannot say, one paragraph each.
    pub notes: &'static [&'static str],
}

/// One table of a guide.
#[derive(Debug)]
pub struct Section {
    /// Heading.
    pub title: &'static str,
    /// Rows.
    pub rows: &'static [Row],
}

/// One item of the seed drive's manual and its equivalent here.
#[derive(Debug)]
pub struct Row {
    /// The item there: object (`0x6060`, `0x6099:01`), parameter (`P4-00`), switch,
    /// LED code, alarm.
    pub there: &'static str,
    /// What it does there (own words).
    pub meaning: &'static str,
    /// The equivalent here.
    pub here: Here,
    /// What differs, if anything.
    pub note: &'static str,
}

/// Access of an entry as the guide states it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Acc {
    /// Read-only.
    Ro,
    /// Readable and writable (in at least one state).
    Rw,
}

impl Acc {
    /// The ESI access text.
    pub fn text(self) -> &'static str {
        match self {
            Acc::Ro => "ro",
            Acc::Rw => "rw",
        }
    }
}

/// An equivalent here.
#[derive(Debug, Clone, Copy)]
pub enum Here {
    /// Dictionary entry `index:sub` with the stated access and PDO mapping.
    Entry(u16, u8, Acc, PdoMappable),
    /// A whole object (every sub-index as the dictionary describes it).
    Object(u16),
    /// A fault of this drive (emergency code, 0x1001 bits, red LED from the fault table).
    Fault(FaultKind),
    /// An AL status code (ETG.1000.6) this drive reports, with its ERR LED pattern.
    Al(u16),
    /// A setting that is not an object (DIP switch, LED, behaviour), in words.
    Text(&'static str),
    /// No equivalent (the note says why and what to do).
    None,
}

/// One change to a master's start-up list.
#[derive(Debug)]
pub struct Change {
    /// The write or map entry the master has for the seed drive.
    pub was: &'static str,
    /// What to write here instead (or "keep").
    pub now: &'static str,
    /// Why.
    pub why: &'static str,
}

/// Why a row's equivalent does not match the dictionary (`None`: it does).
pub fn check(objects: &'static [Object], here: Here) -> Option<String> {
    match here {
        Here::Entry(index, sub, acc, pdo) => {
            let Ok(e) = od::find_entry(objects, ObjectKey::new(index, sub)) else {
                return Some(format!("{index:#06x}:{sub} is not in the dictionary"));
            };
            let (a, p) = (e.access.esi(), e.pdo_mappable());
            (a != acc.text() || p != pdo).then(|| {
                format!(
                    "{index:#06x}:{sub}: the guide says {} / {pdo:?}, the dictionary {a} / {p:?}",
                    acc.text()
                )
            })
        }
        Here::Object(index) => od::find(objects, index)
            .is_none()
            .then(|| format!("{index:#06x} is not in the dictionary")),
        Here::Al(code) => ecat_slave_stack::al_status::AlStatusCode::from_code(code)
            .is_none()
            .then(|| format!("AL status code {code:#06x} is not one of the stack's")),
        Here::Fault(_) | Here::Text(_) | Here::None => None,
    }
}

fn pdo_text(p: PdoMappable) -> &'static str {
    match p {
        PdoMappable::No => "no",
        PdoMappable::Rx => "RxPDO",
        PdoMappable::Tx => "TxPDO",
        PdoMappable::RxTx => "Rx/TxPDO",
    }
}

fn pattern_text(p: Pattern) -> &'static str {
    match p {
        Pattern::Off => "off",
        Pattern::On => "on",
        Pattern::Flickering => "flickering",
        Pattern::Blinking => "blinking",
        Pattern::SingleFlash => "single flash",
        Pattern::DoubleFlash => "double flash",
    }
}

/// Table cells (here, name, access, PDO, unit) of an equivalent.
fn cells(objects: &'static [Object], here: Here) -> [String; 5] {
    let dash = || "—".to_string();
    match here {
        Here::Entry(index, sub, _, _) => {
            match od::find_entry(objects, ObjectKey::new(index, sub)) {
                Ok(e) => [
                    format!("0x{index:04X}:{sub:02X}"),
                    e.name().to_string(),
                    e.access.esi().to_string(),
                    pdo_text(e.pdo_mappable()).to_string(),
                    match e.unit_text() {
                        "" => dash(),
                        u => u.to_string(),
                    },
                ],
                Err(_) => [
                    format!("0x{index:04X}:{sub:02X}"),
                    "MISSING".into(),
                    dash(),
                    dash(),
                    dash(),
                ],
            }
        }
        Here::Object(index) => match od::find(objects, index) {
            Some(o) => [
                format!("0x{index:04X}"),
                o.name().to_string(),
                dash(),
                dash(),
                dash(),
            ],
            None => [
                format!("0x{index:04X}"),
                "MISSING".into(),
                dash(),
                dash(),
                dash(),
            ],
        },
        Here::Fault(k) => {
            let led = k
                .flashes()
                .map_or("ERR LED".to_string(), |n| format!("red LED {n} flashes"));
            [
                format!("fault {}", k as u8),
                format!(
                    "0x603F = 0x{:04X}, 0x1001 = 0x{:02X}, {led}",
                    k.code(),
                    k.error_register()
                ),
                dash(),
                dash(),
                dash(),
            ]
        }
        Here::Al(code) => {
            let text = ecat_slave_stack::al_status::AlStatusCode::from_code(code)
                .map_or("?", |c| c.text());
            let led = ErrCondition::from_al_status(0x10, code).pattern();
            [
                format!("AL status code 0x{code:04X}"),
                format!("{text}; ERR LED {}", pattern_text(led)),
                dash(),
                dash(),
                dash(),
            ]
        }
        Here::Text(t) => [t.to_string(), dash(), dash(), dash(), dash()],
        Here::None => ["none".to_string(), dash(), dash(), dash(), dash()],
    }
}

fn cell(s: &str) -> String {
    s.replace('|', "\\|")
}

/// The Markdown guide, with the details of the equivalents from `objects` (the
/// product dictionary) and the firmware's tables.
pub fn render(g: &Guide, objects: &'static [Object]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Migrating from the {}\n", g.drive);
    let _ = writeln!(s, "{}\n", g.summary);
    let _ = writeln!(
        s,
        "Every item of the {}'s manual with this drive's equivalent. The columns \
         \"name here\", \"access\", \"PDO\" and \"unit\" come from this drive's object \
         dictionary (`docs/object-dictionary.md`); faults show their emergency code, \
         error register and LED as the firmware reports them; AL status codes show the \
         ERR LED pattern (ETG.1300) this drive gives them.\n",
        g.drive
    );
    for sec in g.sections {
        let _ = writeln!(s, "## {}\n", sec.title);
        let _ = writeln!(
            s,
            "| there | meaning there | here | name here | access | PDO | unit | note |\n\
             |---|---|---|---|---|---|---|---|"
        );
        for r in sec.rows {
            let [here, name, acc, pdo, unit] = cells(objects, r.here);
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                cell(r.there),
                cell(r.meaning),
                cell(&here),
                cell(&name),
                acc,
                pdo,
                cell(&unit),
                cell(r.note)
            );
        }
        let _ = writeln!(s);
    }
    if !g.startup.is_empty() {
        let _ = writeln!(s, "## The master's start-up list\n");
        let _ = writeln!(
            s,
            "| written for the {} | here | why |\n|---|---|---|",
            g.drive
        );
        for c in g.startup {
            let _ = writeln!(s, "| {} | {} | {} |", cell(c.was), cell(c.now), cell(c.why));
        }
        let _ = writeln!(s);
    }
    if !g.notes.is_empty() {
        let _ = writeln!(s, "## Differences a table cannot show\n");
        for n in g.notes {
            let _ = writeln!(s, "{n}\n");
        }
    }
    let _ = writeln!(
        s,
        "Generated by `cargo xtask migration` from the tables in `tests-host/src/migration/` \
         and the firmware's own tables; do not edit by hand."
    );
    s
}

/// Rows whose equivalent does not match `objects`, as messages.
pub fn problems(g: &Guide, objects: &'static [Object]) -> Vec<String> {
    g.sections
        .iter()
        .flat_map(|sec| sec.rows.iter())
        .filter_map(|r| check(objects, r.here).map(|m| format!("{}: {}: {m}", g.file, r.there)))
        .collect()
}

/// A row.
pub const fn row(
    there: &'static str,
    meaning: &'static str,
    here: Here,
    note: &'static str,
) -> Row {
    Row {
        there,
        meaning,
        here,
        note,
    }
}

/// Read-write entry, not mappable.
pub const fn rw(index: u16, sub: u8) -> Here {
    Here::Entry(index, sub, Acc::Rw, PdoMappable::No)
}

/// Read-write entry, RxPDO-mappable.
pub const fn rx(index: u16, sub: u8) -> Here {
    Here::Entry(index, sub, Acc::Rw, PdoMappable::Rx)
}

/// Read-only entry, TxPDO-mappable.
pub const fn tx(index: u16, sub: u8) -> Here {
    Here::Entry(index, sub, Acc::Ro, PdoMappable::Tx)
}

/// Read-only entry, not mappable.
pub const fn ro(index: u16, sub: u8) -> Here {
    Here::Entry(index, sub, Acc::Ro, PdoMappable::No)
}

/// Read-write entry, TxPDO-mappable (counters with a reset write).
pub const fn rw_tx(index: u16, sub: u8) -> Here {
    Here::Entry(index, sub, Acc::Rw, PdoMappable::Tx)
}
