//! The LAN9252 and ET1100 drivers of `ecat-slave-stack`, byte by byte against the
//! SPI-level chip models of `tests_host::spi_models`.

use ecat_slave_stack::et1100::{Addressing, Et1100, Et1100Config, ReadMode};
use ecat_slave_stack::lan9252::{IrqConfig, Lan9252, Lan9252Config, ReadCommand, ResetKind};
use ecat_slave_stack::{EscAccess, EscError};
use embedded_hal::delay::DelayNs;
use embedded_hal::spi::{Operation, SpiDevice};
use tests_host::spi_models::{Et1100Model, Lan9252Model, RamEsc, MODEL_ID_REV};

struct NoDelay(u32);
impl DelayNs for NoDelay {
    fn delay_ns(&mut self, _ns: u32) {
        self.0 += 1;
    }
}

fn rd(addr: u16) -> Vec<u8> {
    vec![0x0B, (addr >> 8) as u8, addr as u8, 0x01, 0, 0, 0, 0]
}
fn wr(addr: u16, v: u32) -> Vec<u8> {
    let d = v.to_le_bytes();
    vec![0x02, (addr >> 8) as u8, addr as u8, d[0], d[1], d[2], d[3]]
}

fn lan(cfg: Lan9252Config) -> Lan9252<Lan9252Model<RamEsc>> {
    let mut d = Lan9252::new(Lan9252Model::new(RamEsc::patterned()), cfg);
    d.init(&mut NoDelay(0)).unwrap();
    d.spi_mut().log.clear();
    d
}

fn lan_default() -> Lan9252<Lan9252Model<RamEsc>> {
    lan(Lan9252Config {
        reset: ResetKind::None,
        ..Lan9252Config::default()
    })
}

fn pattern(addr: usize) -> u8 {
    (addr as u32).wrapping_mul(7).wrapping_add(3) as u8
}

// ------------------------------------------------------------------ LAN9252

#[test]
fn lan9252_start_up_sequence_is_byte_exact() {
    let mut d = Lan9252::new(Lan9252Model::new(RamEsc::new()), Lan9252Config::default());
    let mut delay = NoDelay(0);
    d.init(&mut delay).unwrap();
    let m = d.spi_mut();
    assert_eq!(m.digital_resets, 1);
    assert!(m.violations.is_empty(), "{:?}", m.violations);
    // BYTE_TEST, HW_CFG, reset, then two reads that hit the chip in reset (0) ...
    let expect = vec![
        rd(0x064),
        rd(0x074),
        wr(0x1F8, 0x0000_0001),
        rd(0x064), // reads 0 while in reset
        rd(0x064), // still 0
        rd(0x064), // 0x87654321
        rd(0x074),
        rd(0x1F8),
        rd(0x050),
    ];
    let got = m.mosi_since(0);
    let got_headers: Vec<Vec<u8>> = got.clone();
    assert_eq!(got_headers, expect);
    assert_eq!(&m.log[5].miso[4..8], &[0x21, 0x43, 0x65, 0x87]);
    assert_eq!(d.id_rev(), MODEL_ID_REV);
    assert_eq!(delay.0, 2, "one delay per repeated BYTE_TEST poll");
}

#[test]
fn lan9252_serial_read_has_no_dummy_byte() {
    let mut d = lan(Lan9252Config {
        read_command: ReadCommand::Serial,
        reset: ResetKind::None,
        ..Default::default()
    });
    assert_eq!(d.read_reg(0x064).unwrap(), 0x8765_4321);
    assert_eq!(
        d.spi_mut().mosi_since(0),
        vec![vec![0x03, 0x00, 0x64, 0, 0, 0, 0]]
    );
}

#[test]
fn lan9252_csr_read_two_bytes() {
    let mut d = lan_default();
    d.spi_mut().esc.mem[0x130..0x132].copy_from_slice(&[0x12, 0x34]);
    assert_eq!(d.read_u16(0x0130).unwrap(), 0x3412);
    let m = d.spi_mut();
    assert_eq!(
        m.mosi_since(0),
        vec![wr(0x304, 0xC002_0130), rd(0x304), rd(0x304), rd(0x300)]
    );
    // busy on the first poll, clear on the second
    assert_eq!(&m.log[1].miso[4..8], &[0x30, 0x01, 0x02, 0xC0]);
    assert_eq!(&m.log[2].miso[4..8], &[0x30, 0x01, 0x02, 0x40]);
    assert_eq!(&m.log[3].miso[4..8], &[0x12, 0x34, 0x00, 0x00]);
    assert!(m.violations.is_empty(), "{:?}", m.violations);
}

#[test]
fn lan9252_csr_splits_into_aligned_accesses() {
    let mut d = lan_default();
    d.spi_mut().faults.csr_busy_polls = 0;
    let mut b = [0u8; 7];
    d.read(0x0131, &mut b).unwrap();
    let want: Vec<u8> = (0x131..0x138).map(pattern).collect();
    assert_eq!(b.to_vec(), want);
    let cmds: Vec<Vec<u8>> = d
        .spi_mut()
        .mosi_since(0)
        .into_iter()
        .filter(|t| t[0] == 0x02)
        .collect();
    assert_eq!(
        cmds,
        vec![
            wr(0x304, 0xC001_0131),
            wr(0x304, 0xC002_0132),
            wr(0x304, 0xC004_0134)
        ]
    );
    assert!(d.spi_mut().violations.is_empty());
}

#[test]
fn lan9252_csr_write_is_byte_exact() {
    let mut d = lan_default();
    d.spi_mut().faults.csr_busy_polls = 0;
    d.write(0x0134, &[0x11, 0x22, 0x33, 0x44, 0x55]).unwrap();
    let m = d.spi_mut();
    assert_eq!(
        m.mosi_since(0),
        vec![
            wr(0x300, 0x4433_2211),
            wr(0x304, 0x8004_0134),
            rd(0x304),
            wr(0x300, 0x0000_0055),
            wr(0x304, 0x8001_0138),
            rd(0x304),
        ]
    );
    assert_eq!(
        &m.esc.mem[0x133..0x13A],
        &[pattern(0x133), 0x11, 0x22, 0x33, 0x44, 0x55, pattern(0x139)]
    );
    assert!(m.violations.is_empty(), "{:?}", m.violations);
}

#[test]
fn lan9252_pram_read_unaligned_through_fifo() {
    let mut d = lan_default();
    let mut b = [0u8; 10];
    d.read(0x1101, &mut b).unwrap();
    let want: Vec<u8> = (0x1101..0x110B).map(pattern).collect();
    assert_eq!(b.to_vec(), want);
    let m = d.spi_mut();
    // First PRAM access after init aborts whatever the FIFO was doing.
    assert_eq!(
        m.mosi_since(0),
        vec![
            wr(0x30C, 0x4000_0000),
            rd(0x30C),
            wr(0x308, 0x000A_1101),
            wr(0x30C, 0x8000_0000),
            rd(0x30C),
            // 3 words (lead 1 + 10 bytes = 11 bytes) in one burst from the FIFO port
            vec![0x0B, 0x00, 0x00, 0x01, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
        ]
    );
    // FIFO status: available, 3 words
    assert_eq!(&m.log[4].miso[4..8], &[0x01, 0x03, 0x00, 0x80]);
    // The first word carries the first byte at lane 1.
    assert_eq!(
        &m.log[5].miso[5..8],
        &[pattern(0x1101), pattern(0x1102), pattern(0x1103)]
    );
    assert!(m.violations.is_empty(), "{:?}", m.violations);
    // The next read needs no abort, only the busy check before ADDR_LEN.
    let from = m.log.len();
    let mut one = [0u8; 1];
    d.read(0x1000, &mut one).unwrap();
    assert_eq!(one[0], pattern(0x1000));
    let m = d.spi_mut();
    assert_eq!(m.mosi_since(from)[..2], [rd(0x30C), wr(0x308, 0x0001_1000)]);
    assert_eq!(&m.log[from].miso[4..8], &[0, 0, 0, 0], "read unit idle");
}

/// Bit 31 (busy) of a 32-bit register read's MISO bytes.
fn busy_bit(miso: &[u8]) -> bool {
    miso.get(7).is_some_and(|b| b & 0x80 != 0)
}

#[test]
fn lan9252_pram_write_waits_until_the_previous_one_is_done() {
    let mut d = lan_default();
    d.spi_mut().faults.pram_write_busy_reads = 3;
    d.write(0x1400, &[1, 2, 3, 4, 5]).unwrap();
    let from = d.spi_mut().log.len();
    d.write(0x1408, &[6, 7]).unwrap();
    let m = d.spi_mut();
    assert!(m.violations.is_empty(), "{:?}", m.violations);
    assert_eq!(&m.esc.mem[0x1400..0x1405], &[1, 2, 3, 4, 5]);
    assert_eq!(&m.esc.mem[0x1408..0x140A], &[6, 7]);
    // The second write polls ECAT_PRAM_WR_CMD while the first one's data is still
    // being moved (3 busy reads), then one idle read, and only then sets ADDR_LEN.
    let mosi = m.mosi_since(from);
    assert_eq!(
        mosi[..5],
        [
            rd(0x314),
            rd(0x314),
            rd(0x314),
            rd(0x314),
            wr(0x310, 0x0002_1408)
        ]
    );
    let busy: Vec<bool> = m.log[from..from + 4]
        .iter()
        .map(|t| busy_bit(&t.miso))
        .collect();
    assert_eq!(busy, vec![true, true, true, false]);
}

#[test]
fn lan9252_stuck_pram_write_is_a_timeout_without_touching_addr_len() {
    let mut d = lan(Lan9252Config {
        reset: ResetKind::None,
        max_polls: 8,
        ..Lan9252Config::default()
    });
    d.spi_mut().faults.pram_write_stuck_busy = true;
    d.write(0x1500, &[9; 4]).unwrap();
    let from = d.spi_mut().log.len();
    assert_eq!(d.write(0x1504, &[8; 4]), Err(EscError::Timeout));
    let m = d.spi_mut();
    // Bounded polling of the busy bit, nothing else: the model saw no ADDR_LEN write
    // while busy.
    assert_eq!(m.mosi_since(from), vec![rd(0x314); 8]);
    assert!(m.violations.is_empty(), "{:?}", m.violations);
    assert_eq!(
        &m.esc.mem[0x1504..0x1508],
        &[
            pattern(0x1504),
            pattern(0x1505),
            pattern(0x1506),
            pattern(0x1507)
        ]
    );
    // Reads use the other unit and still work.
    let mut b = [0u8; 4];
    d.read(0x1500, &mut b).unwrap();
    assert_eq!(b, [9; 4]);
}

#[test]
fn lan9252_model_refuses_what_the_chip_would_not_do() {
    let mut m = Lan9252Model::new(RamEsc::new());
    let run = |m: &mut Lan9252Model<RamEsc>, bytes: Vec<u8>| {
        m.transaction(&mut [Operation::Write(&bytes)]).unwrap();
    };
    // A one-word write, its word pushed: the unit is still busy.
    run(&mut m, wr(0x310, 0x0004_1000));
    run(&mut m, wr(0x314, 0x8000_0000));
    run(&mut m, wr(0x020, 0x1122_3344));
    assert!(m.violations.is_empty(), "{:?}", m.violations);
    run(&mut m, wr(0x310, 0x0004_1004));
    run(&mut m, wr(0x314, 0x8000_0000));
    assert_eq!(m.violations.len(), 2, "{:?}", m.violations);
    assert!(m.violations[0].contains("ADDR_LEN written while the write is busy"));
    assert!(m.violations[1].contains("started while the write is busy"));
    // The abort is always accepted and leaves the unit idle.
    run(&mut m, wr(0x314, 0x4000_0000));
    let mut r = [0u8; 4];
    m.transaction(&mut [
        Operation::Write(&[0x03, 0x03, 0x14]),
        Operation::Read(&mut r),
    ])
    .unwrap();
    assert_eq!(r[3] & 0x80, 0);
    // A read unit reprogrammed in the middle of a transfer.
    run(&mut m, wr(0x308, 0x0008_1000));
    run(&mut m, wr(0x30C, 0x8000_0000));
    run(&mut m, wr(0x308, 0x0008_1000));
    assert!(m.violations[2].contains("ADDR_LEN written while the read is busy"));
    // Two register words in one transaction outside the FIFO ports: no address
    // auto-increment is assumed there.
    let mut two = [0u8; 8];
    m.transaction(&mut [
        Operation::Write(&[0x03, 0x00, 0x64]),
        Operation::Read(&mut two),
    ])
    .unwrap();
    assert_eq!(&two[..4], &0x8765_4321u32.to_le_bytes());
    assert_eq!(&two[4..], &[0; 4]);
    assert_eq!(m.violations.len(), 4, "{:?}", m.violations);
    assert!(m.violations[3].contains("more than one register word"));
}

#[test]
fn lan9252_pram_read_in_several_fifo_chunks() {
    let mut d = lan_default();
    d.spi_mut().faults.fifo_words = 3;
    let mut b = [0u8; 40];
    d.read(0x1202, &mut b).unwrap();
    let want: Vec<u8> = (0x1202..0x122A).map(pattern).collect();
    assert_eq!(b.to_vec(), want);
    let m = d.spi_mut();
    let bursts: Vec<usize> = m
        .log
        .iter()
        .filter(|t| t.mosi[..3] == [0x0B, 0, 0])
        .map(|t| (t.mosi.len() - 4) / 4)
        .collect();
    // 2 + 40 bytes = 42 → 11 words, at most 3 per burst
    assert_eq!(bursts, vec![3, 3, 3, 2]);
    assert!(m.violations.is_empty(), "{:?}", m.violations);
}

#[test]
fn lan9252_pram_write_unaligned_through_fifo() {
    let mut d = lan_default();
    let data: Vec<u8> = (0..9).map(|i| 0xA0 + i).collect();
    d.write(0x1403, &data).unwrap();
    let m = d.spi_mut();
    let mut burst = vec![0x02, 0x00, 0x20];
    burst.extend_from_slice(&[
        0, 0, 0, 0xA0, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5, 0xA6, 0xA7, 0xA8,
    ]);
    assert_eq!(
        m.mosi_since(0),
        vec![
            wr(0x314, 0x4000_0000),
            rd(0x314),
            wr(0x310, 0x0009_1403),
            wr(0x314, 0x8000_0000),
            rd(0x314),
            burst
        ]
    );
    assert_eq!(&m.esc.mem[0x1403..0x140C], &data[..]);
    assert_eq!(m.esc.mem[0x1402], pattern(0x1402));
    assert_eq!(m.esc.mem[0x140C], pattern(0x140C));
    assert!(m.violations.is_empty(), "{:?}", m.violations);
}

#[test]
fn lan9252_access_spanning_registers_and_pram() {
    let mut d = lan_default();
    let mut b = [0u8; 6];
    d.read(0x0FFD, &mut b).unwrap();
    let want: Vec<u8> = (0x0FFD..0x1003).map(pattern).collect();
    assert_eq!(b.to_vec(), want);
    d.write(0x0FFE, &[1, 2, 3, 4]).unwrap();
    assert_eq!(&d.spi_mut().esc.mem[0x0FFE..0x1002], &[1, 2, 3, 4]);
    assert!(
        d.spi_mut().violations.is_empty(),
        "{:?}",
        d.spi_mut().violations
    );
}

#[test]
fn lan9252_irq_configuration() {
    let mut d = lan_default();
    d.configure_irq(IrqConfig {
        enable: true,
        active_high: false,
        push_pull: true,
        deassert_interval: 5,
    })
    .unwrap();
    assert_eq!(
        d.spi_mut().mosi_since(0),
        vec![wr(0x054, 0x0500_0101), wr(0x05C, 0x0000_0001)]
    );
    assert_eq!(d.spi_mut().irq_cfg, 0x0500_0101);
    // INT_STS follows AL event request & mask.
    d.spi_mut().esc.mem[0x204..0x208].copy_from_slice(&[0, 1, 0, 0]);
    d.spi_mut().esc.mem[0x220..0x224].copy_from_slice(&[0, 0, 0, 0]);
    assert_eq!(d.irq_status().unwrap() & 1, 0);
    d.spi_mut().esc.mem[0x221] = 1;
    assert_eq!(d.irq_status().unwrap() & 1, 1);
}

#[test]
fn lan9252_faults_give_errors_and_bounded_traffic() {
    // Wrong BYTE_TEST.
    let mut m = Lan9252Model::new(RamEsc::new());
    m.faults.byte_test = Some(0x4321_8765);
    let mut d = Lan9252::new(
        m,
        Lan9252Config {
            startup_polls: 10,
            ..Default::default()
        },
    );
    assert_eq!(d.init(&mut NoDelay(0)), Err(EscError::NotDetected));
    assert_eq!(d.spi_mut().log.len(), 10);
    // Absent chip.
    let mut m = Lan9252Model::new(RamEsc::new());
    m.faults.absent = true;
    let mut d = Lan9252::new(
        m,
        Lan9252Config {
            startup_polls: 4,
            ..Default::default()
        },
    );
    assert_eq!(d.init(&mut NoDelay(0)), Err(EscError::NotDetected));
    assert_eq!(d.spi_mut().log.len(), 4);
    // Never ready.
    let mut m = Lan9252Model::new(RamEsc::new());
    m.faults.never_ready = true;
    let mut d = Lan9252::new(
        m,
        Lan9252Config {
            startup_polls: 4,
            ..Default::default()
        },
    );
    assert_eq!(d.init(&mut NoDelay(0)), Err(EscError::Timeout));
    // Stuck CSR busy.
    let mut d = lan(Lan9252Config {
        max_polls: 20,
        reset: ResetKind::None,
        ..Default::default()
    });
    d.spi_mut().faults.csr_stuck_busy = true;
    assert_eq!(d.read_u32(0x0220), Err(EscError::Timeout));
    assert_eq!(d.spi_mut().log.len(), 1 + 20);
    d.spi_mut().faults.csr_stuck_busy = false;
    d.spi_mut().violations.clear();
    assert!(d.read_u32(0x0220).is_ok(), "recovers once the chip answers");
    // FIFO never ready; the next transfer after the failure starts with an abort.
    d.spi_mut().faults.fifo_never_ready = true;
    let mut b = [0u8; 4];
    assert_eq!(d.read(0x1000, &mut b), Err(EscError::Timeout));
    assert_eq!(d.write(0x1000, &b), Err(EscError::Timeout));
    d.spi_mut().faults.fifo_never_ready = false;
    let from = d.spi_mut().log.len();
    d.read(0x1000, &mut b).unwrap();
    assert_eq!(d.spi_mut().mosi_since(from)[0], wr(0x30C, 0x4000_0000));
    assert_eq!(
        b,
        [
            pattern(0x1000),
            pattern(0x1001),
            pattern(0x1002),
            pattern(0x1003)
        ]
    );
    // Bus error.
    d.spi_mut().faults.fail_next = true;
    assert_eq!(d.read(0x1000, &mut b), Err(EscError::Bus));
    d.read(0x1000, &mut b).unwrap();
    assert!(
        d.spi_mut().violations.is_empty(),
        "{:?}",
        d.spi_mut().violations
    );
}

#[test]
fn lan9252_random_round_trips_match_ram() {
    let mut d = lan_default();
    let mut shadow = d.spi_mut().esc.mem.clone();
    let mut seed = 0x1234_5678u32;
    let mut next = || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        seed >> 8
    };
    for _ in 0..300 {
        let addr = (next() % 0x2000) as u16;
        let len = ((next() % 70) as usize).min(0x2000 - addr as usize);
        if next() % 2 == 0 {
            let data: Vec<u8> = (0..len).map(|_| next() as u8).collect();
            d.write(addr, &data).unwrap();
            shadow[addr as usize..addr as usize + len].copy_from_slice(&data);
        } else {
            let mut b = vec![0u8; len];
            d.read(addr, &mut b).unwrap();
            assert_eq!(
                b,
                shadow[addr as usize..addr as usize + len],
                "read {addr:#06x}+{len}"
            );
        }
    }
    assert_eq!(d.spi_mut().esc.mem[..0x2000], shadow[..0x2000]);
    assert!(
        d.spi_mut().violations.is_empty(),
        "{:?}",
        d.spi_mut().violations
    );
}

// ------------------------------------------------------------------ ET1100

fn et(cfg: Et1100Config) -> Et1100<Et1100Model<RamEsc>> {
    Et1100::new(Et1100Model::new(RamEsc::patterned()), cfg)
}

#[test]
fn et1100_read_two_byte_address_with_wait_state_and_termination() {
    let mut d = et(Et1100Config::default());
    d.spi_mut().esc.mem[0x220..0x224].copy_from_slice(&[0x05, 0x01, 0x00, 0x00]);
    let mut b = [0u8; 3];
    d.read(0x0130, &mut b).unwrap();
    assert_eq!(b, [pattern(0x130), pattern(0x131), pattern(0x132)]);
    let m = d.spi_mut();
    assert_eq!(
        m.mosi_since(0),
        vec![vec![0x09, 0x83, 0xFF, 0x00, 0x00, 0xFF]]
    );
    assert_eq!(
        &m.log[0].miso[..2],
        &[0x05, 0x01],
        "AL event clocked out during the address"
    );
    assert!(m.violations.is_empty(), "{:?}", m.violations);
    // The AL event comes from that transaction: no extra SPI traffic.
    assert_eq!(d.al_event().unwrap(), 0x0105);
    assert_eq!(d.spi_mut().log.len(), 1);
    // A second call with nothing in between refreshes with a NOP.
    d.spi_mut().esc.mem[0x220] = 0x11;
    assert_eq!(d.al_event().unwrap(), 0x0111);
    assert_eq!(d.spi_mut().mosi_since(1), vec![vec![0x00, 0x00]]);
    assert!(
        d.spi_mut().violations.is_empty(),
        "{:?}",
        d.spi_mut().violations
    );
}

#[test]
fn et1100_single_byte_read_is_one_termination_byte() {
    let mut d = et(Et1100Config::default());
    assert_eq!(d.read_u8(0x0000).unwrap(), pattern(0));
    assert_eq!(
        d.spi_mut().mosi_since(0),
        vec![vec![0x00, 0x03, 0xFF, 0xFF]]
    );
    assert!(d.spi_mut().violations.is_empty());
}

#[test]
fn et1100_three_byte_address_above_0x2000() {
    let mut d = et(Et1100Config::default());
    d.spi_mut().esc.mem[0x220..0x223].copy_from_slice(&[0x00, 0x04, 0x00]);
    let mut b = [0u8; 2];
    d.read(0x2F00, &mut b).unwrap();
    assert_eq!(b, [pattern(0x2F00), pattern(0x2F01)]);
    d.write(0x2FFE, &[0xAB, 0xCD]).unwrap();
    let m = d.spi_mut();
    assert_eq!(
        m.mosi_since(0),
        vec![
            vec![0x78, 0x06, 0x2C, 0xFF, 0x00, 0xFF],
            vec![0x7F, 0xF6, 0x30, 0xAB, 0xCD]
        ]
    );
    assert_eq!(&m.esc.mem[0x2FFE..0x3000], &[0xAB, 0xCD]);
    assert!(m.violations.is_empty(), "{:?}", m.violations);
}

#[test]
fn et1100_write_two_byte_address() {
    let mut d = et(Et1100Config::default());
    d.write_u16(0x0130, 0x0012).unwrap();
    let m = d.spi_mut();
    assert_eq!(m.mosi_since(0), vec![vec![0x09, 0x84, 0x12, 0x00]]);
    assert_eq!(&m.esc.mem[0x130..0x132], &[0x12, 0x00]);
    assert_eq!(m.esc.writes, vec![(0x0130, vec![0x12, 0x00])]);
}

#[test]
fn et1100_extended_addressing_clocks_out_third_event_byte() {
    let mut d = et(Et1100Config {
        addressing: Addressing::Extended,
        ..Default::default()
    });
    d.spi_mut().esc.mem[0x220..0x224].copy_from_slice(&[0x01, 0x02, 0x03, 0x04]);
    let mut b = [0u8; 2];
    d.read(0x0130, &mut b).unwrap();
    assert_eq!(
        d.spi_mut().mosi_since(0),
        vec![vec![0x09, 0x86, 0x0C, 0xFF, 0x00, 0xFF]]
    );
    assert_eq!(d.al_event().unwrap(), 0x0003_0201);
    assert!(d.spi_mut().violations.is_empty());
}

#[test]
fn et1100_read_with_delay_instead_of_wait_state() {
    let mut d = et(Et1100Config {
        read_mode: ReadMode::Delay(300),
        ..Default::default()
    });
    let mut b = [0u8; 2];
    d.read(0x0110, &mut b).unwrap();
    let m = d.spi_mut();
    assert_eq!(m.mosi_since(0), vec![vec![0x08, 0x82, 0x00, 0xFF]]);
    assert_eq!(m.log[0].delays, vec![(2, 300)]);
    assert!(m.violations.is_empty(), "{:?}", m.violations);
}

#[test]
fn et1100_init_and_faults() {
    let mut ram = RamEsc::new();
    ram.mem[0] = 0x11;
    ram.mem[0x110] = 0x01;
    let mut d = Et1100::new(Et1100Model::new(ram), Et1100Config::default());
    assert_eq!(d.init(&mut NoDelay(0)), Ok(()));
    // Wrong type.
    let mut ram = RamEsc::new();
    ram.mem[0] = 0x12;
    let mut d = Et1100::new(
        Et1100Model::new(ram),
        Et1100Config {
            startup_polls: 6,
            ..Default::default()
        },
    );
    assert_eq!(d.init(&mut NoDelay(0)), Err(EscError::NotDetected));
    assert_eq!(d.spi_mut().log.len(), 6);
    // Absent chip.
    let mut m = Et1100Model::new(RamEsc::new());
    m.faults.absent = true;
    let mut d = Et1100::new(
        m,
        Et1100Config {
            startup_polls: 3,
            ..Default::default()
        },
    );
    assert_eq!(d.init(&mut NoDelay(0)), Err(EscError::NotDetected));
    assert_eq!(d.spi_mut().log.len(), 3);
    // PDI never operational.
    let mut ram = RamEsc::new();
    ram.mem[0] = 0x11;
    let mut d = Et1100::new(
        Et1100Model::new(ram),
        Et1100Config {
            startup_polls: 5,
            ..Default::default()
        },
    );
    assert_eq!(d.init(&mut NoDelay(0)), Err(EscError::Timeout));
    assert_eq!(d.spi_mut().log.len(), 1 + 5);
    // Bus error.
    d.spi_mut().faults.fail_next = true;
    assert_eq!(d.read_u8(0), Err(EscError::Bus));
    assert_eq!(d.al_event().map(|_| ()), Ok(()));
}

#[test]
fn et1100_random_round_trips_match_ram() {
    for addressing in [Addressing::Auto, Addressing::Extended] {
        let mut d = et(Et1100Config {
            addressing,
            ..Default::default()
        });
        let mut shadow = d.spi_mut().esc.mem.clone();
        let mut seed = 99u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed >> 8
        };
        for _ in 0..300 {
            let addr = (next() % 0x3000) as u16;
            let len = ((next() % 70) as usize).min(0x3000 - addr as usize);
            if next() % 2 == 0 {
                let data: Vec<u8> = (0..len).map(|_| next() as u8).collect();
                d.write(addr, &data).unwrap();
                shadow[addr as usize..addr as usize + len].copy_from_slice(&data);
            } else {
                let mut b = vec![0u8; len];
                d.read(addr, &mut b).unwrap();
                assert_eq!(b, shadow[addr as usize..addr as usize + len]);
            }
        }
        assert_eq!(d.spi_mut().esc.mem, shadow);
        assert!(
            d.spi_mut().violations.is_empty(),
            "{:?}",
            d.spi_mut().violations
        );
    }
}

// ------------------------------------------------------------------ the models check

#[test]
fn et1100_model_flags_protocol_errors() {
    let mut m = Et1100Model::new(RamEsc::new());
    // Read without termination, wrong wait-state byte, byte after termination.
    m.transaction(&mut [Operation::Write(&[0x09, 0x83, 0x00, 0x00, 0x00])])
        .unwrap();
    m.transaction(&mut [Operation::Write(&[0x09, 0x83, 0xFF, 0xFF, 0x00])])
        .unwrap();
    // 0b010 read with no delay; reserved command.
    m.transaction(&mut [Operation::Write(&[0x09, 0x82, 0xFF])])
        .unwrap();
    m.transaction(&mut [Operation::Write(&[0x09, 0x81])])
        .unwrap();
    // Operation::Read sends 0x00: no termination.
    let mut b = [0u8; 2];
    m.transaction(&mut [
        Operation::Write(&[0x09, 0x83, 0xFF]),
        Operation::Read(&mut b),
    ])
    .unwrap();
    assert_eq!(m.violations.len(), 6, "{:?}", m.violations);
    // Garbage streams never panic.
    let mut seed = 5u32;
    for _ in 0..500 {
        seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        let n = ((seed >> 16) % 12) as usize;
        let bytes: Vec<u8> = (0..n)
            .map(|_| {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                (seed >> 16) as u8
            })
            .collect();
        m.transaction(&mut [Operation::Write(&bytes)]).unwrap();
    }
}

#[test]
fn lan9252_model_flags_protocol_errors() {
    let mut m = Lan9252Model::new(RamEsc::new());
    m.transaction(&mut [Operation::Write(&[0x3B, 0, 0])])
        .unwrap(); // SQI dual read: unsupported
    m.transaction(&mut [Operation::Write(&wr(0x304, 0x8003_0130))])
        .unwrap(); // size 3
    m.transaction(&mut [Operation::Write(&wr(0x304, 0x8004_0132))])
        .unwrap(); // unaligned
    m.transaction(&mut [Operation::Write(&[0x02, 0x00, 0x54, 1, 2])])
        .unwrap(); // partial word
    m.transaction(&mut [Operation::Write(&wr(0x020, 0))])
        .unwrap(); // FIFO push, no transfer
    assert_eq!(m.violations.len(), 5, "{:?}", m.violations);
    let mut seed = 11u32;
    for _ in 0..500 {
        seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        let n = ((seed >> 16) % 16) as usize;
        let bytes: Vec<u8> = (0..n)
            .map(|_| {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                (seed >> 16) as u8
            })
            .collect();
        let mut r = [0u8; 8];
        m.transaction(&mut [Operation::Write(&bytes), Operation::Read(&mut r)])
            .unwrap();
    }
}

// ------------------------------------------------------------------ driver + model + ESC simulator

fn sii_image(esc: ecat_slave_stack::sii::EscFlavour) -> Vec<u8> {
    use ecat_slave_stack::sii::{self, DeviceDescription};
    let desc = DeviceDescription {
        vendor_id: 0x0E5C,
        vendor_name: "test",
        product_code: 0x5840,
        revision: 0x0001_0000,
        serial: 0,
        type_name: "ECS-HS",
        name: "ECS-HS EtherCAT hybrid servo",
        group_type: "Drives",
        group_name: "Drives",
        hardware_version: "1.0",
        software_version: "0.1.0",
        esc,
        sync_pulse_length: 1000,
        sync0_drive: sii::SyncDrive::PushPullActiveHigh,
        station_alias: 0x0042,
        mailbox_protocols: sii::MBOX_COE,
        mailbox_data_link_layer: true,
        coe: sii::STANDARD_COE,
        fmmus: &sii::STANDARD_FMMUS,
        sync_managers: &sii::STANDARD_SYNC_MANAGERS,
        dc_op_modes: &sii::STANDARD_DC_OP_MODES,
        eeprom_bytes: 2048,
        physical_ports: 0x0011,
        profile_no: 402,
        ebus_current_ma: 0,
        bootstrap: None,
    };
    let mut img = vec![0xFF; 2048];
    sii::build(&desc, &mut img).unwrap();
    img
}

/// Checks one driver over the simulator: identity of the chip, the configuration area
/// loaded from our SII image, AL status written from the PDI, process RAM.
fn exercise(d: &mut impl EscAccess, esc_type: u8, pdi_control: u16) {
    assert_eq!(d.read_u8(0x0000).unwrap(), esc_type);
    assert_eq!(d.read_u16(0x0012).unwrap(), 0x0042, "alias from SII word 4");
    assert_eq!(
        d.read_u16(0x0140).unwrap(),
        pdi_control,
        "PDI control from SII word 0"
    );
    assert_eq!(d.read_u16(0x0110).unwrap() & 1, 1, "EEPROM loaded");
    d.write_u16(0x0130, 0x0002).unwrap();
    assert_eq!(d.read_u16(0x0130).unwrap(), 0x0002);
    let data: Vec<u8> = (0..37).map(|i| i as u8 ^ 0x5A).collect();
    d.write(0x1801, &data).unwrap();
    let mut back = vec![0u8; 37];
    d.read(0x1801, &mut back).unwrap();
    assert_eq!(back, data);
    assert!(d.al_event().is_ok());
}

#[test]
fn drivers_compose_with_the_esc_simulator() {
    use ecat_slave_stack::sii::EscFlavour;
    use tests_host::esc_sim::{EscSim, Flavour};

    let sim = EscSim::new(Flavour::Lan9252, sii_image(EscFlavour::Lan9252));
    let mut d = Lan9252::new(Lan9252Model::new(sim), Lan9252Config::default());
    d.init(&mut NoDelay(0)).unwrap();
    exercise(
        &mut d,
        Flavour::Lan9252.esc_type(),
        EscFlavour::Lan9252.pdi_control(),
    );
    assert_eq!(d.spi_mut().esc.al_status(), 0x0002);
    assert_eq!(d.spi_mut().esc.peek(0x1801, 2), &[0x5A, 0x5B]);
    assert!(
        d.spi_mut().violations.is_empty(),
        "{:?}",
        d.spi_mut().violations
    );

    let sim = EscSim::new(Flavour::Et1100, sii_image(EscFlavour::Et1100));
    let mut d = Et1100::new(Et1100Model::new(sim), Et1100Config::default());
    d.init(&mut NoDelay(0)).unwrap();
    exercise(
        &mut d,
        Flavour::Et1100.esc_type(),
        EscFlavour::Et1100.pdi_control(),
    );
    assert_eq!(d.spi_mut().esc.al_status(), 0x0002);
    assert!(
        d.spi_mut().violations.is_empty(),
        "{:?}",
        d.spi_mut().violations
    );
}

// ------------------------------------------------------------------ board self-test

/// The self-test's ESC checks (`firmware::selftest`) through both drivers and their
/// chip models: the type register, and a process-RAM word through the LAN9252's FIFO
/// path and the ET1100's direct access.
#[test]
fn selftest_esc_checks_through_both_drivers() {
    use ecat_slave_stack::{et1100::ET1100_TYPE, lan9252::LAN9252_TYPE};
    use firmware::selftest::{esc_identity, process_ram_word, Verdict, SCRATCH_PRAM};

    let mut l = lan_default();
    l.spi_mut().esc.mem[0] = LAN9252_TYPE;
    assert_eq!(esc_identity(&mut l, LAN9252_TYPE), Verdict::Pass);
    assert!(!esc_identity(&mut l, ET1100_TYPE).passed());
    assert_eq!(process_ram_word(&mut l, SCRATCH_PRAM), Verdict::Pass);
    let a = usize::from(SCRATCH_PRAM);
    assert_eq!(l.spi_mut().esc.mem[a..a + 4], [0; 4]);
    assert!(
        l.spi_mut().violations.is_empty(),
        "{:?}",
        l.spi_mut().violations
    );

    let mut e = et(Et1100Config::default());
    e.spi_mut().esc.mem[0] = ET1100_TYPE;
    assert_eq!(esc_identity(&mut e, ET1100_TYPE), Verdict::Pass);
    assert_eq!(process_ram_word(&mut e, SCRATCH_PRAM), Verdict::Pass);
    assert_eq!(e.spi_mut().esc.mem[a..a + 4], [0; 4]);
}
