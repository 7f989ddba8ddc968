//! The migration guides `docs/migration/*.md` (`cargo xtask migration`): the committed
//! files are what the tables in `tests-host/src/migration/` and the firmware generate;
//! every dictionary entry a guide names exists with the access and PDO mapping the
//! guide states, in both variants' dictionaries; the checker catches a wrong row; the
//! DIP tables the guides call "the same" are the firmware's.

#[allow(dead_code)]
#[path = "../src/bin/drive-docs.rs"]
mod drive_docs;

use ecat_slave_stack::od::PdoMappable;
use firmware::identity::Variant;
use tests_host::migration::{check, problems, Acc, Here, GUIDES};

fn repo_path(rel: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(rel)
}

#[test]
fn committed_guides_are_up_to_date() {
    let guides = drive_docs::migration_guides().expect("every row matches the dictionary");
    assert_eq!(guides.len(), 4);
    let hint = "run `cargo xtask migration` and commit docs/migration";
    for (name, text) in &guides {
        let committed =
            std::fs::read_to_string(repo_path("docs/migration").join(name)).unwrap_or_default();
        assert!(
            &committed == text,
            "docs/migration/{name} is out of date: {hint}"
        );
    }
    let mut present: Vec<String> = std::fs::read_dir(repo_path("docs/migration"))
        .expect("docs/migration")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    present.sort();
    let mut want: Vec<String> = guides.iter().map(|(n, _)| n.clone()).collect();
    want.sort();
    assert_eq!(
        present, want,
        "files in docs/migration that no guide writes"
    );
}

#[test]
fn every_named_entry_exists_with_the_stated_access_and_mapping() {
    for (variant, _) in drive_docs::VARIANTS {
        let objects = drive_docs::variant_objects(variant);
        for g in GUIDES {
            let bad = problems(g, objects);
            assert!(bad.is_empty(), "{variant:?}:\n{}", bad.join("\n"));
            let named = g
                .sections
                .iter()
                .flat_map(|s| s.rows.iter())
                .filter(|r| matches!(r.here, Here::Entry(..) | Here::Object(_)))
                .count();
            assert!(named >= 10, "{}: only {named} objects named", g.file);
        }
    }
}

#[test]
fn the_checker_refuses_wrong_rows() {
    let objects = drive_docs::variant_objects(Variant::HybridServo);
    // Right.
    assert_eq!(
        check(objects, Here::Entry(0x6040, 0, Acc::Rw, PdoMappable::Rx)),
        None
    );
    assert_eq!(
        check(objects, Here::Entry(0x60FA, 0, Acc::Ro, PdoMappable::Tx)),
        None
    );
    assert_eq!(
        check(objects, Here::Entry(0x2000, 0, Acc::Rw, PdoMappable::Rx)),
        None
    );
    // Wrong access, wrong mapping, missing entry, missing object, unknown AL code.
    assert!(check(objects, Here::Entry(0x6041, 0, Acc::Rw, PdoMappable::Tx)).is_some());
    assert!(check(objects, Here::Entry(0x2001, 0, Acc::Rw, PdoMappable::Rx)).is_some());
    assert!(check(objects, Here::Entry(0x6040, 1, Acc::Rw, PdoMappable::Rx)).is_some());
    assert!(check(objects, Here::Object(0x60C1)).is_some());
    assert!(check(objects, Here::Al(0x7777)).is_some());
}

#[test]
fn dip_tables_the_guides_call_the_same_are_the_firmwares() {
    use firmware::dip;
    // EST-584: SW1-SW3 peak current (A), SW6-SW7 smoothing (ms), in the manual's order.
    assert_eq!(
        dip::EST584_CURRENT_MA,
        [2000, 3500, 4500, 5200, 5800, 6700, 7700, 8400]
    );
    assert_eq!(dip::EST584_SMOOTHING_MS, [0, 2, 12, 25]);
    // E5 ID bank: all ON = 0, S1 OFF = 1, all OFF = 127.
    assert_eq!(dip::id_bank_address(0x7F), 0);
    assert_eq!(dip::id_bank_address(0x7E), 1);
    assert_eq!(dip::id_bank_address(0x00), 127);
    // DP3CL filter: OFF/OFF 1.5 ms, OFF/ON 3 ms, ON/OFF 12 ms, ON/ON off.
    assert_eq!(dip::DP3CL705_FILTER_US, [1500, 3000, 12_000, 0]);
}
