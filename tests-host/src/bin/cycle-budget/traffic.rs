//! The SPI traffic of one process-data cycle: one drive on the SPI chip model brought
//! to Op by raw datagrams, then cycles whose every SPI transaction is logged.

use super::*;
/// One simulated drive on `flavour` with its PDI through driver + SPI model.
pub(super) fn spi_segment(flavour: Flavour) -> Result<Segment<SimDrive>, String> {
    let desc =
        identity::device_description(Variant::HybridServo, sim_drive::esc_flavour(flavour), 0);
    let sii = sii_image(&desc).map_err(|e| format!("SII image: {e:?}"))?;
    let axis = tests_host::sim_axis::boxed_model(Motor::Ecn57_20, AxisModel::Kinematic, 1);
    let app = SimDrive::new(0x1000, FileFlash::in_memory(), axis);
    let mut seg = Segment::new(
        SegmentConfig::new(flavour).with_pdi(PdiPath::Spi),
        &sii,
        vec![app],
        sim_drive::slave_config(),
        None,
    )
    .map_err(|e| format!("ESC start-up: {e:?}"))?;
    sim_drive::power_up_drives(&mut seg);
    Ok(seg)
}

pub(super) fn fpwr(seg: &mut Segment<SimDrive>, ado: u16, data: &[u8]) -> u16 {
    let d = seg.raw(FrameBuilder::new().physical(Command::Fpwr, 0x1000, ado, data));
    d.first().map_or(0, |d| d.wkc)
}

pub(super) fn al_request(seg: &mut Segment<SimDrive>, state: u16) -> (u16, u16) {
    fpwr(seg, 0x0120, &state.to_le_bytes());
    sim_drive::advance(seg, 1_000);
    seg.al_status(0)
}

pub(super) fn sm(seg: &mut Segment<SimDrive>, n: u16, start: u16, len: u16, control: u8) {
    let mut b = [0u8; 8];
    b[0..2].copy_from_slice(&start.to_le_bytes());
    b[2..4].copy_from_slice(&len.to_le_bytes());
    b[4] = control;
    b[6] = 1;
    fpwr(seg, 0x0806 + 8 * n, &[0]);
    fpwr(seg, 0x0800 + 8 * n, &b);
}

/// Writes a map (sub 0 = 0, entries, sub 0 = n) through the runtime's objects.
pub(super) fn write_map(
    seg: &mut Segment<SimDrive>,
    index: u16,
    entries: &[u32],
) -> Result<(), String> {
    let d = seg.drive_mut(0);
    let mut rt = d.slave.runtime_objects(firmware::dictionary::OBJECTS);
    let e = |r: Result<(), od::SdoAbort>| r.map_err(|a| format!("{index:#06x}: {a:?}"));
    e(rt.write(ObjectKey::new(index, 0), &[0], EsmState::PreOp))?;
    for (k, v) in entries.iter().enumerate() {
        e(rt.write(
            ObjectKey::new(index, k as u8 + 1),
            &v.to_le_bytes(),
            EsmState::PreOp,
        ))?;
    }
    e(rt.write(
        ObjectKey::new(index, 0),
        &[entries.len() as u8],
        EsmState::PreOp,
    ))
}

pub(super) fn spi_log(pdi: &mut Pdi) -> Option<&mut Vec<Transaction>> {
    match pdi {
        Pdi::Lan9252(d) => Some(&mut d.spi_mut().log),
        Pdi::Et1100(d) => Some(&mut d.spi_mut().log),
        Pdi::Direct(_) => None,
    }
}

/// What one transaction does, from its MOSI header.
pub(super) fn describe(flavour: Flavour, t: &Transaction) -> String {
    let m = &t.mosi;
    match flavour {
        Flavour::Lan9252 => {
            if m.len() < 3 {
                return format!("{m:02x?}");
            }
            let addr = (u16::from(m[1]) << 8 | u16::from(m[2])) & 0x3FFF;
            let op = match m[0] {
                0x02 => "write",
                0x03 => "read",
                0x0B => "fast read",
                _ => "?",
            };
            let name = match addr {
                0x000..=0x01F => "PRAM read FIFO",
                0x020..=0x03F => "PRAM write FIFO",
                0x058 => "INT_STS",
                0x300 => "ECAT_CSR_DATA",
                0x304 => "ECAT_CSR_CMD",
                0x308 => "PRAM_RD_ADDR_LEN",
                0x30C => "PRAM_RD_CMD",
                0x310 => "PRAM_WR_ADDR_LEN",
                0x314 => "PRAM_WR_CMD",
                _ => "",
            };
            format!("{op} {addr:#05x} {name}")
        }
        Flavour::Et1100 => {
            if m.len() < 2 {
                return format!("{m:02x?}");
            }
            let mut addr = u16::from(m[0]) << 5 | u16::from(m[1]) >> 3;
            let mut cmd = m[1] & 7;
            if cmd == 0b110 && m.len() >= 3 {
                addr |= u16::from(m[2] >> 5) << 13;
                cmd = (m[2] >> 2) & 7;
            }
            let op = match cmd {
                0b000 => "NOP (AL event)",
                0b010 => "read",
                0b011 => "read (wait state)",
                0b100 => "write",
                _ => "?",
            };
            format!("{op} {addr:#06x}")
        }
    }
}

/// True for the transaction that writes the inputs (SM3 at 0x1400).
pub(super) fn writes_inputs(flavour: Flavour, t: &Transaction) -> bool {
    let d = describe(flavour, t);
    match flavour {
        Flavour::Lan9252 => d.contains("PRAM_WR_ADDR_LEN"),
        Flavour::Et1100 => d == "write 0x1400",
    }
}

/// SPI traffic of one process-data cycle.
pub(super) struct CycleTraffic {
    pub(super) transactions: Vec<Transaction>,
    pub(super) idle: Vec<Transaction>,
    pub(super) rx_bytes: usize,
    /// Polls from the SM2 write to the inputs written.
    pub(super) polls: u32,
}

impl CycleTraffic {
    pub(super) fn bytes(&self) -> usize {
        self.transactions.iter().map(|t| t.mosi.len()).sum()
    }
}

/// Brings the drive to Op with the given maps (None: defaults) and measures one
/// steady-state SM2 cycle.
pub(super) fn measure(chip: &Chip, maps: Option<(&[u32], &[u32])>) -> Result<CycleTraffic, String> {
    let mut seg = spi_segment(chip.flavour)?;
    let (rx_bytes, tx_bytes) = to_op(&mut seg, maps)?;
    let mut last = None;
    for k in 1..=5u32 {
        last = Some(one_cycle(&mut seg, chip, k, rx_bytes, tx_bytes)?);
        if seg.al_status(0) != (8, 0) {
            return Err(format!("left Op: {:?}", seg.al_status(0)));
        }
    }
    let (transactions, idle, polls) = last.ok_or("no cycle measured")?;
    // The cycle ran: the inputs were written.
    if !transactions.iter().any(|t| writes_inputs(chip.flavour, t)) {
        return Err(format!("inputs not written after {polls} polls"));
    }
    let violations = seg.drive_mut(0).slave.esc_mut().spi_violations();
    if !violations.is_empty() {
        return Err(format!("SPI protocol violations: {violations:?}"));
    }
    Ok(CycleTraffic {
        transactions,
        idle,
        rx_bytes,
        polls,
    })
}

/// The master's outputs of cycle `k`: controlword 0x000F and a moving target.
pub(super) fn outputs(rx_bytes: usize, k: u32) -> Vec<u8> {
    let mut o = vec![0u8; rx_bytes];
    o[0..2].copy_from_slice(&0x000Fu16.to_le_bytes());
    o[2..6].copy_from_slice(&(50 * k as i32).to_le_bytes());
    o
}

/// Station address, mailbox SMs, Pre-Op, the maps (`None`: the defaults), the process
/// data SMs, Safe-Op with the first outputs, Op. Returns the output and input bytes.
pub(super) fn to_op(
    seg: &mut Segment<SimDrive>,
    maps: Option<(&[u32], &[u32])>,
) -> Result<(usize, usize), String> {
    let d =
        seg.raw(FrameBuilder::new().physical(Command::Apwr, 0, 0x0010, &0x1000u16.to_le_bytes()));
    if d.first().map(|d| d.wkc) != Some(1) {
        return Err("station address not written".into());
    }
    sm(seg, 0, 0x1000, 128, 0x26);
    sm(seg, 1, 0x1080, 128, 0x22);
    if al_request(seg, 2) != (2, 0) {
        return Err(format!("Pre-Op refused: {:?}", seg.al_status(0)));
    }
    let (rx_bytes, tx_bytes) = match maps {
        None => (12usize, 19usize),
        Some((rx, tx)) => {
            write_map(seg, 0x1600, rx)?;
            write_map(seg, 0x1A00, tx)?;
            (32, 32)
        }
    };
    sm(seg, 2, 0x1100, rx_bytes as u16, 0x64);
    sm(seg, 3, 0x1400, tx_bytes as u16, 0x20);
    if al_request(seg, 4) != (4, 0) {
        return Err(format!("Safe-Op refused: {:?}", seg.al_status(0)));
    }
    fpwr(seg, 0x1100, &outputs(rx_bytes, 0));
    if al_request(seg, 8) != (8, 0) {
        return Err(format!("Op refused: {:?}", seg.al_status(0)));
    }
    Ok((rx_bytes, tx_bytes))
}

/// The SPI transactions of cycle `k`, of one idle poll after it, and the polls the
/// cycle needed.
pub(super) type OneCycle = (Vec<Transaction>, Vec<Transaction>, u32);

/// Cycle `k`: the next 1 ms boundary, the master's frame (outputs written, inputs
/// read), then polls as the board's ESC task runs them, each SPI transaction logged.
pub(super) fn one_cycle(
    seg: &mut Segment<SimDrive>,
    chip: &Chip,
    k: u32,
    rx_bytes: usize,
    tx_bytes: usize,
) -> Result<OneCycle, String> {
    let to_next = 1_000_000 - seg.now_ns() % 1_000_000;
    sim_drive::advance(seg, to_next);
    let mut frame = FrameBuilder::new()
        .physical(Command::Fpwr, 0x1000, 0x1100, &outputs(rx_bytes, k))
        .physical(Command::Fprd, 0x1000, 0x1400, &vec![0; tx_bytes])
        .build();
    let now_ns = seg.now_ns();
    let hop = seg.config().hop_ns;
    {
        let escs: Vec<_> = seg.drives_mut().iter().map(|d| d.esc.clone()).collect();
        let mut refs: Vec<_> = escs.iter().map(|e| e.borrow_mut()).collect();
        process_frame(&mut refs, &mut frame, now_ns, hop);
    }
    let wkc: Vec<u16> = datagrams(&frame)
        .unwrap_or_default()
        .iter()
        .map(|d| d.wkc)
        .collect();
    if wkc != [1, 1] {
        return Err(format!("cycle {k}: working counters {wkc:?}"));
    }
    // Polls until the inputs are written (the ET1100 driver may answer the first
    // poll with the AL event bytes of its previous access, see the notes).
    let d = seg.drive_mut(0);
    if let Some(l) = spi_log(d.slave.esc_mut()) {
        l.clear();
    }
    let mut cycle = Vec::new();
    let mut polls = 0;
    while polls < 4 && !cycle.iter().any(|t| writes_inputs(chip.flavour, t)) {
        d.slave
            .poll(&mut d.app, now_ns / 1000)
            .map_err(|e| format!("poll: {e:?}"))?;
        polls += 1;
        cycle.extend(
            spi_log(d.slave.esc_mut())
                .map(std::mem::take)
                .unwrap_or_default(),
        );
    }
    // A poll without any event (what the runtime does between cycles).
    d.slave
        .poll(&mut d.app, now_ns / 1000 + 1)
        .map_err(|e| format!("poll: {e:?}"))?;
    let idle = spi_log(d.slave.esc_mut())
        .map(std::mem::take)
        .unwrap_or_default();
    Ok((cycle, idle, polls))
}
