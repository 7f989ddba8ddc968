//! `drive-docs`: the files generated from the drive's one description.
//!
//! ```text
//! drive-docs esi DIR      ESI XML files and SII EEPROM images into DIR
//! drive-docs od-doc FILE  Markdown reference of the object dictionary into FILE
//! drive-docs faults-doc FILE  Markdown table of the drive's faults into FILE
//! drive-docs migration DIR  the migration guides (`tests_host::migration`) into DIR
//! ```
//!
//! `esi DIR` writes, per ESC flavour of the board (LAN9252, ET1100), one ESI file
//! `ecs-<esc>.xml` that holds both product variants (ECS-HS hybrid servo and ECS-OL
//! open-loop stepper: different product codes, so one file can list both), one SII
//! image `ecs-<hs|ol>-<esc>.bin` per variant and flavour, and a `README.md` listing
//! them. The two ESI files differ only in the PDI configuration words (`ConfigData`):
//! install the one matching the board's ESC in the master, not both (they describe the
//! same product codes and revision).
//!
//! Sources: `firmware::identity::device_description` (identity, SyncManagers,
//! mailbox, DC), `firmware::dictionary::OBJECTS` (the dictionary) and
//! `firmware::pdo_defaults::PDO_DEFAULTS` (the default mapping). The table of
//! `firmware::dictionary` describes the hybrid servo; the entries whose power-up value
//! depends on the variant (0x1000, 0x1008, 0x1018:02, 0x2024) get, in each variant's
//! ESI device, the value that variant's drive reports when read through its own
//! dictionary (`firmware::drive::Drive`), and the mapping and
//! assignment objects get the default mapping as their default values.
//!
//! `od-doc FILE` writes `ecat_slave_stack::od::write_reference` of the hybrid-servo
//! dictionary, followed by the list of entries in which the open-loop variant differs.
//!
//! `faults-doc FILE` writes the fault table (`firmware::faults::TABLE`) and the
//! diagnosis texts of the faults (`firmware::diagnosis`).
#![deny(clippy::undocumented_unsafe_blocks)]

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::OnceLock;

use ecat_slave_stack::esi::{self, EsiDevice, EsiError, PdoMap};
use ecat_slave_stack::od::Dictionary as _;
use ecat_slave_stack::od::{
    self, DataType, DefaultValue, Entry, EntryDesc, Object, ObjectDesc, ObjectKey,
};
use ecat_slave_stack::pdo::PdoConfig;
use ecat_slave_stack::sii::{self, DeviceDescription, EscFlavour, SiiError};
use firmware::drive::Drive;
use firmware::identity::{self, Variant};
use firmware::pdo_defaults::PDO_DEFAULTS;

/// The product variants and their short file-name tags.
pub const VARIANTS: [(Variant, &str); 2] =
    [(Variant::HybridServo, "hs"), (Variant::OpenLoop, "ol")];

/// The ESC flavours of the board and their file-name tags.
pub const FLAVOURS: [(EscFlavour, &str); 2] = [
    (EscFlavour::Lan9252, "lan9252"),
    (EscFlavour::Et1100, "et1100"),
];

/// Name of the ESI file of `esc`.
pub fn esi_file_name(esc: EscFlavour) -> String {
    format!("ecs-{}.xml", flavour_tag(esc))
}

/// Name of the SII image of `variant` on `esc`.
pub fn sii_file_name(variant: Variant, esc: EscFlavour) -> String {
    format!("ecs-{}-{}.bin", variant_tag(variant), flavour_tag(esc))
}

fn variant_tag(v: Variant) -> &'static str {
    VARIANTS
        .iter()
        .find(|(x, _)| *x == v)
        .map_or("?", |(_, t)| t)
}

/// The chip's name as its maker writes it.
pub fn flavour_label(e: EscFlavour) -> &'static str {
    match e {
        EscFlavour::Lan9252 => "LAN9252",
        EscFlavour::Et1100 => "ET1100",
    }
}

fn flavour_tag(e: EscFlavour) -> &'static str {
    FLAVOURS
        .iter()
        .find(|(x, _)| *x == e)
        .map_or("?", |(_, t)| t)
}

/// The device description of the generic image (serial number 0).
pub fn description(variant: Variant, esc: EscFlavour) -> DeviceDescription {
    identity::device_description(variant, esc, 0)
}

/// Where a power-up value comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// `firmware::comm` (0x1000-0x10FF: identity, names).
    Comm,
    /// `firmware::params` (vendor parameters: 0x2024 follows the variant).
    Params,
    /// `ecat_slave_stack::pdo::PdoConfig` with the product's default mapping.
    Pdo,
    /// `firmware::cia402` entries that follow the variant's loop mode (0x6502: CST
    /// only in closed loop).
    Cia402,
}

/// Which of the variant-aware modules serves `index`.
pub fn source_of(index: u16) -> Option<Source> {
    let has = |objects: &[ObjectDesc]| objects.iter().any(|o| o.index == index);
    if has(firmware::comm::OBJECTS) {
        Some(Source::Comm)
    } else if has(firmware::params::OBJECTS) {
        Some(Source::Params)
    } else if has(ecat_slave_stack::pdo::OBJECTS) && is_mapping_or_assignment(index) {
        Some(Source::Pdo)
    } else if index == 0x6502 {
        Some(Source::Cia402)
    } else {
        None
    }
}

fn is_mapping_or_assignment(index: u16) -> bool {
    matches!(index, 0x1600..=0x1603 | 0x1A00..=0x1A03 | 0x1C12 | 0x1C13)
}

/// The raw little-endian bytes an SDO upload of `index:sub` returns on a freshly
/// powered-up drive of `variant`: through `firmware::drive::Drive`'s dictionary for
/// the drive's objects, through `PdoConfig` with the product's defaults for the
/// mapping and assignment objects (the slave runtime serves those). None: refused.
pub fn power_up_bytes(variant: Variant, index: u16, sub: u8) -> Option<Vec<u8>> {
    let mut buf = [0u8; 256];
    let n = if is_mapping_or_assignment(index) {
        PdoConfig::new(PDO_DEFAULTS)
            .read(ObjectKey::new(index, sub), &mut buf)
            .ok()?
    } else {
        Drive::new(variant, 0)
            .read(ObjectKey::new(index, sub), &mut buf)
            .ok()?
    };
    Some(buf[..n].to_vec())
}

/// The power-up value of `index:sub` as a default value of `entry`'s type.
pub fn power_up_value(variant: Variant, index: u16, entry: &EntryDesc) -> Option<DefaultValue> {
    let bytes = power_up_bytes(variant, index, entry.sub())?;
    match entry.data_type() {
        DataType::VisibleString => {
            let s = String::from_utf8(bytes).ok()?;
            Some(DefaultValue::Text(Box::leak(s.into_boxed_str())))
        }
        DataType::OctetString | DataType::Real32 => None,
        t => od::decode_int(t, &bytes).map(DefaultValue::Int),
    }
}

/// True when `a` and `b` are the same default.
pub fn same_default(a: DefaultValue, b: DefaultValue) -> bool {
    match (a, b) {
        (DefaultValue::None, DefaultValue::None) => true,
        (DefaultValue::Int(x), DefaultValue::Int(y)) => x == y,
        (DefaultValue::Text(x), DefaultValue::Text(y)) => x == y,
        _ => false,
    }
}

/// The default `entry` of `index` has in `variant`'s description: the power-up value
/// when the entry has a default that depends on the variant (comm, params) or belongs
/// to the product's default mapping (mapping and assignment objects); the table's
/// default otherwise.
pub fn variant_default(variant: Variant, index: u16, entry: &EntryDesc) -> DefaultValue {
    let live = || power_up_value(variant, index, entry);
    match (source_of(index), entry.default_value()) {
        (Some(Source::Pdo), _) => live().unwrap_or(entry.default_value()),
        (Some(_), DefaultValue::None) | (None, _) => entry.default_value(),
        (Some(_), d) => live().unwrap_or(d),
    }
}

/// `firmware::dictionary::OBJECTS` with the defaults of `variant` (see
/// [`variant_default`]): the owners' tables with those defaults, packed as the
/// firmware packs them. Same objects, entries, names, types, access and mapping.
pub fn variant_objects(variant: Variant) -> &'static [Object] {
    static CACHE: [OnceLock<&'static [Object]>; 2] = [OnceLock::new(), OnceLock::new()];
    let slot = VARIANTS
        .iter()
        .position(|(v, _)| *v == variant)
        .unwrap_or(0);
    CACHE[slot].get_or_init(|| {
        let parts: Vec<&'static [ObjectDesc]> = firmware::dictionary::PARTS
            .iter()
            .map(|part| {
                let objects: Vec<ObjectDesc> = part
                    .iter()
                    .map(|o| {
                        let entries: Vec<EntryDesc> = o
                            .entries()
                            .iter()
                            .map(|e| e.with_default_value(variant_default(variant, o.index, e)))
                            .collect();
                        o.with_entries(Box::leak(entries.into_boxed_slice()))
                    })
                    .collect();
                &*Box::leak(objects.into_boxed_slice())
            })
            .collect();
        od::pack::leak(&parts, firmware::dictionary::VOCABULARY)
    })
}

/// One difference between two variants' descriptions.
#[derive(Debug, Clone, Copy)]
pub struct Difference {
    /// Object index.
    pub index: u16,
    /// The entry (its default is the first variant's).
    pub a: &'static Entry,
    /// The same entry in the second variant.
    pub b: &'static Entry,
}

/// Entries whose default differs between the descriptions of `a` and `b`.
pub fn differences(a: Variant, b: Variant) -> Vec<Difference> {
    let (oa, ob) = (variant_objects(a), variant_objects(b));
    oa.iter()
        .zip(ob)
        .flat_map(|(x, y)| {
            x.entries()
                .iter()
                .zip(y.entries())
                .filter_map(move |(ea, eb)| {
                    (!same_default(ea.default_value(), eb.default_value())).then_some(Difference {
                        index: x.index,
                        a: ea,
                        b: eb,
                    })
                })
        })
        .collect()
}

/// The default PDOs of `variant` on `esc` (what the ESI's RxPdo/TxPdo list).
pub fn pdo_maps(variant: Variant, esc: EscFlavour) -> Vec<PdoMap> {
    let d = description(variant, esc);
    esi::pdo_maps(&d, variant_objects(variant), &PDO_DEFAULTS)
        .into_iter()
        .collect()
}

/// The ESI document for boards with `esc`: both variants.
pub fn esi_document(esc: EscFlavour) -> Result<String, EsiError> {
    let descs: Vec<DeviceDescription> =
        VARIANTS.iter().map(|(v, _)| description(*v, esc)).collect();
    let maps: Vec<Vec<PdoMap>> = VARIANTS.iter().map(|(v, _)| pdo_maps(*v, esc)).collect();
    let devices: Vec<EsiDevice<'_>> = VARIANTS
        .iter()
        .enumerate()
        .map(|(i, (v, _))| EsiDevice {
            desc: &descs[i],
            objects: variant_objects(*v),
            pdos: &maps[i],
            diag_texts: firmware::diagnosis::TEXTS,
        })
        .collect();
    let mut out = String::new();
    esi::write_devices(&devices, &mut out)?;
    Ok(out)
}

/// The SII EEPROM image of `variant` on `esc`: the whole EEPROM (`eeprom_bytes`),
/// unused bytes 0xFF as in an erased part.
pub fn sii_image(variant: Variant, esc: EscFlavour) -> Result<Vec<u8>, SiiError> {
    let d = description(variant, esc);
    let mut img = vec![0xFFu8; d.eeprom_bytes as usize];
    sii::build_with_pdos(
        &d,
        variant_objects(variant),
        &pdo_maps(variant, esc),
        &mut img,
    )?;
    Ok(img)
}

/// `README.md` of the ESI directory.
pub fn esi_readme() -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# ESI files and SII images\n");
    let _ = writeln!(
        s,
        "Generated by `cargo run -p tests-host --release --bin drive-docs -- esi DIR` \
         (`cargo xtask esi` writes them to `target/esi/`) from the same description as \
         the firmware: `firmware::identity`, `firmware::dictionary::OBJECTS` and \
         `firmware::pdo_defaults::PDO_DEFAULTS`. Do not edit by hand; \
         `tests-host/tests/esi_sii.rs` checks that these copies are up to date.\n"
    );
    let _ = writeln!(
        s,
        "Each ESI file describes both variants. The two files differ only in the \
         PDI configuration of the EEPROM (`ConfigData`): give your master the one for \
         the board's EtherCAT chip, not both (same product codes and revision).\n"
    );
    let _ = writeln!(s, "| file | contents |\n|---|---|");
    for (esc, _) in FLAVOURS {
        let _ = writeln!(
            s,
            "| `{}` | ESI (ETG.2000) for boards with the {} |",
            esi_file_name(esc),
            flavour_label(esc)
        );
    }
    for (esc, _) in FLAVOURS {
        for (v, _) in VARIANTS {
            let _ = writeln!(
                s,
                "| `{}` | SII EEPROM image, {} on the {} ({} bytes, serial 0) |",
                sii_file_name(v, esc),
                v.type_name(),
                flavour_label(esc),
                identity::EEPROM_BYTES
            );
        }
    }
    let _ = writeln!(
        s,
        "\n| variant | name | vendor ID | product code | revision |\n|---|---|---|---|---|"
    );
    for (v, _) in VARIANTS {
        let _ = writeln!(
            s,
            "| {} | {} | 0x{:08X} | 0x{:08X} | 0x{:08X} |",
            v.type_name(),
            v.device_name(),
            identity::VENDOR_ID,
            v.product_code(),
            identity::REVISION
        );
    }
    s
}

/// Every file `esi DIR` writes: (file name, contents).
pub fn esi_files() -> Result<BTreeMap<String, Vec<u8>>, String> {
    let mut files = BTreeMap::new();
    for (esc, _) in FLAVOURS {
        let xml = esi_document(esc).map_err(|e| format!("ESI for {esc:?}: {e:?}"))?;
        files.insert(esi_file_name(esc), xml.into_bytes());
        for (v, _) in VARIANTS {
            let img = sii_image(v, esc).map_err(|e| format!("SII {v:?} {esc:?}: {e:?}"))?;
            files.insert(sii_file_name(v, esc), img);
        }
    }
    files.insert("README.md".into(), esi_readme().into_bytes());
    Ok(files)
}

fn show(d: DefaultValue) -> String {
    match d {
        DefaultValue::None => "-".into(),
        DefaultValue::Int(v) if v >= 0x100 => format!("{v} (0x{v:X})"),
        DefaultValue::Int(v) => v.to_string(),
        DefaultValue::Text(t) => format!("\"{t}\""),
    }
}

/// The Markdown reference of the dictionary (hybrid servo) with the open-loop
/// variant's differences appended.
pub fn od_reference() -> String {
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = od::write_reference(variant_objects(Variant::HybridServo), &mut s);
    let _ = writeln!(
        s,
        "\n## Variant differences\n\n\
         The tables above describe the hybrid servo {hs} (\"{hsn}\"). The open-loop \
         stepper {ol} (\"{oln}\") has the same objects; these defaults differ:\n",
        hs = Variant::HybridServo.type_name(),
        hsn = Variant::HybridServo.device_name(),
        ol = Variant::OpenLoop.type_name(),
        oln = Variant::OpenLoop.device_name(),
    );
    let _ = writeln!(
        s,
        "| Index | Sub | Name | {} | {} |\n|---|---|---|---|---|",
        Variant::HybridServo.type_name(),
        Variant::OpenLoop.type_name()
    );
    for d in differences(Variant::HybridServo, Variant::OpenLoop) {
        let _ = writeln!(
            s,
            "| 0x{:04X} | {} | {} | {} | {} |",
            d.index,
            d.a.sub,
            d.a.name(),
            show(d.a.default_value()),
            show(d.b.default_value())
        );
    }
    let _ = writeln!(
        s,
        "\nGenerated by `cargo xtask od-doc` from `firmware::dictionary::OBJECTS`; \
         do not edit by hand."
    );
    s
}

/// `docs/faults.md`: the fault table as the firmware states it.
pub fn faults_reference() -> String {
    use firmware::faults::{FaultKind, Faults, TABLE};
    let yes = |b: bool| if b { "yes" } else { "no" };
    let mut s = String::from(
        "# Faults\n\n\
         Every fault the drive reports, as the firmware states it once \
         (`firmware::faults::TABLE`). The kinds are in order of severity: 0x603F and the \
         red LED show the most severe active fault. Every fault sends one emergency per \
         occurrence (manufacturer byte 0: the kind; bytes 1-2: the bus voltage in 0.1 V; \
         bytes 3-4: a detail), enters the history 0x2400-0x2406 and the diagnosis \
         history 0x10F3, sets the alarm output and takes the CiA 402 state machine to \
         Fault.\n\n\
         - **Reaction**: *power off at once* withdraws the power stage in the same \
         supervision tick (the motor coasts, the brake engages); *0x605E ramp* runs the \
         CiA 402 fault reaction 0x605E on the drive's clock, with the power stage on \
         until the motor stands, then Fault.\n\
         - **Latched**: survives a fault reset until power is cycled, unless \
         0x2057 = 1. Every fault also stays until its condition is gone.\n\
         - **0x2056 bit**: a set bit enables the detection; \"—\": 0x2056 cannot mask it. \
         The default mask is shown as *on* / *off*.\n\
         - **Protective**: the fault protects the hardware or the load. A detection of it \
         whose cause has already taken the torque away (a latched hardware trip, a \
         failed current-sensor check) is reported whatever 0x2056 says, so the drive \
         never sits in Operation enabled with no torque and nothing reported.\n\n\
         | kind | fault | 0x603F | 0x1001 | red LED | reaction | latched | 0x2056 bit | protective | detection |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    let defaults = Faults::default();
    for (k, i) in FaultKind::ALL.into_iter().zip(TABLE.iter()) {
        let led = match k.flashes() {
            Some(1) => "1 flash".into(),
            Some(n) => format!("{n} flashes"),
            None => "— (ERR LED)".into(),
        };
        let mask = match k.mask_bit() {
            Some(b) => format!("{b} ({})", if defaults.enabled(k) { "on" } else { "off" }),
            None => "—".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {} | 0x{:04X} | 0x{:02X} | {led} | {} | {} | {mask} | {} | {} |",
            k as u8,
            i.name,
            i.code,
            i.register,
            if i.cuts_power {
                "power off at once"
            } else {
                "0x605E ramp"
            },
            yes(i.latched),
            yes(i.protective),
            i.detection
        );
    }
    s.push_str(
        "\n## Diagnosis texts (0x10F3)\n\n\
         Each fault's emergency is also a diagnosis message (code 0xE800 with the \
         emergency code in bits 16-31) with this text; the parameters are the bus \
         voltage and the detail bytes.\n\n\
         | kind | text ID | text |\n|---|---|---|\n",
    );
    for k in FaultKind::ALL {
        let _ = writeln!(
            s,
            "| {} | 0x{:04X} | {} |",
            k as u8,
            firmware::diagnosis::fault_text_id(k),
            k.info().text
        );
    }
    s.push_str(
        "\nGenerated by `cargo xtask faults-doc` from `firmware::faults::TABLE`; do not \
         edit by hand.\n",
    );
    s
}

/// The migration guides (file name, text) over the hybrid-servo dictionary (the
/// variants have the same objects); an error names every row whose equivalent does
/// not match the dictionary.
pub fn migration_guides() -> Result<Vec<(String, String)>, String> {
    use tests_host::migration::{problems, render, GUIDES};
    let objects = variant_objects(Variant::HybridServo);
    let bad: Vec<String> = GUIDES.iter().flat_map(|g| problems(g, objects)).collect();
    if !bad.is_empty() {
        return Err(bad.join("\n"));
    }
    Ok(GUIDES
        .iter()
        .map(|g| (g.file.to_string(), render(g, objects)))
        .collect())
}

fn write_file(path: &Path, data: &[u8]) -> Result<(), String> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::write(path, data).map_err(|e| format!("{}: {e}", path.display()))?;
    println!("wrote {} ({} bytes)", path.display(), data.len());
    Ok(())
}

fn run(args: &[String]) -> Result<(), String> {
    match args {
        [cmd, dir] if cmd == "esi" => {
            let dir = Path::new(dir);
            for (name, data) in esi_files()? {
                write_file(&dir.join(name), &data)?;
            }
            Ok(())
        }
        [cmd, file] if cmd == "od-doc" => write_file(Path::new(file), od_reference().as_bytes()),
        [cmd, file] if cmd == "faults-doc" => {
            write_file(Path::new(file), faults_reference().as_bytes())
        }
        [cmd, dir] if cmd == "migration" => {
            for (name, text) in migration_guides()? {
                write_file(&Path::new(dir).join(name), text.as_bytes())?;
            }
            Ok(())
        }
        _ => Err(
            "usage: drive-docs esi DIR | drive-docs od-doc FILE | drive-docs faults-doc FILE | drive-docs migration DIR"
                .into(),
        ),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Err(e) = run(&args) {
        eprintln!("drive-docs: {e}");
        std::process::exit(2);
    }
}
