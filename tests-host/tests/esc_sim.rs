//! The ESC simulator on its own: datagram commands, working counters, access rights,
//! SyncManagers, FMMUs, SII, watchdog, DC, and garbage frames.

use ecat_slave_stack::registers as reg;
use ecat_slave_stack::EscAccess;
use tests_host::esc_sim::frame::{
    datagrams, process_frame, Command, DatagramView, FrameBuilder, FrameOutcome,
};
use tests_host::esc_sim::{sii_crc8, EscSim, Flavour, Side};

const HOP: u64 = 500;

/// A small SII image: config area (alias in word 4), identity, mailbox words,
/// EEPROM size word, end marker.
fn sii_image(alias: u16) -> Vec<u8> {
    let mut s = vec![0u8; 256];
    s[0..2].copy_from_slice(&0x0C80u16.to_le_bytes());
    s[8..10].copy_from_slice(&alias.to_le_bytes());
    s[14] = sii_crc8(&s[0..14]);
    s[16..20].copy_from_slice(&0x0000_0E5Cu32.to_le_bytes());
    s[20..24].copy_from_slice(&0x0000_5840u32.to_le_bytes());
    for (i, b) in s.iter_mut().enumerate().skip(0x80) {
        *b = i as u8;
    }
    s[0x7C] = 1; // 2 Kibit
    s[0x80..0x82].copy_from_slice(&0xFFFFu16.to_le_bytes());
    s
}

fn chain(n: usize, f: Flavour) -> Vec<EscSim> {
    (0..n)
        .map(|i| {
            let mut e = EscSim::new(f, sii_image(0x100 + i as u16));
            e.set_ports(i + 1 < n);
            e.set_clock_base(1_000_000 * i as u64 + 12_345);
            e
        })
        .collect()
}

fn run_at(escs: &mut [EscSim], fb: FrameBuilder, t: u64) -> Vec<DatagramView> {
    let mut f = fb.build();
    let src = f[6];
    let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
    let out = process_frame(&mut refs, &mut f, t, HOP);
    assert!(matches!(out, FrameOutcome::Processed { .. }), "{out:?}");
    assert_eq!(
        f[6],
        src | 0x02,
        "locally administered bit set on the way back"
    );
    datagrams(&f).unwrap()
}

fn run(escs: &mut [EscSim], fb: FrameBuilder) -> Vec<DatagramView> {
    let t = escs[0].now_ns();
    run_at(escs, fb, t)
}

fn one(escs: &mut [EscSim], cmd: Command, adp: u16, ado: u16, data: &[u8]) -> DatagramView {
    run(escs, FrameBuilder::new().physical(cmd, adp, ado, data)).remove(0)
}

fn set_addresses(escs: &mut [EscSim]) {
    for i in 0..escs.len() {
        let d = one(
            escs,
            Command::Apwr,
            0u16.wrapping_sub(i as u16),
            reg::STATION_ADDRESS.addr(),
            &(0x1000 + i as u16).to_le_bytes(),
        );
        assert_eq!(d.wkc, 1);
    }
}

fn pdi_u16(e: &mut EscSim, addr: u16) -> u16 {
    e.read_u16(addr).unwrap()
}

#[test]
fn esc_information_per_flavour() {
    for (f, fmmus, sms, kib) in [(Flavour::Lan9252, 3, 4, 4), (Flavour::Et1100, 8, 8, 8)] {
        let mut escs = chain(3, f);
        let d = one(&mut escs, Command::Brd, 0, 0x0000, &[0; 10]);
        assert_eq!(d.wkc, 3, "BRD working counter = slave count");
        assert_eq!(
            d.addr & 0xFFFF,
            3,
            "broadcast increments ADP in every slave"
        );
        assert_eq!(d.data[0], f.esc_type());
        assert_eq!(d.data[4], fmmus);
        assert_eq!(d.data[5], sms);
        assert_eq!(d.data[6], kib);
        assert_eq!(u16::from_le_bytes([d.data[8], d.data[9]]), f.features());
        assert_eq!(escs[0].peek(0x0000, 0x10000).len(), f.address_space());
    }
}

#[test]
fn auto_increment_and_configured_addressing() {
    let mut escs = chain(4, Flavour::Et1100);
    set_addresses(&mut escs);
    for (i, e) in escs.iter().enumerate() {
        assert_eq!(e.station_address(), 0x1000 + i as u16);
    }
    // APRD at position -2 reads the third slave; ADP comes back incremented 4 times.
    let d = one(
        &mut escs,
        Command::Aprd,
        0xFFFE,
        reg::STATION_ADDRESS.addr(),
        &[0, 0],
    );
    assert_eq!(d.wkc, 1);
    assert_eq!(d.data, 0x1002u16.to_le_bytes());
    assert_eq!(d.addr & 0xFFFF, 2);
    // Position beyond the segment: nobody answers.
    let d = one(
        &mut escs,
        Command::Aprd,
        0xFFF0,
        reg::STATION_ADDRESS.addr(),
        &[0xAA, 0xBB],
    );
    assert_eq!(d.wkc, 0);
    assert_eq!(d.data, [0xAA, 0xBB]);
    // FPRD by station address and by alias (alias only once DL control bit 24 is set).
    let d = one(
        &mut escs,
        Command::Fprd,
        0x1003,
        reg::STATION_ADDRESS.addr(),
        &[0, 0],
    );
    assert_eq!(
        (d.wkc, d.data.as_slice()),
        (1, &0x1003u16.to_le_bytes()[..])
    );
    let d = one(
        &mut escs,
        Command::Fprd,
        0x0101,
        reg::STATION_ALIAS.addr(),
        &[0, 0],
    );
    assert_eq!(d.wkc, 0);
    one(
        &mut escs,
        Command::Fpwr,
        0x1001,
        reg::DL_CONTROL.addr() + 3,
        &[1],
    );
    let d = one(
        &mut escs,
        Command::Fprd,
        0x0101,
        reg::STATION_ALIAS.addr(),
        &[0, 0],
    );
    assert_eq!(
        (d.wkc, d.data.as_slice()),
        (1, &0x0101u16.to_le_bytes()[..]),
        "alias loaded from SII word 4"
    );
}

#[test]
fn working_counter_rules_for_every_command() {
    let mut escs = chain(3, Flavour::Lan9252);
    set_addresses(&mut escs);
    let user = 0x0F80;
    // Writes count 1 per slave written.
    assert_eq!(one(&mut escs, Command::Bwr, 0, user, &[1, 2]).wkc, 3);
    assert_eq!(one(&mut escs, Command::Apwr, 0xFFFF, user, &[7, 7]).wkc, 1);
    assert_eq!(one(&mut escs, Command::Fpwr, 0x1002, user, &[9, 9]).wkc, 1);
    // BRD ORs every slave's data into the datagram.
    let d = one(&mut escs, Command::Brd, 0, user, &[0x10, 0]);
    assert_eq!(d.wkc, 3);
    assert_eq!(d.data, [0x10 | 1 | 7 | 9, 2 | 7 | 9]);
    // Read-write: +3, data returned is the old content.
    let d = one(&mut escs, Command::Aprw, 0, user, &[0x55, 0x66]);
    assert_eq!((d.wkc, d.data.as_slice()), (3, &[1u8, 2][..]));
    let d = one(&mut escs, Command::Fprw, 0x1000, user, &[0, 0]);
    assert_eq!((d.wkc, d.data.as_slice()), (3, &[0x55u8, 0x66][..]));
    let d = one(&mut escs, Command::Brw, 0, user, &[0, 0]);
    assert_eq!(d.wkc, 9);
    assert_eq!(d.data, [7 | 9, 7 | 9]);
    // ARMW: slave at position 0 reads, the others write what it read.
    one(&mut escs, Command::Apwr, 0, user, &[0xA5, 0x5A]);
    let d = one(&mut escs, Command::Armw, 0, user, &[0, 0]);
    assert_eq!((d.wkc, d.data.as_slice()), (3, &[0xA5u8, 0x5A][..]));
    for i in 1..3 {
        let d = one(
            &mut escs,
            Command::Aprd,
            0u16.wrapping_sub(i),
            user,
            &[0, 0],
        );
        assert_eq!(d.data, [0xA5, 0x5A]);
    }
    // FRMW: the addressed slave (the second) reads; the first and third write.
    one(&mut escs, Command::Fpwr, 0x1001, user, &[0x11, 0x22]);
    let d = one(&mut escs, Command::Frmw, 0x1001, user, &[0, 0]);
    assert_eq!(d.wkc, 3);
    assert_eq!(d.data, [0x11, 0x22]);
    assert_eq!(
        one(&mut escs, Command::Fprd, 0x1002, user, &[0, 0]).data,
        [0x11, 0x22]
    );
    // The first slave sits before the reader: it writes what arrived (zeros).
    assert_eq!(
        one(&mut escs, Command::Fprd, 0x1000, user, &[0xEE, 0xEE]).data,
        [0, 0]
    );
    // NOP and unknown commands: nothing happens.
    let d = run(
        &mut escs,
        FrameBuilder::new()
            .raw(0, 0x0F80_0000, &[1])
            .raw(15, 0x0F80_0000, &[1])
            .raw(0xFF, 0, &[]),
    );
    assert!(d.iter().all(|d| d.wkc == 0));
    // Several datagrams per frame, each with its own counter.
    let d = run(
        &mut escs,
        FrameBuilder::new()
            .physical(Command::Brd, 0, 0, &[0])
            .physical(Command::Fprd, 0x1001, 0x0010, &[0, 0])
            .physical(Command::Fprd, 0x7777, 0x0010, &[0, 0]),
    );
    assert_eq!(d.iter().map(|d| d.wkc).collect::<Vec<_>>(), vec![3, 1, 0]);
}

#[test]
fn out_of_range_physical_accesses() {
    for f in [Flavour::Lan9252, Flavour::Et1100] {
        let mut escs = chain(1, f);
        let end = f.address_space() as u16;
        // Entirely outside: not accepted, data unchanged.
        let d = one(&mut escs, Command::Aprd, 0, end, &[0xAB; 4]);
        assert_eq!((d.wkc, d.data.as_slice()), (0, &[0xABu8; 4][..]));
        assert_eq!(one(&mut escs, Command::Apwr, 0, end + 16, &[1; 4]).wkc, 0);
        assert_eq!(one(&mut escs, Command::Aprd, 0, 0xFFFF, &[0; 8]).wkc, 0);
        // Straddling the end: the inside part is accessed.
        let d = one(&mut escs, Command::Aprw, 0, end - 2, &[1, 2, 3, 4]);
        assert_eq!(d.wkc, 3);
        assert_eq!(d.data, [0, 0, 3, 4]);
        assert_eq!(escs[0].peek(end - 2, 4), &[1, 2]);
    }
}

#[test]
fn access_rights_ecat_versus_pdi() {
    let mut escs = chain(1, Flavour::Et1100);
    // The master cannot write AL status, ESC information, DL status or the AL event mask.
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::AL_STATUS.addr(),
        &[0x08, 0, 0, 0, 0x1B, 0],
    );
    assert_eq!(escs[0].al_status(), 0x0001);
    assert_eq!(escs[0].al_status_code(), 0);
    one(&mut escs, Command::Apwr, 0, 0x0000, &[0xFF; 10]);
    assert_eq!(escs[0].peek(0x0004, 1), &[8]);
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::AL_EVENT_MASK.addr(),
        &[0xFF; 4],
    );
    assert_eq!(escs[0].peek(reg::AL_EVENT_MASK.addr(), 4), &[0; 4]);
    // The PDI cannot write AL control, the station address or FMMUs/SM configuration.
    let e = &mut escs[0];
    e.write_u16(reg::AL_CONTROL.addr(), 0x0008).unwrap();
    e.write_u16(reg::STATION_ADDRESS.addr(), 0x4444).unwrap();
    e.write(reg::fmmu_register(0), &[0xFF; 16]).unwrap();
    e.write(reg::sm_register(0), &[0xFF; 7]).unwrap();
    assert_eq!(e.peek(reg::AL_CONTROL.addr(), 2), &[1, 0]);
    assert_eq!(e.peek(reg::STATION_ADDRESS.addr(), 2), &[0, 0]);
    assert_eq!(e.peek(reg::fmmu_register(0), 16), &[0; 16]);
    assert_eq!(e.peek(reg::sm_register(0), 7), &[0; 7]);
    // The PDI writes AL status and code and the event mask.
    e.write(reg::AL_STATUS.addr(), &[0x12, 0, 0, 0, 0x16, 0])
        .unwrap();
    e.write_u32(reg::AL_EVENT_MASK.addr(), 0x0000_0001).unwrap();
    assert_eq!((e.al_status(), e.al_status_code()), (0x12, 0x16));
    // An AL status change raises ECAT event bit 3, visible in the IRQ field once masked.
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::ECAT_EVENT_MASK.addr(),
        &[0x08, 0],
    );
    let d = one(&mut escs, Command::Aprd, 0, reg::AL_STATUS.addr(), &[0; 6]);
    assert_eq!(d.irq & 0x08, 0x08);
    assert_eq!(d.data, [0x12, 0, 0, 0, 0x16, 0]);
    let d = one(&mut escs, Command::Aprd, 0, reg::AL_STATUS.addr(), &[0; 2]);
    assert_eq!(
        d.irq & 0x08,
        0,
        "reading AL status from ECAT clears the event"
    );
    // Error counters: a master write clears them whatever the value.
    one(&mut escs, Command::Apwr, 0, 0x0300, &[5; 4]);
    assert_eq!(escs[0].peek(0x0300, 4), &[0; 4]);
}

#[test]
fn al_control_event_and_mailbox_like_handshake() {
    let mut escs = chain(1, Flavour::Lan9252);
    escs[0]
        .write_u32(reg::AL_EVENT_MASK.addr(), reg::al_event::AL_CONTROL)
        .unwrap();
    assert!(!escs[0].pdi_irq());
    assert_eq!(
        one(
            &mut escs,
            Command::Apwr,
            0,
            reg::AL_CONTROL.addr(),
            &[0x02, 0]
        )
        .wkc,
        1
    );
    let e = &mut escs[0];
    assert_eq!(e.al_event().unwrap() & 1, 1);
    assert!(e.pdi_irq());
    // A second request before the PDI read it is not taken.
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::AL_CONTROL.addr(),
        &[0x04, 0],
    );
    let e = &mut escs[0];
    assert_eq!(e.stats().al_control_writes_ignored, 1);
    assert_eq!(pdi_u16(e, reg::AL_CONTROL.addr()), 0x0002);
    assert_eq!(
        e.al_event().unwrap() & 1,
        0,
        "reading AL control clears AL event bit 0"
    );
    assert!(!e.pdi_irq());
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::AL_CONTROL.addr(),
        &[0x04, 0],
    );
    assert_eq!(pdi_u16(&mut escs[0], reg::AL_CONTROL.addr()), 0x0004);
    // Device emulation (0x0141 bit 0) mirrors AL control into AL status.
    let mut s = sii_image(0);
    s[1] = 0x01;
    s[14] = sii_crc8(&s[0..14]);
    let mut emu = vec![EscSim::new(Flavour::Et1100, s)];
    one(
        &mut emu,
        Command::Apwr,
        0,
        reg::AL_CONTROL.addr(),
        &[0x02, 0],
    );
    one(
        &mut emu,
        Command::Apwr,
        0,
        reg::AL_CONTROL.addr(),
        &[0x04, 0],
    );
    assert_eq!(emu[0].al_status(), 0x0004);
}

fn configure_sm(escs: &mut [EscSim], adp: u16, n: u8, start: u16, len: u16, control: u8) {
    let mut b = [0u8; 8];
    b[0..2].copy_from_slice(&start.to_le_bytes());
    b[2..4].copy_from_slice(&len.to_le_bytes());
    b[4] = control;
    b[6] = 1;
    assert_eq!(
        one(escs, Command::Apwr, adp, reg::sm_register(n), &b).wkc,
        1
    );
}

#[test]
fn sm_configuration_is_locked_while_enabled_and_activation_raises_event() {
    let mut escs = chain(1, Flavour::Et1100);
    configure_sm(&mut escs, 0, 0, 0x1000, 128, 0x26);
    assert_eq!(
        escs[0].al_event().unwrap() & reg::al_event::SM_CHANGE,
        reg::al_event::SM_CHANGE
    );
    let _ = escs[0].read_u8(reg::sm_register(0) + 6).unwrap();
    assert_eq!(
        escs[0].al_event().unwrap() & reg::al_event::SM_CHANGE,
        0,
        "PDI read of activate acknowledges"
    );
    // Rewriting start/length/control while enabled has no effect.
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::sm_register(0),
        &[0x00, 0x18, 0x10, 0, 0x22],
    );
    assert_eq!(
        escs[0].peek(reg::sm_register(0), 5),
        &[0x00, 0x10, 128, 0, 0x26]
    );
    // Disable, then the configuration is writable again (SOEM-style 16-byte write).
    one(&mut escs, Command::Apwr, 0, reg::sm_register(0) + 6, &[0]);
    let mut two = [0u8; 16];
    two[0..8].copy_from_slice(&[0x00, 0x18, 0x80, 0, 0x26, 0, 1, 0]);
    two[8..16].copy_from_slice(&[0x80, 0x18, 0x80, 0, 0x22, 0, 1, 0]);
    one(&mut escs, Command::Apwr, 0, reg::sm_register(0), &two);
    assert_eq!(escs[0].peek(reg::sm_register(0), 16), &two);
}

#[test]
fn mailbox_sync_managers() {
    let mut escs = chain(1, Flavour::Lan9252);
    configure_sm(&mut escs, 0, 0, 0x1000, 128, 0x26);
    configure_sm(&mut escs, 0, 1, 0x1080, 128, 0x22);
    let e = &mut escs[0];
    e.write_u32(
        reg::AL_EVENT_MASK.addr(),
        reg::al_event::sm(0) | reg::al_event::sm(1),
    )
    .unwrap();
    // Master → slave (SM0): the write of the whole buffer fills it.
    let req: Vec<u8> = (0..128u8).collect();
    assert_eq!(one(&mut escs, Command::Apwr, 0, 0x1000, &req).wkc, 1);
    let e = &mut escs[0];
    assert_eq!(
        e.peek(reg::sm_register(0) + 5, 1)[0] & 0x08,
        0x08,
        "SM0 full"
    );
    assert!(e.pdi_irq());
    assert_eq!(
        e.al_event().unwrap() & reg::al_event::sm(0),
        reg::al_event::sm(0)
    );
    // A second write while full is refused (WKC 0) and does not change the buffer.
    assert_eq!(
        one(&mut escs, Command::Apwr, 0, 0x1000, &[0xEE; 128]).wkc,
        0
    );
    let e = &mut escs[0];
    let mut got = vec![0u8; 128];
    e.read(0x1000, &mut got[..64]).unwrap();
    assert_eq!(
        e.al_event().unwrap() & reg::al_event::sm(0),
        0,
        "PDI access clears the SM event"
    );
    assert_eq!(
        e.peek(reg::sm_register(0) + 5, 1)[0] & 0x08,
        0x08,
        "still full until the last byte is read"
    );
    e.read(0x1040, &mut got[64..]).unwrap();
    assert_eq!(got, req);
    assert_eq!(
        e.peek(reg::sm_register(0) + 5, 1)[0] & 0x08,
        0,
        "reading the last byte empties SM0"
    );
    // Slave → master (SM1): reading an empty mailbox is not counted.
    let d = one(&mut escs, Command::Aprd, 0, 0x1080, &[0; 128]);
    assert_eq!(d.wkc, 0);
    let e = &mut escs[0];
    e.write(0x1080, &[0x42; 10]).unwrap();
    assert_eq!(
        e.peek(reg::sm_register(1) + 5, 1)[0] & 0x08,
        0,
        "not full before the last byte"
    );
    e.write(0x10FF, &[0x99]).unwrap();
    assert_eq!(e.peek(reg::sm_register(1) + 5, 1)[0] & 0x08, 0x08);
    // PDI cannot overwrite a full mailbox.
    e.write(0x1080, &[0x00; 4]).unwrap();
    let d = one(&mut escs, Command::Aprd, 0, 0x1080, &[0; 128]);
    assert_eq!(d.wkc, 1);
    assert_eq!(&d.data[..10], &[0x42; 10]);
    assert_eq!(d.data[127], 0x99);
    let e = &mut escs[0];
    assert_eq!(
        e.peek(reg::sm_register(1) + 5, 1)[0] & 0x08,
        0,
        "master read of the last byte empties SM1"
    );
    assert_eq!(
        e.al_event().unwrap() & reg::al_event::sm(1),
        reg::al_event::sm(1),
        "SM1 event: mailbox read by the master"
    );
    // Reading the mailbox in the wrong direction / PDI writing SM0: refused.
    assert!(!e.side_write(Side::Pdi, 0x1000, &[1]));
    // Repeat request: the master toggles activate bit 1 → SM change event.
    let _ = e.read_u8(reg::sm_register(1) + 6).unwrap();
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::sm_register(1) + 6,
        &[0x03],
    );
    let e = &mut escs[0];
    assert_ne!(e.al_event().unwrap() & reg::al_event::SM_CHANGE, 0);
    // The PDI deactivates SM1 (PDI control bit 0), which clears a full buffer, and
    // acknowledges the repeat in bit 1.
    e.write(0x1080, &[7; 128]).unwrap();
    assert_eq!(e.peek(reg::sm_register(1) + 5, 1)[0] & 0x08, 0x08);
    e.write_u8(reg::sm_register(1) + 7, 0x01).unwrap();
    assert_eq!(e.peek(reg::sm_register(1) + 5, 1)[0] & 0x08, 0);
    e.write_u8(reg::sm_register(1) + 7, 0x02).unwrap();
    e.write(0x1080, &[8; 128]).unwrap();
    let d = one(&mut escs, Command::Aprd, 0, reg::sm_register(1), &[0; 8]);
    assert_eq!(d.data[5] & 0x08, 0x08);
    assert_eq!(d.data[7], 0x02, "repeat acknowledge visible to the master");
}

#[test]
fn three_buffer_consumer_gets_latest_complete_buffer() {
    let mut escs = chain(1, Flavour::Et1100);
    configure_sm(&mut escs, 0, 2, 0x1100, 4, 0x64);
    configure_sm(&mut escs, 0, 3, 0x1400, 4, 0x20);
    escs[0]
        .write_u32(reg::AL_EVENT_MASK.addr(), reg::al_event::sm(2))
        .unwrap();
    // Master writes A then B: the PDI gets B.
    one(&mut escs, Command::Apwr, 0, 0x1100, &[0xA; 4]);
    one(&mut escs, Command::Apwr, 0, 0x1100, &[0xB; 4]);
    assert!(escs[0].pdi_irq());
    let mut b = [0u8; 4];
    escs[0].read(0x1100, &mut b).unwrap();
    assert_eq!(b, [0xB; 4]);
    assert!(!escs[0].pdi_irq());
    // The PDI opens the buffer (first two bytes); the master writes C, D meanwhile; the
    // PDI finishes reading B untorn, and the next read gets D.
    one(&mut escs, Command::Apwr, 0, 0x1100, &[0xC; 4]);
    escs[0].read(0x1100, &mut b[..2]).unwrap();
    one(&mut escs, Command::Apwr, 0, 0x1100, &[0xD; 4]);
    one(&mut escs, Command::Apwr, 0, 0x1100, &[0xE; 4]);
    escs[0].read(0x1102, &mut b[2..]).unwrap();
    assert_eq!(
        b, [0xC; 4],
        "buffer opened before the writes stays consistent"
    );
    escs[0].read(0x1100, &mut b).unwrap();
    assert_eq!(b, [0xE; 4]);
    // A partial master write (no last byte) is not committed.
    one(&mut escs, Command::Apwr, 0, 0x1100, &[0xF; 3]);
    escs[0].read(0x1100, &mut b).unwrap();
    assert_eq!(b, [0xE; 4]);
    // Inputs: PDI writes, master reads the newest; the master cannot write SM3.
    escs[0].write(0x1400, &[1; 4]).unwrap();
    escs[0].write(0x1400, &[2; 4]).unwrap();
    let d = one(&mut escs, Command::Aprd, 0, 0x1400, &[0; 4]);
    assert_eq!((d.wkc, d.data.as_slice()), (1, &[2u8; 4][..]));
    assert_eq!(one(&mut escs, Command::Apwr, 0, 0x1400, &[9; 4]).wkc, 0);
    assert_ne!(
        escs[0].peek(reg::sm_register(3) + 5, 1)[0] & 0x30,
        0x30,
        "a buffer has been written"
    );
    let fresh = chain(1, Flavour::Et1100);
    assert_eq!(
        fresh[0].peek(reg::sm_register(3) + 5, 1)[0],
        0,
        "disabled SM: status clear"
    );
}

#[allow(clippy::too_many_arguments)] // one argument per FMMU register field
fn configure_fmmu(
    escs: &mut [EscSim],
    adp: u16,
    n: u8,
    log: u32,
    len: u16,
    log_bits: (u8, u8),
    phys: u16,
    phys_bit: u8,
    ty: u8,
) {
    let mut b = [0u8; 16];
    b[0..4].copy_from_slice(&log.to_le_bytes());
    b[4..6].copy_from_slice(&len.to_le_bytes());
    b[6] = log_bits.0;
    b[7] = log_bits.1;
    b[8..10].copy_from_slice(&phys.to_le_bytes());
    b[10] = phys_bit;
    b[11] = ty;
    b[12] = 1;
    assert_eq!(
        one(escs, Command::Apwr, adp, reg::fmmu_register(n), &b).wkc,
        1
    );
}

#[test]
fn lrw_over_two_slaves_with_sync_managers() {
    let mut escs = chain(2, Flavour::Lan9252);
    // Logical image: [in0 (2)][in1 (2)][out0 (2)][out1 (2)].
    for i in 0..2u16 {
        let adp = 0u16.wrapping_sub(i);
        configure_sm(&mut escs, adp, 2, 0x1100, 2, 0x64);
        configure_sm(&mut escs, adp, 3, 0x1400, 2, 0x20);
        configure_fmmu(
            &mut escs,
            adp,
            0,
            0x10004 + 2 * i as u32,
            2,
            (0, 7),
            0x1100,
            0,
            2,
        );
        configure_fmmu(
            &mut escs,
            adp,
            1,
            0x10000 + 2 * i as u32,
            2,
            (0, 7),
            0x1400,
            0,
            1,
        );
    }
    escs[0].write(0x1400, &[0x11, 0x12]).unwrap();
    escs[1].write(0x1400, &[0x21, 0x22]).unwrap();
    let d = run(
        &mut escs,
        FrameBuilder::new().logical(Command::Lrw, 0x10000, &[0, 0, 0, 0, 0xA1, 0xA2, 0xB1, 0xB2]),
    );
    assert_eq!(d[0].wkc, 6, "LRW: 3 per slave (read + write)");
    assert_eq!(d[0].data[..4], [0x11, 0x12, 0x21, 0x22]);
    let mut o = [0u8; 2];
    escs[0].read(0x1100, &mut o).unwrap();
    assert_eq!(o, [0xA1, 0xA2]);
    escs[1].read(0x1100, &mut o).unwrap();
    assert_eq!(o, [0xB1, 0xB2]);
    // LRD / LWR count 1 per slave; a logical window nobody maps counts 0.
    assert_eq!(
        run(
            &mut escs,
            FrameBuilder::new().logical(Command::Lrd, 0x10000, &[0; 8])
        )[0]
        .wkc,
        2
    );
    assert_eq!(
        run(
            &mut escs,
            FrameBuilder::new().logical(Command::Lwr, 0x10000, &[0; 8])
        )[0]
        .wkc,
        2
    );
    assert_eq!(
        run(
            &mut escs,
            FrameBuilder::new().logical(Command::Lrw, 0x20000, &[0; 8])
        )[0]
        .wkc,
        0
    );
    // LRW covering only the inputs: read only (+1 each).
    assert_eq!(
        run(
            &mut escs,
            FrameBuilder::new().logical(Command::Lrw, 0x10000, &[0; 4])
        )[0]
        .wkc,
        2
    );
    // LRW covering only the outputs: write only (+2 each).
    assert_eq!(
        run(
            &mut escs,
            FrameBuilder::new().logical(Command::Lrw, 0x10004, &[0; 4])
        )[0]
        .wkc,
        4
    );
    // LRW covering the inputs of slave 0 and the outputs of slave 1 only: +1 +2.
    configure_fmmu(&mut escs, 0xFFFF, 0, 0x10002, 2, (0, 7), 0x1100, 0, 2);
    configure_fmmu(&mut escs, 0xFFFF, 1, 0x20000, 2, (0, 7), 0x1400, 0, 1);
    assert_eq!(
        run(
            &mut escs,
            FrameBuilder::new().logical(Command::Lrw, 0x10000, &[0; 4])
        )[0]
        .wkc,
        3
    );
}

#[test]
fn bit_granular_fmmu_mapping() {
    // Two slaves share logical byte 0x100: slave 0 bits 0..3, slave 1 bits 4..7.
    let mut escs = chain(2, Flavour::Et1100);
    configure_fmmu(&mut escs, 0, 0, 0x100, 1, (0, 3), 0x0F80, 0, 1);
    configure_fmmu(&mut escs, 0xFFFF, 0, 0x100, 1, (4, 7), 0x0F80, 2, 1);
    configure_fmmu(&mut escs, 0, 1, 0x101, 1, (2, 5), 0x0F90, 4, 2);
    escs[0].write_u8(0x0F80, 0b0000_1010).unwrap();
    escs[1].write_u16(0x0F80, 0b0000_0011_1100).unwrap();
    let d = run(
        &mut escs,
        FrameBuilder::new().logical(Command::Lrd, 0x100, &[0xFF, 0]),
    );
    assert_eq!(d[0].wkc, 2);
    // slave 0 supplies its bits 0..3 (1010); slave 1 its physical bits 2..5 (1111).
    assert_eq!(d[0].data[0], 0b1111_1010);
    // Logical bits 2..5 of byte 0x101 → physical 0x0F90 bits 4..7, neighbours kept.
    escs[0].write_u8(0x0F90, 0b0000_0110).unwrap();
    let d = run(
        &mut escs,
        FrameBuilder::new().logical(Command::Lwr, 0x101, &[0b0010_1000]),
    );
    assert_eq!(d[0].wkc, 1);
    assert_eq!(escs[0].peek(0x0F90, 1)[0], 0b1010_0110);
}

fn sii_read(escs: &mut [EscSim], word: u16) -> (Vec<u8>, usize) {
    let mut cmd = [0u8; 6];
    cmd[1] = 0x01;
    cmd[2..4].copy_from_slice(&word.to_le_bytes());
    assert_eq!(
        one(escs, Command::Fpwr, 0x1000, reg::SII_CONTROL.addr(), &cmd).wkc,
        1
    );
    let mut polls = 0;
    loop {
        polls += 1;
        let d = one(
            escs,
            Command::Fprd,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0, 0],
        );
        let st = u16::from_le_bytes([d.data[0], d.data[1]]);
        if st & 0x8000 == 0 {
            let n = if st & 0x40 != 0 { 8 } else { 4 };
            let d = one(
                escs,
                Command::Fprd,
                0x1000,
                reg::SII_DATA.addr(),
                &vec![0; n],
            );
            return (d.data, polls);
        }
        assert!(polls < 10);
    }
}

#[test]
fn sii_eeprom_interface() {
    for (f, n) in [(Flavour::Lan9252, 4), (Flavour::Et1100, 8)] {
        let mut escs = chain(1, f);
        set_addresses(&mut escs);
        let img = escs[0].sii().to_vec();
        // Ownership dance as ethercrab does it.
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_CONFIG.addr(),
            &[2],
        );
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_CONFIG.addr(),
            &[0],
        );
        for w in [0u16, 4, 8, 0x40, 0x7F] {
            let (data, polls) = sii_read(&mut escs, w);
            assert_eq!(polls, 2, "busy seen once");
            let o = 2 * w as usize;
            let expect: Vec<u8> = (0..n)
                .map(|i| img.get(o + i).copied().unwrap_or(0xFF))
                .collect();
            assert_eq!(data, expect);
        }
        // Past the image: erased EEPROM.
        assert_eq!(sii_read(&mut escs, 0x4000).0, vec![0xFF; n]);
        // Write without write enable: error bit 14; with enable: stored.
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_DATA.addr(),
            &[0x34, 0x12],
        );
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0x00, 0x02, 0x50, 0, 0, 0],
        );
        let st = one(
            &mut escs,
            Command::Fprd,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0, 0],
        );
        let st = u16::from_le_bytes([st.data[0], st.data[1]]);
        assert_ne!(st & 0x4000, 0);
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0x01, 0x02, 0x50, 0, 0, 0],
        );
        assert_eq!(&escs[0].sii()[0xA0..0xA2], &[0x34, 0x12]);
        // A command while busy is ignored: poll first.
        one(
            &mut escs,
            Command::Fprd,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0, 0],
        );
        // Unknown command: error bit 13.
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0x00, 0x07],
        );
        one(
            &mut escs,
            Command::Fprd,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0, 0],
        );
        let st = one(
            &mut escs,
            Command::Fprd,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0, 0],
        );
        assert_ne!(u16::from_le_bytes([st.data[0], st.data[1]]) & 0x2000, 0);
        // Offered to the PDI but not taken: the master keeps access.
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_CONFIG.addr(),
            &[1],
        );
        let before = escs[0].stats().sii_commands;
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0x00, 0x01, 0, 0, 0, 0],
        );
        assert_eq!(escs[0].stats().sii_commands, before + 1);
        one(
            &mut escs,
            Command::Fprd,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0, 0],
        );
        // Taken by the PDI (0x0501 bit 0): the master's commands are ignored.
        escs[0].write_u8(reg::SII_PDI_ACCESS.addr(), 1).unwrap();
        let before = escs[0].stats().sii_commands;
        one(
            &mut escs,
            Command::Fpwr,
            0x1000,
            reg::SII_CONTROL.addr(),
            &[0x00, 0x01, 0, 0, 0, 0],
        );
        assert_eq!(escs[0].stats().sii_commands, before);
        // The PDI can read it now.
        let e = &mut escs[0];
        e.write(reg::SII_CONTROL.addr(), &[0x00, 0x01, 0x08, 0, 0, 0])
            .unwrap();
        let _ = e.read_u16(reg::SII_CONTROL.addr()).unwrap();
        assert_eq!(e.read_u32(reg::SII_DATA.addr()).unwrap(), 0x0000_0E5C);
    }
}

#[test]
fn sii_checksum_error_and_short_image() {
    let mut bad = sii_image(7);
    bad[14] ^= 1;
    for img in [bad, vec![1, 2, 3], Vec::new()] {
        let mut escs = vec![EscSim::new(Flavour::Et1100, img)];
        let dl = one(&mut escs, Command::Aprd, 0, reg::DL_STATUS.addr(), &[0, 0]);
        assert_eq!(
            dl.data[0] & 1,
            0,
            "PDI not operational without a valid EEPROM"
        );
        let st = one(
            &mut escs,
            Command::Aprd,
            0,
            reg::SII_CONTROL.addr(),
            &[0, 0],
        );
        assert_ne!(st.data[1] & 0x10, 0, "not loaded");
        assert_eq!(escs[0].peek(reg::STATION_ALIAS.addr(), 2), &[0, 0]);
        // Reads still work and never panic.
        one(
            &mut escs,
            Command::Apwr,
            0,
            reg::SII_CONTROL.addr(),
            &[0, 1, 0xFF, 0xFF, 0xFF, 0xFF],
        );
        let d = one(&mut escs, Command::Aprd, 0, reg::SII_DATA.addr(), &[0; 8]);
        assert_eq!(d.data, vec![0xFF; 8]);
    }
}

#[test]
fn process_data_watchdog_in_simulated_time() {
    let mut escs = chain(1, Flavour::Lan9252);
    configure_sm(&mut escs, 0, 2, 0x1100, 2, 0x64);
    configure_fmmu(&mut escs, 0, 0, 0, 2, (0, 7), 0x1100, 0, 2);
    // Default divider 2498 and time 1000 → 100 ms.
    run(
        &mut escs,
        FrameBuilder::new().logical(Command::Lwr, 0, &[1, 2]),
    );
    escs[0].advance_to(99_000_000);
    assert!(escs[0].pd_watchdog_ok());
    run(
        &mut escs,
        FrameBuilder::new().logical(Command::Lwr, 0, &[1, 2]),
    );
    escs[0].advance_to(190_000_000);
    assert!(escs[0].pd_watchdog_ok(), "retriggered at 99 ms");
    escs[0].advance_to(200_000_001);
    assert!(!escs[0].pd_watchdog_ok());
    assert_eq!(escs[0].stats().pd_watchdog_expiries, 1);
    assert_ne!(escs[0].al_event().unwrap() & reg::al_event::WATCHDOG, 0);
    assert_eq!(
        escs[0].read_u16(reg::WATCHDOG_STATUS_PD.addr()).unwrap() & 1,
        0
    );
    assert_eq!(escs[0].al_event().unwrap() & reg::al_event::WATCHDOG, 0);
    assert_eq!(escs[0].peek(reg::WATCHDOG_COUNTER_PD.addr(), 1), &[1]);
    run(
        &mut escs,
        FrameBuilder::new().logical(Command::Lwr, 0, &[1, 2]),
    );
    assert!(escs[0].pd_watchdog_ok());
    // A shorter watchdog: divider 98 (4 µs) × 250 = 1 ms.
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::WATCHDOG_DIVIDER.addr(),
        &98u16.to_le_bytes(),
    );
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::WATCHDOG_TIME_PD.addr(),
        &250u16.to_le_bytes(),
    );
    let t = escs[0].now_ns();
    escs[0].advance_to(t + 1_000_001);
    assert!(!escs[0].pd_watchdog_ok());
    // 0 disables it.
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::WATCHDOG_TIME_PD.addr(),
        &[0, 0],
    );
    run(
        &mut escs,
        FrameBuilder::new().logical(Command::Lwr, 0, &[1, 2]),
    );
    let t = escs[0].now_ns();
    escs[0].advance_to(t + 10_000_000_000);
    assert!(escs[0].pd_watchdog_ok());
    // An SM without the watchdog bit does not trigger it.
    let mut e2 = chain(1, Flavour::Lan9252);
    configure_sm(&mut e2, 0, 2, 0x1100, 2, 0x24);
    one(&mut e2, Command::Apwr, 0, 0x1100, &[0, 0]);
    e2[0].advance_to(1_000_000_000);
    assert!(e2[0].pd_watchdog_ok());
}

#[test]
fn distributed_clocks_latching_offset_and_sync0() {
    let mut escs = chain(3, Flavour::Et1100);
    set_addresses(&mut escs);
    for e in escs.iter_mut() {
        e.advance_to(5_000_000);
    }
    assert_eq!(
        one(
            &mut escs,
            Command::Bwr,
            0,
            reg::DC_RECEIVE_TIME_PORT0.addr(),
            &[0; 4]
        )
        .wkc,
        3
    );
    let mut recv = Vec::new();
    for i in 0..3u16 {
        let d = one(
            &mut escs,
            Command::Fprd,
            0x1000 + i,
            reg::DC_RECEIVE_TIME_PORT0.addr(),
            &[0; 16],
        );
        let p0 = u32::from_le_bytes(d.data[0..4].try_into().unwrap());
        let p1 = u32::from_le_bytes(d.data[4..8].try_into().unwrap());
        let base = 1_000_000 * i as u64 + 12_345;
        assert_eq!(p0 as u64, 5_000_000 + base + HOP * i as u64);
        if i < 2 {
            // Back on port 1 after the rest of the line: 2·(n−1−i) hops later.
            assert_eq!(p1 - p0, (2 * (2 - i as u32)) * HOP as u32);
        } else {
            assert_eq!(p1, 0, "end of line: port 1 not latched");
        }
        let d = one(
            &mut escs,
            Command::Fprd,
            0x1000 + i,
            reg::DC_RECEIVE_TIME_PU.addr(),
            &[0; 8],
        );
        let pu = u64::from_le_bytes(d.data[..8].try_into().unwrap());
        assert_eq!(pu as u32, p0);
        recv.push(pu);
    }
    // Offsets as a master computes them; delays; then system-time distribution (FRMW).
    let master_now = 777_000_000_000u64;
    for i in 0..3u16 {
        let off = master_now.wrapping_sub(recv[i as usize]);
        one(
            &mut escs,
            Command::Fpwr,
            0x1000 + i,
            reg::DC_SYSTEM_TIME_OFFSET.addr(),
            &off.to_le_bytes(),
        );
        one(
            &mut escs,
            Command::Fpwr,
            0x1000 + i,
            reg::DC_SYSTEM_TIME_DELAY.addr(),
            &((HOP * i as u64) as u32).to_le_bytes(),
        );
    }
    for _ in 0..3 {
        let d = one(
            &mut escs,
            Command::Frmw,
            0x1000,
            reg::DC_SYSTEM_TIME.addr(),
            &[0; 8],
        );
        assert_eq!(d.wkc, 3);
    }
    let t = escs[0].now_ns();
    let times: Vec<u64> = escs.iter().map(|e| e.system_time()).collect();
    assert!(times.iter().all(|&s| s == times[0]), "{times:?}");
    assert_eq!(times[0], master_now + (t - 5_000_000));
    // SYNC0: start 1 ms from now, 250 µs cycle.
    let start = times[0] + 1_000_000;
    for i in 0..3u16 {
        one(
            &mut escs,
            Command::Fpwr,
            0x1000 + i,
            reg::DC_SYNC0_CYCLE.addr(),
            &250_000u32.to_le_bytes(),
        );
        one(
            &mut escs,
            Command::Fpwr,
            0x1000 + i,
            reg::DC_START_TIME.addr(),
            &start.to_le_bytes(),
        );
        one(
            &mut escs,
            Command::Fpwr,
            0x1000 + i,
            reg::DC_CYCLIC_UNIT_CONTROL.addr(),
            &[0x00, 0x03],
        );
    }
    escs[1]
        .write_u32(reg::AL_EVENT_MASK.addr(), reg::al_event::SYNC0)
        .unwrap();
    for e in escs.iter_mut() {
        e.advance_to(t + 999_000);
    }
    assert_eq!(escs[1].stats().sync0_pulses, 0);
    assert_eq!(
        escs[1].peek(reg::DC_ACTIVATION_STATUS.addr(), 1)[0] & 1,
        1,
        "first SYNC0 pending"
    );
    for e in escs.iter_mut() {
        e.advance_to(t + 1_000_000);
    }
    assert_eq!(escs[1].stats().sync0_pulses, 1);
    assert!(escs[1].pdi_irq());
    assert_eq!(escs[1].read_u8(reg::DC_SYNC0_STATUS.addr()).unwrap(), 1);
    assert!(!escs[1].pdi_irq(), "reading 0x098E clears AL event bit 2");
    for e in escs.iter_mut() {
        e.advance_to(t + 2_000_000);
    }
    assert_eq!(escs[2].stats().sync0_pulses, 5);
    // Four pulses since the last read of 0x098E, one event: a microcontroller late
    // for its SYNC0 interrupt sees one interrupt, not a burst (issue 32).
    assert_eq!(escs[1].stats().sync0_pulses, 5);
    assert!(escs[1].pdi_irq());
    assert_eq!(escs[1].read_u8(reg::DC_SYNC0_STATUS.addr()).unwrap(), 1);
    assert!(!escs[1].pdi_irq(), "one event for the four pulses");
    assert_eq!(
        escs[1].next_sync0_ns(),
        Some(t + 2_250_000),
        "the next pulse keeps the period"
    );
    let d = one(
        &mut escs,
        Command::Fprd,
        0x1001,
        reg::DC_START_TIME.addr(),
        &[0; 8],
    );
    assert_eq!(
        u64::from_le_bytes(d.data[..8].try_into().unwrap()),
        start + 5 * 250_000,
        "0x0990 reads the next SYNC0"
    );
    // A start time in the past never fires (the chip would wait for a wrap-around).
    one(
        &mut escs,
        Command::Fpwr,
        0x1000,
        reg::DC_ACTIVATION.addr(),
        &[0],
    );
    one(
        &mut escs,
        Command::Fpwr,
        0x1000,
        reg::DC_START_TIME.addr(),
        &1u64.to_le_bytes(),
    );
    one(
        &mut escs,
        Command::Fpwr,
        0x1000,
        reg::DC_ACTIVATION.addr(),
        &[3],
    );
    let before = escs[0].stats().sync0_pulses;
    escs[0].advance_to(t + 10_000_000);
    assert_eq!(escs[0].stats().sync0_pulses, before);
    assert_eq!(
        escs[0].peek(reg::DC_ACTIVATION_STATUS.addr(), 1)[0] & 0x04,
        0x04
    );
}

#[test]
fn non_ethercat_and_malformed_frames_pass_unchanged() {
    let mut escs = chain(2, Flavour::Lan9252);
    let good = FrameBuilder::new()
        .physical(Command::Bwr, 0, 0x0F80, &[1, 2, 3])
        .build();
    let mut cases: Vec<Vec<u8>> = vec![
        vec![],
        vec![0; 10],
        good[..15].to_vec(),
        good[..20].to_vec(),
    ];
    // EtherCAT length pointing past the frame.
    let mut c = good.clone();
    c[14] = 0xFF;
    c[15] = 0x17;
    cases.push(c);
    // Datagram data length past the EtherCAT length.
    let mut c = good.clone();
    c[16 + 6] = 0xF0;
    cases.push(c);
    // More-follows set on the last datagram.
    let mut c = good.clone();
    c[16 + 7] |= 0x80;
    cases.push(c);
    // Zero length.
    let mut c = good.clone();
    c[14] = 0;
    c[15] = 0x10;
    cases.push(c);
    for (k, case) in cases.into_iter().enumerate() {
        let mut f = case.clone();
        let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
        let out = process_frame(&mut refs, &mut f, 0, HOP);
        assert!(
            matches!(out, FrameOutcome::Malformed(_)),
            "case {k}: {out:?}"
        );
        assert_eq!(f, case, "case {k}: unchanged");
    }
    assert_eq!(escs[0].peek(0x0F80, 3), &[0, 0, 0], "nothing executed");
    // Another EtherType or EtherCAT type passes through unchanged.
    let mut ip = good.clone();
    ip[12] = 0x08;
    ip[13] = 0x00;
    let mut t4 = good.clone();
    t4[15] = (t4[15] & 0x0F) | 0x40;
    for case in [ip, t4] {
        let mut f = case.clone();
        let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
        assert_eq!(
            process_frame(&mut refs, &mut f, 0, HOP),
            FrameOutcome::PassedThrough
        );
        assert_eq!(f, case);
    }
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
}

#[test]
fn fuzz_random_frames_never_panic() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    for f in [Flavour::Lan9252, Flavour::Et1100] {
        let mut escs = chain(3, f);
        set_addresses(&mut escs);
        // Some live configuration so that SMs, FMMUs and the SII are in play.
        configure_sm(&mut escs, 0, 0, 0x1000, 128, 0x26);
        configure_sm(&mut escs, 0, 1, 0x1080, 128, 0x22);
        configure_sm(&mut escs, 0, 2, 0x1100, 8, 0x64);
        configure_sm(&mut escs, 0, 3, 0x1400, 8, 0x20);
        configure_fmmu(&mut escs, 0, 0, 0, 8, (0, 7), 0x1100, 0, 2);
        configure_fmmu(&mut escs, 0, 1, 8, 8, (3, 5), 0x1400, 1, 1);
        let mut t = 0;
        for round in 0..6000 {
            let mut fb = FrameBuilder::new();
            for _ in 0..1 + rng.below(4) {
                let cmd = rng.below(17) as u8;
                let addr = match rng.below(4) {
                    0 => rng.next() as u32,
                    1 => ((rng.below(0x3100) as u32) << 16) | (rng.below(4) as u32 * 0xFFFF),
                    2 => (0x1000 + rng.below(3) as u32) | ((rng.below(0x1000) as u32) << 16),
                    _ => rng.below(64) as u32,
                };
                let len = match rng.below(3) {
                    0 => rng.below(8),
                    1 => rng.below(200),
                    _ => rng.below(600),
                } as usize;
                let data: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
                fb = fb.raw(cmd, addr, &data);
            }
            let mut frame = fb.build();
            // Mutate some frames at random positions, or truncate them.
            match rng.below(4) {
                0 => {
                    for _ in 0..1 + rng.below(6) {
                        let p = rng.below(frame.len() as u64) as usize;
                        frame[p] = rng.next() as u8;
                    }
                }
                1 => {
                    let n = rng.below(frame.len() as u64) as usize;
                    frame.truncate(n);
                }
                _ => {}
            }
            let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
            let _ = process_frame(&mut refs, &mut frame, t, HOP);
            // PDI side garbage too.
            let e = &mut escs[round % 3];
            let a = rng.below(0x3400) as u16;
            let mut b = vec![0u8; rng.below(40) as usize];
            let _ = e.read(a, &mut b);
            let d: Vec<u8> = (0..rng.below(40)).map(|_| rng.next() as u8).collect();
            let _ = EscAccess::write(e, a, &d);
            t += rng.below(2_000_000);
            for e in escs.iter_mut() {
                e.advance_to(t);
            }
        }
        // Completely random bytes as frames.
        for _ in 0..3000 {
            let len = rng.below(1600) as usize;
            let mut frame: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
            if len > 16 && rng.below(2) == 0 {
                frame[12] = 0x88;
                frame[13] = 0xA4;
            }
            let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
            let _ = process_frame(&mut refs, &mut frame, t, HOP);
        }
    }
}

#[test]
fn pdi_watchdog_and_dl_status() {
    let mut escs = chain(2, Flavour::Et1100);
    let dl = |escs: &mut Vec<EscSim>, pos: u16| {
        let d = one(escs, Command::Aprd, pos, reg::DL_STATUS.addr(), &[0, 0]);
        u16::from_le_bytes([d.data[0], d.data[1]])
    };
    let first = dl(&mut escs, 0);
    let last = dl(&mut escs, 0xFFFF);
    assert_eq!(first & 0x0001, 1, "EEPROM loaded, PDI operational");
    assert_eq!(first & 0x0030, 0x0030, "links on ports 0 and 1");
    assert_eq!(last & 0x0030, 0x0010, "end of line: port 1 without link");
    assert_ne!(last & 0x0400, 0, "end of line: port 1 loop closed");
    // Default PDI watchdog: 100 ms without a PDI access expires it.
    escs[0].read_u8(0x0000).unwrap();
    escs[0].advance_to(99_000_000);
    assert_eq!(dl(&mut escs, 0) & 0x0002, 0x0002);
    escs[0].advance_to(100_000_001);
    assert_eq!(dl(&mut escs, 0) & 0x0002, 0);
    assert_eq!(escs[0].peek(reg::WATCHDOG_COUNTER_PDI.addr(), 1), &[1]);
    assert_eq!(escs[0].stats().pdi_watchdog_expiries, 1);
    escs[0].read_u8(0x0000).unwrap();
    assert_eq!(
        dl(&mut escs, 0) & 0x0002,
        0x0002,
        "a PDI access restarts it"
    );
}

#[test]
fn circulating_frames_are_marked_then_destroyed() {
    let mut escs = chain(3, Flavour::Lan9252);
    // Normal line: the bit stays clear.
    let mut f = FrameBuilder::new()
        .physical(Command::Brd, 0, 0, &[0])
        .build();
    let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
    process_frame(&mut refs, &mut f, 0, HOP);
    assert_eq!(datagrams(&f).unwrap()[0].wkc, 3);
    assert_eq!(f[16 + 7] & 0x40, 0);
    // Cable to the master broken at the second ESC: it marks the frame.
    escs[1].set_port0_loop_closed(true);
    assert_ne!(
        escs[1].peek(reg::DL_STATUS.addr() + 1, 1)[0] & 0x01,
        0,
        "port 0 loop closed in DL status"
    );
    let mut f = FrameBuilder::new()
        .physical(Command::Brd, 0, 0, &[0])
        .build();
    let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
    assert!(matches!(
        process_frame(&mut refs, &mut f, 0, HOP),
        FrameOutcome::Processed { .. }
    ));
    assert_eq!(f[16 + 7] & 0x40, 0x40, "circulating bit set");
    // The same frame coming round again is destroyed there.
    let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
    assert_eq!(
        process_frame(&mut refs, &mut f, 0, HOP),
        FrameOutcome::Destroyed { at: 1 }
    );
    escs[1].set_port0_loop_closed(false);
    assert_eq!(
        escs[1].peek(reg::DL_STATUS.addr(), 1)[0] & 0x10,
        0x10,
        "link back"
    );
}

#[test]
fn vlan_tagged_frames_are_processed() {
    let mut escs = chain(2, Flavour::Lan9252);
    let plain = FrameBuilder::new()
        .physical(Command::Brd, 0, 0, &[0; 2])
        .build();
    let mut f = plain[..12].to_vec();
    f.extend_from_slice(&[0x81, 0x00, 0x00, 0x05]);
    f.extend_from_slice(&plain[12..]);
    let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
    assert_eq!(
        process_frame(&mut refs, &mut f, 0, HOP),
        FrameOutcome::Processed { datagrams: 1 }
    );
    let d = datagrams(&f).unwrap();
    assert_eq!(d[0].wkc, 2);
    assert_eq!(d[0].data[0], Flavour::Lan9252.esc_type());
    // A tag with nothing behind it.
    let mut short = f[..15].to_vec();
    let mut refs: Vec<&mut EscSim> = escs.iter_mut().collect();
    assert!(matches!(
        process_frame(&mut refs, &mut short, 0, HOP),
        FrameOutcome::Malformed(_)
    ));
}

#[test]
fn sii_forced_back_to_the_master() {
    let mut escs = chain(1, Flavour::Et1100);
    one(&mut escs, Command::Apwr, 0, reg::SII_CONFIG.addr(), &[1]);
    escs[0].write_u8(reg::SII_PDI_ACCESS.addr(), 1).unwrap();
    let before = escs[0].stats().sii_commands;
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::SII_CONTROL.addr(),
        &[0x00, 0x01, 0, 0, 0, 0],
    );
    assert_eq!(escs[0].stats().sii_commands, before, "PDI holds the EEPROM");
    // Bit 1 forces master access: resets 0x0501 bit 0.
    one(&mut escs, Command::Apwr, 0, reg::SII_CONFIG.addr(), &[2]);
    assert_eq!(escs[0].peek(reg::SII_PDI_ACCESS.addr(), 1), &[0]);
    one(&mut escs, Command::Apwr, 0, reg::SII_CONFIG.addr(), &[0]);
    one(
        &mut escs,
        Command::Apwr,
        0,
        reg::SII_CONTROL.addr(),
        &[0x00, 0x01, 0, 0, 0, 0],
    );
    assert_eq!(escs[0].stats().sii_commands, before + 1);
}
