//! Host side of the portable harness: catch_unwind per test, libtest-like output.
use crate::TestFn;
use std::panic;

/// Runs all tests; returns the process exit code (0 = all passed). An optional
/// filter (first non-flag command-line argument) selects tests by substring, as
/// libtest does.
pub fn run(module: &str, tests: &[TestFn]) -> i32 {
    let filter: Option<String> = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let selected: Vec<&TestFn> = tests
        .iter()
        .filter(|(name, _)| filter.as_deref().is_none_or(|f| name.contains(f)))
        .collect();
    println!("\nrunning {} tests ({module}, host)", selected.len());
    let (mut passed, mut failed) = (0usize, Vec::new());
    for (name, f) in selected {
        match panic::catch_unwind(*f) {
            Ok(()) => {
                passed += 1;
                println!("test {name} ... ok");
            }
            Err(_) => {
                failed.push(*name);
                println!("test {name} ... FAILED");
            }
        }
    }
    let verdict = if failed.is_empty() { "ok" } else { "FAILED" };
    if !failed.is_empty() {
        println!("\nfailures:");
        for name in &failed {
            println!("    {name}");
        }
    }
    println!(
        "\ntest result: {verdict}. {passed} passed; {} failed; 0 ignored; 0 measured; 0 filtered out\n",
        failed.len()
    );
    i32::from(!failed.is_empty())
}
