//! Static worst-case stack usage of the board firmware (printed by `cargo xtask size`).
//!
//! Reads the firmware ELF itself (no external tool; the instructions are decoded by
//! the capstone library):
//!
//! 1. a minimal ELF32 little-endian reader: section headers, `.symtab`/`.strtab`, bytes
//!    at a load address;
//! 2. every function (`STT_FUNC`, size > 0) is walked instruction by instruction
//!    (Thumb-2: the length from the first halfword, the instruction from capstone in
//!    Thumb M-class mode; the `$t`/`$d` mapping symbols mark literal
//!    pools and jump tables, which are skipped — without them data is decoded as code,
//!    which can only add SP decrements or edges, i.e. over-estimate). Its frame is the
//!    sum of *every* SP decrement in its body (PUSH, STMDB SP!, STR/STRD pre-indexed on
//!    SP, VPUSH, SUB SP / SUB.W / SUBW SP): conservative when a function has several
//!    prologue paths;
//! 3. call graph: BL gives an edge, B/B.W/B<c>/CBZ to another function a tail-call
//!    edge (the caller's frame is counted too: conservative); BLX/BX register calls are
//!    indirect and recorded per function;
//! 4. depth of a function = frame + max over its callees (memoised DFS; a cycle is
//!    recursion: the figure is then unbounded and the cycle is reported);
//! 5. roots: thread mode (`Reset` → `main` → the embassy thread executor, whose
//!    indirect task call is resolved to the `TaskStorage<F>::poll` functions of the
//!    thread tasks), the interrupt executor on `UART4` (resolved to the polls of the
//!    cyclic tasks), every vector-table handler with its NVIC priority (see
//!    [`IRQ_PRIORITIES`]). Worst case = thread + for each priority level the deepest
//!    handler of that level (levels nest, equal levels do not) + one exception frame
//!    per nesting level.
//!
//! Tasks are told apart by code, not by their names: a poll function belongs to the
//! task whose `POOL` static the spawn code addresses just before it, and the start-up
//! task is the one spawned by code that the reset handler reaches through direct calls
//! (the entry `#[embassy_executor::main]` generates). Only the placement on the
//! interrupt executor is declared ([`INTERRUPT_EXECUTOR`]), and a declared task that
//! is not found is an error.
//!
//! The steps live in submodules: [`elf`] (the reader), [`decode`] (Thumb-2 decoding and
//! the per-function scan), [`graph`] (functions, edges, tasks, roots), [`depth`] (the
//! solver), [`report`] (nesting, coarse bound, the printed text), [`names`] (demangling).
//!
//! The decoder is capstone (crate `capstone` 0.14, Capstone 5.0 built from source by
//! `capstone-sys` with the C compiler) rather than a decoder of our own or
//! `yaxpeax-arm`: yaxpeax-arm 0.5.0 decodes no Thumb floating-point instruction
//! (`vpush`, `vpop`, `vldr`, `vadd.f32` all give `DecodeError::Incomplete`: its table
//! A6-30 leaves the `101x` coprocessor rows unimplemented), and VPUSH is part of the
//! frame. Capstone decodes all the analysis needs: push/pop, vpush, sub sp, bl/blx, b.w
//! tail calls, cbz, ldr pc, movw/movt, literal loads, and tbb/tbh and it blocks.

mod decode;
mod depth;
mod elf;
mod graph;
mod names;
mod report;
#[cfg(test)]
mod tests;

use std::path::Path;

use elf::Elf;
use graph::{Program, Roots, Tasks};
// What the unit tests reach through `super::*`.
#[cfg(test)]
use {
    decode::{decode16, decode32, is_32bit, scan, Insn},
    depth::Solver,
    elf::{SHT_SYMTAB, STT_FUNC},
    names::demangle,
    std::collections::HashMap,
};

// ---------------------------------------------------------------------------------------
// What the analysis must know about the firmware (keep in step with the sources)
// ---------------------------------------------------------------------------------------

/// NVIC priorities the firmware programs (0 = most urgent), from the table it sets
/// them from (`firmware::irq_priority`):
/// * `BREAK`: `TIM1_BRK_TIM15`, `TIM8_BRK` (`firmware/src/hw/pwm.rs`);
/// * `CURRENT_LOOP`: `ADC1_2` (`firmware/src/hw/adc.rs`);
/// * `SPI_DMA`: every DMA channel interrupt embassy binds (`firmware/src/hw/clock.rs`
///   `config`, `bdma_interrupt_priority`: `DMA1_CHANNEL1`, `DMA1_CHANNEL2` in
///   `bind_interrupts!`);
/// * `CYCLIC`: `EXTI1/2/3` and `UART4` (the cyclic interrupt executor,
///   `firmware/src/main.rs`);
/// * `TIME_DRIVER`: `TIM5` (the embassy time driver, `firmware/src/hw/clock.rs`).
///
/// A name ending in `*` is a prefix. Every other handler in the vector table keeps the
/// reset priority 0 (NVIC IPR / SHPR reset value); NMI (-2) and HardFault (-1) are fixed.
pub const IRQ_PRIORITIES: &[(&str, i32)] = {
    use firmware::irq_priority::{BREAK, CURRENT_LOOP, CYCLIC, SPI_DMA, TIME_DRIVER};
    &[
        ("TIM1_BRK_TIM15", BREAK as i32),
        ("TIM8_BRK", BREAK as i32),
        ("ADC1_2", CURRENT_LOOP as i32),
        ("DMA1_CHANNEL*", SPI_DMA as i32),
        ("DMA2_CHANNEL*", SPI_DMA as i32),
        ("UART4", CYCLIC as i32),
        ("EXTI1", CYCLIC as i32),
        ("EXTI2", CYCLIC as i32),
        ("EXTI3", CYCLIC as i32),
        ("TIM5", TIME_DRIVER as i32),
    ]
};

/// The interrupt executor: its vector and the tasks it polls (`firmware/src/main.rs`:
/// `EXECUTOR_CYCLIC.start(interrupt::UART4)`, `cyclic_spawner` spawns of `cyclic`,
/// `touch_probe2` and `tick`). Every other task runs on the thread executor.
pub const INTERRUPT_EXECUTOR: (&str, &[&str]) = ("UART4", &["cyclic", "touch_probe2", "tick"]);

/// Functions whose indirect call is the executor calling a task's poll function (the
/// thread executor's run loop inlines `SyncExecutor::poll`; the interrupt executor's
/// `on_interrupt` is inlined into the `UART4` handler, which is added by name).
const DISPATCHERS: &[&str] = &[
    "embassy_executor::platform::thread::Executor::run",
    "embassy_executor::raw::SyncExecutor::poll",
    "embassy_executor::raw::Executor::poll",
    "embassy_executor::platform::interrupt::InterruptExecutor::on_interrupt",
];

/// Name prefix of the task poll functions (`TaskStorage<F>::poll`, one per task).
const TASK_POLL: &str = "embassy_executor::raw::TaskStorage<F>::poll";

/// Bytes one exception entry pushes with an FPU context (Cortex-M4F; lazy stacking
/// reserves the FP part too): 8 basic + 18 FP words. The 4-byte alignment padding the
/// core may add (CCR.STKALIGN) is not counted: the compiled code keeps SP 8-aligned.
pub const EXCEPTION_FRAME: u64 = 104;

// ---------------------------------------------------------------------------------------
// The firmware analysis
// ---------------------------------------------------------------------------------------

pub struct StackReport {
    /// Worst-case stack bytes (a recursion counted once when `bounded` is false).
    pub worst: u64,
    pub bounded: bool,
    /// The same with every unresolved indirect call assumed to reach every function no
    /// direct call reaches (a coarse bound).
    pub with_indirect: u64,
    /// Lines to print (indented).
    pub text: String,
}

/// The most urgent [`IRQ_PRIORITIES`] level any of `names` has.
fn priority_of(names: &[&str]) -> Option<i32> {
    let mut best: Option<i32> = None;
    for n in names {
        for (pat, p) in IRQ_PRIORITIES {
            let hit = match pat.strip_suffix('*') {
                Some(prefix) => n.starts_with(prefix),
                None => n == pat,
            };
            if hit {
                best = Some(best.map_or(*p, |b| b.min(*p)));
            }
        }
    }
    best
}

/// Analyses the firmware ELF at `path`.
pub fn analyse(path: &Path) -> Result<StackReport, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("read {}: {e}", path.display()))?;
    analyse_elf(&Elf::parse(bytes)?)
}

/// Symbols → decoded functions and their edges → tasks → roots → depths and report.
pub fn analyse_elf(elf: &Elf) -> Result<StackReport, String> {
    let symbols = elf.symbols()?;
    let prog = Program::load(elf, &symbols)?;
    let tasks = Tasks::find(&symbols, &prog);
    let roots = Roots::find(elf, &symbols, &prog, &tasks)?;
    report::report(&prog, &tasks, &roots)
}
