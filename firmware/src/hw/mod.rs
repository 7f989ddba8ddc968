//! Board support for the STM32G474RE reference board (binary only; the library
//! never sees these modules). Each module owns one concern and is the one place to
//! review it:
//!
//! | module | what |
//! |---|---|
//! | [`pwm`] | TIM1/TIM8 centre-aligned complementary PWM, dead time, break input, ADC trigger |
//! | [`clock`] | the system clock (PLL → 170 MHz), the ADC kernel clock, the DMA interrupt priority |
//! | [`adc`] | ADC1/ADC2 injected conversions at the PWM centre and the current-loop ISR |
//! | [`control`] | the current loop + motion layer in the ADC interrupt, lock-free exchange with the cyclic path |
//! | [`encoder`] | TIM2 quadrature encoder with Z and IN1 hardware captures |
//! | [`esc`] | SPI2 with DMA to the EtherCAT slave controller, the ESC driver flavour |
//! | [`lock`] | the priority-ceiling lock of the drive state (cyclic path ↔ thread mode) |
//! | [`io`] | DIP matrix, digital inputs, outputs, brake, LEDs |
//! | [`flash`] | the internal flash: the parameter-record region and the firmware update's partitions |
//! | [`log`] | log texts of the board's errors, the parameter-slot report, event counters and the status line |
//! | [`safety`] | emergency stop, panic and HardFault handlers, fault number |
//! | [`stack`] | painted-stack high-water mark |
//! | `selftest` | the checks of the `selftest` build (first power-up), verdicts from `firmware::selftest` |
//! | `boot` | the static slots of the drive state, the flash set-up, the control state's start |
//! | `records` | programming staged flash records outside the lock |
//!
//! ## Tasks, interrupts and priorities
//!
//! NVIC priorities (stated once in `firmware::irq_priority`): 0 is the most urgent;
//! the G4 implements 4 priority bits. The break interrupts run above the current
//! loop, so a break in the middle of a current-loop step takes the other bridge off
//! at once. Thread
//! mode (the embassy thread executor) is below every interrupt. Budgets are per
//! activation at 170 MHz; "to be measured" means it needs the board (TP1 + scope or
//! DWT CYCCNT, see docs/board/bring-up.md) — QEMU has no timing model.
//!
//! | what | runs in | priority | rate | worst-case budget |
//! |---|---|---|---|---|
//! | current loop: ADC1 JEOS → I_A, I_B, V_BUS → encoder update → `foc::current_loop::CurrentLoop::step` → TIM1/TIM8 compare (`hw::control`) | `ADC1_2` ISR | 1 | 40 kHz (PWM centre) | ≤ 12.5 µs (half a PWM period); the current step's instruction count is BENCHMARKS.md's "current loop step" row; to be measured (`ISR max` in the status line) |
//! | motion layer: `firmware::commutation::CommutatedMotion::step` — at the first closed-loop enable after power-up the commutation alignment (`foc::servo::Alignment`, 0.25 s, 0.65 s with the 0x2083 wiggle; offset → encoder), then `firmware::motion::Motion::step` (interpolation, servo / open loop → current reference); index, touch probe 1 (TIM2 CH4 capture) and touch probe 2 (from the task below) → positions (`firmware::latch`); feedback published | same ISR, every 4th period | 1 | 10 kHz | together with the current step ≤ 12.5 µs; to be measured |
//! | over-current: break input → TIM1/TIM8 MOE off | hardware | — | event | break filter ≈ 24 ns + gate driver |
//! | break bookkeeping: other bridge off, latch | `TIM1_BRK_TIM15`, `TIM8_BRK` ISRs | 0 | event | < 1 µs, to be measured |
//! | SPI DMA completion (ESC transfers) | `DMA1_CHANNEL1/2` ISRs (embassy) | 2 | per transfer | < 1 µs, to be measured |
//! | cyclic path: SYNC0 → `Slave::cycle` (SM2 read, `Drive` = CiA 402 cycle, SM3 write) → set-points to the ISR | interrupt executor on `UART4` (vector unused: its pins carry TIM8) | 3 | DC sync rate (≥ 125 µs cycle) | ≤ 50 % of the cycle; SPI ≈ 0.4 µs/byte at 21.25 MHz + the CSP cycle (BENCHMARKS.md's "CSP cycle" row); to be measured |
//! | touch probe 2 (IN2 edge → encoder count + edge direction → `hw::control::PROBE2_RAW`) | interrupt executor `UART4` | 3 | event | < 2 µs latency (the latch error), to be measured |
//! | EXTI1/2/3 wakers (IN2, ESC IRQ, SYNC0) | `EXTI1..3` ISRs (embassy) | 3 | event | < 1 µs |
//! | embassy time driver | `TIM5` ISR | 4 | alarms | < 2 µs |
//! | EtherCAT: ESC IRQ (or every 1 ms) → `Slave::poll` (AL control, ESM, mailbox/SDO, watchdog supervision; the cycle in SM-synchronous / free-run mode), emergencies forwarded | thread executor, holding the priority-ceiling lock | thread (ceiling 3) | ESC IRQ, ≥ 1 kHz | one SDO ≈ 2 × 128-byte SPI transfers + dictionary access; a 'save' adds the record serialisation (≈ 1.7 KiB of dictionary reads); delays the cyclic path by at most this; to be measured |
//! | parameter storage: staged record → flash (erase ≈ 20 ms per 2 KiB page, ≤ 40 ms max; program ≈ 85 µs per 8 bytes) | thread executor, after `poll`, **no lock** | thread | on 'save' / 'load' | ≤ 4 × 40 ms + 20 ms; the cyclic path and the ISRs keep running (bank 2 read-while-write); the thread tasks pause — the watchdog (300 ms) covers it |
//! | 1 ms supervision tick, the drive's own clock: raw inputs → `Drive::tick` (filter, protections, over-current and current-sensing faults from the board, a failed commutation alignment → following error 0x8611, and — unless a cycle just did it — the control step: PDS, fault reactions, ramps, generators, brake, in every ESM state), outputs from `Drive::outputs`, the brake decision into the command (the pin is the current-loop interrupt's: `firmware::power_gate::BrakeOut`), LEDs (`Drive::leds`, RUN/ERR from the ESM state and AL status code) | interrupt executor `UART4` (so a flash commit in thread mode never stops it; lock held for the drive part) | 3 | 1 kHz | < 20 µs; the control step ≈ 1 k instructions (QEMU count), to be measured |
//! | supervisor: offset self-check at start, watchdog feeding, status line | thread executor | thread | 100 Hz | < 100 µs per tick |
//!
//! ## Who owns what
//! * The **drive state** — `Slave<Esc>` (the ESC and its SPI bus) and `Drive` (the
//!   application: dictionary, CiA 402, faults, parameter store) — is one
//!   [`DriveState`] value in a blocking `Mutex<CyclicCeiling, RefCell<..>>`
//!   ([`hw::lock`]): locking raises BASEPRI to the cyclic priority, so the thread-mode
//!   tasks exclude the cyclic path while they hold it, and the current loop
//!   and the break and DMA interrupts (levels above the cyclic one) are never delayed
//!   by it.
//!   We did not split Slave and Drive: `poll` and `cycle` both need both.
//! * `Slave::poll` runs in **thread mode** (task `ecat`), `Slave::cycle` on the
//!   **interrupt executor** (task `cyclic`, SYNC0; each SYNC0 is run once, by
//!   whichever of the two sees it first, see `cyclic`). A 'save' (0x1010) arrives as an SDO
//!   inside `poll`; the parameter store is `hw::flash::BoardStore`
//!   (`firmware::staged_flash::StagedRecords`): inside `poll` the dictionary is only
//!   read into a 2 KiB RAM stage (no flash access, no CRC; the SDO answer reports the
//!   serialisation's result) and the `ecat` task writes the record *after* releasing
//!   the lock ([`hw::flash::commit`]: the newest record looked up, the entries a partial
//!   command keeps, the CRC, then erase, payload, header last — the storage's
//!   power-loss order). So no flash erase ever runs under the lock and the
//!   cyclic path keeps its timing during a save; a flash error at commit time is
//!   logged and sent as an emergency (0x5530). The fault history's record
//!   (`Drive::persist_history`, polled after `poll` when no 'save' record waits) goes
//!   the same way through the same stage: the fault path only marks it dirty.
//!   A second 'save' while one is being
//!   programmed cannot happen (the same task does both in turn).
//! * The **chip's flash** is one `hw::flash::ChipFlash` (a thread-mode mutex: taking it
//!   masks nothing) shared by the parameter region and the **firmware update**
//!   (`firmware::update`, attached to the drive): FoE in Bootstrap runs inside `poll`,
//!   erasing and programming the DFU partition (bank 2, read-while-write) under the
//!   lock, one 2 KiB page per FoE DATA at most (≈ 20 ms, answered BUSY); the power
//!   stage is off in Bootstrap. After an accepted update, Bootstrap → Init resets the
//!   chip into embassy-boot (`Drive::reset_requested`). A new image confirms itself
//!   (embassy-boot's state partition, bank 1: a stall of the code bank for the page
//!   erase) only with the power stage off, once the offset check passed and Pre-Op was
//!   reached.
//! * The **motor control state** (`CurrentLoop`, `foc::encoder::Encoder`,
//!   `CommutatedMotion` = `Motion` + the commutation alignment) is owned by the ADC
//!   interrupt ([`hw::control`]). It talks to the drive through two lock-free double
//!   buffers: set-points / permission / configuration / offsets in, measurements
//!   (`AxisState` fields, index and touch-probe latches, alignment failures) out.
//! * **Touch probes** (0x60B8-0x60BD): the interrupt publishes the axis position at
//!   each electrical edge of IN1 / IN2 with a sequence number
//!   (`firmware::latch::Edges`); whoever updates the drive (`update_axis`) turns new
//!   ones into rising/falling edges per 0x2154 and hands them to the drive in
//!   `AxisState::probe1/probe2` until a drive step has run (`publish_command` clears
//!   them), exactly as the index pulse.
//! * **Decisions** between the drive and the interrupt — latches pending for a step,
//!   probe polarity, alignment failures → 0x8611, the failed offset check → current-sensing fault,
//!   the power and tune permissions, break latch ↔ over-current fault and its re-arm — are the
//!   library's `firmware::board_glue::BoardGlue` (held in [`DriveState`]), run by host and
//!   QEMU tests and by the simulator (`tests-host`). This file wires tasks to it.
//!
//! ## Watchdog
//! The independent watchdog ([`board::WATCHDOG_TIMEOUT_US`]) is fed by the supervisor
//! only while the current-loop ISR keeps producing samples (its sample counter
//! advanced since the last feed) and the control state is installed. A stuck PWM/ADC
//! chain, a hung interrupt or a starved thread executor all end in a reset; the next
//! start logs the cause.
pub mod adc;
pub mod boot;
pub mod clock;
pub mod control;
pub mod encoder;
pub mod esc;
pub mod flash;
pub mod io;
pub mod lock;
pub mod log;
pub mod pwm;
pub mod records;
pub mod safety;
#[cfg(feature = "selftest")]
pub mod selftest;
pub mod stack;
