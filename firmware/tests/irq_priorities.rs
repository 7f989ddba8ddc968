//! The board's interrupt priorities (`firmware::irq_priority`): the order the safety
//! argument needs, and that the board code (`src/hw`, `src/main.rs`) takes every
//! priority from that table and states none of its own.

use firmware::irq_priority::{self, register, ALL, BREAK, CURRENT_LOOP, CYCLIC, SPI_DMA};

#[test]
fn the_break_preempts_the_current_loop() {
    // Lower is more urgent on the NVIC: the break interrupts must preempt the current
    // loop (a break in the middle of a current step takes the other bridge off at
    // once), the current loop everything else.
    assert!(register(BREAK) < register(CURRENT_LOOP));
    assert!(register(CURRENT_LOOP) < register(SPI_DMA));
    // The DMA completion preempts the cyclic path that waits for it.
    assert!(register(SPI_DMA) < register(CYCLIC));
    for w in ALL.windows(2) {
        assert!(w[0].1 < w[1].1, "{} before {}", w[0].0, w[1].0);
    }
    for (name, level) in ALL {
        assert!(level < 1 << irq_priority::BITS, "{name}: {level}");
        assert_eq!(
            register(level) & 0x0F,
            0,
            "{name}: the G4 ignores the low bits"
        );
    }
    assert_eq!(ALL[0], ("break", BREAK));
}

fn source(name: &str) -> String {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("src")
        .join(name);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn the_board_code_sets_every_priority_from_the_table() {
    let mut files: Vec<String> =
        std::fs::read_dir(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/hw"))
            .unwrap()
            .map(|e| format!("hw/{}", e.unwrap().file_name().to_string_lossy()))
            .filter(|n| n.ends_with(".rs"))
            .collect();
    files.push("main.rs".into());
    let mut setters = 0;
    for f in &files {
        let text = source(f);
        for (i, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            // The one mapping from a level to embassy's priority lives in hw/lock.rs.
            if f != "hw/lock.rs" {
                assert!(
                    !line.contains("Priority::P"),
                    "{f}:{}: a priority of its own: {line}",
                    i + 1
                );
            }
            if line.contains("set_priority(") || line.contains("interrupt_priority =") {
                setters += 1;
            }
        }
    }
    assert!(setters >= 5, "only {setters} priority settings found");
    // Each interrupt takes its level by name.
    for (file, level) in [
        ("hw/pwm.rs", "irq_priority::BREAK"),
        ("hw/adc.rs", "irq_priority::CURRENT_LOOP"),
        ("hw/clock.rs", "irq_priority::SPI_DMA"),
        ("hw/clock.rs", "irq_priority::TIME_DRIVER"),
        ("hw/lock.rs", "irq_priority::CYCLIC"),
    ] {
        assert!(source(file).contains(level), "{file} does not use {level}");
    }
    let pwm = source("hw/pwm.rs");
    let brk = pwm
        .find("TIM1_BRK_TIM15.set_priority")
        .expect("break priority set");
    assert!(pwm[..brk].rfind("irq_priority::BREAK").is_some());
}
