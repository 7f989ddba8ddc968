//! SyncManager register views and the checks of the ESM transitions.
//!
//! [`SmRegs`] is the 8-byte register block of one SyncManager (ETG.1000.4, registers 0x0800 + 8·n) as read
//! from `0x0800 + 8·n`. The validation functions are pure: the runtime reads the
//! registers and passes them in.
//!
//! * [`validate_mailbox`] (I→P): SM0 and SM1 lengths within the product's
//!   [`MailboxLimits`] (by default what the mailbox server can hold), even start addresses, inside process RAM, no overlap with each other or
//!   with an SM2/SM3 area the master has configured, mode/direction 0x26 / 0x22
//!   (mailbox mode, write resp. read, AL event interrupt), enabled → else 0x0016.
//! * [`validate_process_data`] (P→S): SM2/SM3 start inside process RAM with room for
//!   three buffers, length equal to the mapped size, buffered mode, right direction,
//!   SM2 with the AL event interrupt (control bit 5: the runtime is driven by the SM2
//!   event), enabled iff the size is non-zero, no overlap with the mailboxes or each other
//!   (a 3-buffer SM occupies 3 × length) → 0x001D (outputs) / 0x001E (inputs).
//! * [`validate_boot_mailbox`] (I→B): SM0/SM1 exactly at the start addresses and
//!   lengths of the product's [`BootMailbox`] (SII words 0x14–0x17), with the same
//!   mode/direction/enable/RAM/overlap rules as at I→P → else 0x0015.
//! * [`validate_watchdog`] (P→S): 0x0420 ≠ 0 exactly when SM2's watchdog trigger
//!   (control bit 6) is set, and an enabled watchdog at least twice the cycle time →
//!   else 0x001F.

use crate::al_status::AlStatusCode;
use crate::registers;

/// Buffer type of a SyncManager (control bits 1:0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmMode {
    /// Buffered (3-buffer) mode: process data.
    Buffered,
    /// Mailbox (1-buffer) mode.
    Mailbox,
    /// A reserved code (1 or 3).
    Reserved(u8),
}

/// Direction of a SyncManager (control bits 3:2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmDirection {
    /// ECAT reads, PDI writes (inputs, mailbox in).
    Read,
    /// ECAT writes, PDI reads (outputs, mailbox out).
    Write,
    /// A reserved code (2 or 3).
    Reserved(u8),
}

/// The control byte (0x0804 + 8·n): mode, direction, interrupts, watchdog.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Control(pub u8);

impl Control {
    const MODE_MASK: u8 = 0x03;
    const DIR_SHIFT: u8 = 2;
    const ECAT_EVENT_IRQ: u8 = 0x10;
    const AL_EVENT_IRQ: u8 = 0x20;
    const WATCHDOG: u8 = 0x40;

    /// A control byte with this mode and direction, no interrupts, no watchdog.
    pub const fn new(mode: SmMode, direction: SmDirection) -> Self {
        let m = match mode {
            SmMode::Buffered => 0,
            SmMode::Mailbox => 2,
            SmMode::Reserved(x) => x & Self::MODE_MASK,
        };
        let d = match direction {
            SmDirection::Read => 0,
            SmDirection::Write => 1,
            SmDirection::Reserved(x) => x & 3,
        };
        Control(m | d << Self::DIR_SHIFT)
    }
    /// The same byte with the AL event interrupt (bit 5) set or cleared.
    pub const fn with_al_event_irq(self, on: bool) -> Self {
        Control(set_bit(self.0, Self::AL_EVENT_IRQ, on))
    }
    /// The same byte with the watchdog trigger (bit 6) set or cleared.
    pub const fn with_watchdog(self, on: bool) -> Self {
        Control(set_bit(self.0, Self::WATCHDOG, on))
    }
    /// Buffer type, bits 1:0.
    pub const fn mode(self) -> SmMode {
        match self.0 & Self::MODE_MASK {
            0 => SmMode::Buffered,
            2 => SmMode::Mailbox,
            x => SmMode::Reserved(x),
        }
    }
    /// Direction, bits 3:2.
    pub const fn direction(self) -> SmDirection {
        match (self.0 >> Self::DIR_SHIFT) & 3 {
            0 => SmDirection::Read,
            1 => SmDirection::Write,
            x => SmDirection::Reserved(x),
        }
    }
    /// Interrupt into the ECAT event register (bit 4).
    pub const fn ecat_event_irq(self) -> bool {
        self.0 & Self::ECAT_EVENT_IRQ != 0
    }
    /// Interrupt into the AL event register (bit 5).
    pub const fn al_event_irq(self) -> bool {
        self.0 & Self::AL_EVENT_IRQ != 0
    }
    /// Watchdog trigger (bit 6).
    pub const fn watchdog(self) -> bool {
        self.0 & Self::WATCHDOG != 0
    }
}

/// The status byte (0x0805 + 8·n).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Status(pub u8);

impl Status {
    /// Interrupt write (bit 0): the master wrote a buffer.
    pub const fn interrupt_write(self) -> bool {
        self.0 & 0x01 != 0
    }
    /// Interrupt read (bit 1): the master read a buffer.
    pub const fn interrupt_read(self) -> bool {
        self.0 & 0x02 != 0
    }
    /// Mailbox full (bit 3, 1-buffer mode).
    pub const fn mailbox_full(self) -> bool {
        self.0 & 0x08 != 0
    }
    /// Buffer state (bits 5:4, 3-buffer mode): the last written buffer.
    pub const fn buffer_state(self) -> u8 {
        (self.0 >> 4) & 3
    }
}

/// The activate byte (0x0806 + 8·n), written by the master.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Activate(pub u8);

impl Activate {
    /// SM enabled (bit 0).
    pub const fn enabled(self) -> bool {
        self.0 & 0x01 != 0
    }
    /// Repeat request (bit 1), toggled by the master.
    pub const fn repeat_request(self) -> bool {
        self.0 & 0x02 != 0
    }
}

/// The PDI control byte (0x0807 + 8·n), written by this side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PdiControl(pub u8);

impl PdiControl {
    /// A PDI control byte: deactivate the SM (bit 0), repeat acknowledge (bit 1).
    pub const fn new(deactivate: bool, repeat_ack: bool) -> Self {
        PdiControl(set_bit(0, 0x01, deactivate) | set_bit(0, 0x02, repeat_ack))
    }
    /// Deactivate bit.
    pub const fn deactivate(self) -> bool {
        self.0 & 0x01 != 0
    }
    /// Repeat acknowledge bit.
    pub const fn repeat_ack(self) -> bool {
        self.0 & 0x02 != 0
    }
}

const fn set_bit(byte: u8, bit: u8, on: bool) -> u8 {
    if on {
        byte | bit
    } else {
        byte & !bit
    }
}

/// One SyncManager register block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SmRegs {
    /// Physical start address.
    pub start: u16,
    /// Length in bytes.
    pub len: u16,
    /// Control byte.
    pub control: Control,
    /// Status byte.
    pub status: Status,
    /// Activate byte.
    pub activate: Activate,
    /// PDI control byte.
    pub pdi_control: PdiControl,
}

impl SmRegs {
    /// Decodes the 8 register bytes.
    pub const fn from_bytes(b: &[u8; 8]) -> Self {
        SmRegs {
            start: u16::from_le_bytes([b[0], b[1]]),
            len: u16::from_le_bytes([b[2], b[3]]),
            control: Control(b[4]),
            status: Status(b[5]),
            activate: Activate(b[6]),
            pdi_control: PdiControl(b[7]),
        }
    }
    /// Encodes the 8 register bytes.
    pub const fn to_bytes(&self) -> [u8; 8] {
        let s = self.start.to_le_bytes();
        let l = self.len.to_le_bytes();
        [
            s[0],
            s[1],
            l[0],
            l[1],
            self.control.0,
            self.status.0,
            self.activate.0,
            self.pdi_control.0,
        ]
    }
    /// Decodes SM `n` from a block of consecutive SM registers starting at SM0.
    pub fn from_block(block: &[u8], n: usize) -> Self {
        let mut b = [0u8; 8];
        if let Some(src) = block.get(n * 8..n * 8 + 8) {
            b.copy_from_slice(src);
        }
        Self::from_bytes(&b)
    }
    /// Activate bit 0.
    pub const fn enabled(&self) -> bool {
        self.activate.enabled()
    }
    /// Buffer type.
    pub const fn mode(&self) -> SmMode {
        self.control.mode()
    }
    /// Direction.
    pub const fn direction(&self) -> SmDirection {
        self.control.direction()
    }
    /// Repeat request bit of the activate byte.
    pub const fn repeat_request(&self) -> bool {
        self.activate.repeat_request()
    }
    /// Bytes of RAM this SM occupies: 3 × length in buffered mode.
    pub const fn footprint(&self) -> u32 {
        if matches!(self.mode(), SmMode::Buffered) {
            3 * self.len as u32
        } else {
            self.len as u32
        }
    }
    /// The occupied RAM range `[start, end)`.
    pub const fn range(&self) -> (u32, u32) {
        (self.start as u32, self.start as u32 + self.footprint())
    }
    /// Address of the last byte of the (first) buffer.
    pub const fn last_byte(&self) -> u16 {
        self.start.wrapping_add(self.len.saturating_sub(1))
    }
}

/// Limits of the mailbox configuration accepted at I→P.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxLimits {
    /// SM0 (mailbox out) length range.
    pub sm0_len: (u16, u16),
    /// SM1 (mailbox in) length range.
    pub sm1_len: (u16, u16),
}

impl MailboxLimits {
    /// Every length the mailbox server can hold:
    /// [`crate::mailbox::MIN_MAILBOX_SIZE`]…[`crate::mailbox::MAX_MAILBOX_SIZE`] bytes
    /// for both mailboxes. A product narrows it in its
    /// [`crate::slave::SlaveConfig`].
    pub const ANY: MailboxLimits = MailboxLimits {
        sm0_len: (
            crate::mailbox::MIN_MAILBOX_SIZE as u16,
            crate::mailbox::MAX_MAILBOX_SIZE as u16,
        ),
        sm1_len: (
            crate::mailbox::MIN_MAILBOX_SIZE as u16,
            crate::mailbox::MAX_MAILBOX_SIZE as u16,
        ),
    };
}

impl Default for MailboxLimits {
    fn default() -> Self {
        Self::ANY
    }
}

/// The bootstrap mailbox of a product (SII words 0x14–0x17, ESI `<BootStrap>`): the
/// SM0/SM1 layout a master must configure before requesting Bootstrap. Lengths of
/// [`crate::mailbox::MIN_MAILBOX_SIZE`]…[`crate::mailbox::MAX_MAILBOX_SIZE`] bytes
/// (others are never accepted: every Init→Boot answers 0x0015).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BootMailbox {
    /// Receive mailbox (SM0, master → slave) start address.
    pub rx_start: u16,
    /// Receive mailbox length, bytes.
    pub rx_len: u16,
    /// Send mailbox (SM1, slave → master) start address.
    pub tx_start: u16,
    /// Send mailbox length, bytes.
    pub tx_len: u16,
}

impl BootMailbox {
    /// The usual layout, the same as the standard mailbox: SM0 at 0x1000, SM1 at
    /// 0x1080, 128 bytes each (SOES `MBXSIZEBOOT`).
    pub const STANDARD: BootMailbox = BootMailbox {
        rx_start: 0x1000,
        rx_len: 128,
        tx_start: 0x1080,
        tx_len: 128,
    };

    /// SII words 0x14–0x17: receive offset, receive size, send offset, send size.
    pub const fn sii_words(&self) -> [u16; 4] {
        [self.rx_start, self.rx_len, self.tx_start, self.tx_len]
    }

    /// The ESI `<Eeprom><BootStrap>` value: the four SII words as 8 bytes in
    /// little-endian order, written as 16 upper-case hex digits (e.g.
    /// `0010800080108000` for [`Self::STANDARD`]).
    pub fn esi_hex(&self) -> [u8; 16] {
        const HEX: &[u8; 16] = b"0123456789ABCDEF";
        let mut out = [b'0'; 16];
        for (i, w) in self.sii_words().iter().enumerate() {
            for (j, b) in w.to_le_bytes().iter().enumerate() {
                let k = 4 * i + 2 * j;
                out[k] = HEX[(b >> 4) as usize];
                out[k + 1] = HEX[(b & 0x0F) as usize];
            }
        }
        out
    }
}

/// The process RAM window `[0x1000, 0x1000 + size)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RamWindow {
    /// First address.
    pub start: u32,
    /// One past the last address.
    pub end: u32,
}

impl RamWindow {
    /// Process RAM of `kib` KiB (register 0x0006), at least 1 KiB assumed.
    pub const fn from_kib(kib: u8) -> Self {
        let size = if kib == 0 { 1024 } else { kib as u32 * 1024 };
        RamWindow {
            start: registers::PROCESS_RAM as u32,
            end: registers::PROCESS_RAM as u32 + size,
        }
    }
    /// True when `[a, b)` lies inside the window.
    pub const fn contains(&self, a: u32, b: u32) -> bool {
        a >= self.start && b <= self.end && a <= b
    }
}

const fn overlap(a: (u32, u32), b: (u32, u32)) -> bool {
    a.0 < b.1 && b.0 < a.1
}

fn check_mailbox_sm(
    sm: &SmRegs,
    len: (u16, u16),
    dir: SmDirection,
    ram: RamWindow,
) -> Result<(), AlStatusCode> {
    let bad = Err(AlStatusCode::InvalidMailboxConfig);
    if !sm.enabled() || sm.len < len.0 || sm.len > len.1 || !sm.start.is_multiple_of(2) {
        return bad;
    }
    if sm.mode() != SmMode::Mailbox || sm.direction() != dir || !sm.control.al_event_irq() {
        return bad;
    }
    let (a, b) = sm.range();
    if !ram.contains(a, b) {
        return bad;
    }
    Ok(())
}

/// The I→P check of SM0/SM1 (see the module docs). `pd` are SM2 and SM3 as the
/// master left them; a process-data SM with length 0 occupies nothing.
pub fn validate_mailbox(
    sm0: &SmRegs,
    sm1: &SmRegs,
    pd: &[SmRegs],
    limits: &MailboxLimits,
    ram: RamWindow,
) -> Result<(), AlStatusCode> {
    check_mailbox_sm(sm0, limits.sm0_len, SmDirection::Write, ram)?;
    check_mailbox_sm(sm1, limits.sm1_len, SmDirection::Read, ram)?;
    if overlap(sm0.range(), sm1.range()) {
        return Err(AlStatusCode::InvalidMailboxConfig);
    }
    for p in pd.iter().filter(|p| p.len > 0) {
        if overlap(sm0.range(), p.range()) || overlap(sm1.range(), p.range()) {
            return Err(AlStatusCode::InvalidMailboxConfig);
        }
    }
    Ok(())
}

/// The I→B check of SM0/SM1 against the product's bootstrap mailbox: exact start
/// addresses and lengths, plus the rules of [`validate_mailbox`] (SM2/SM3 are not
/// looked at: there is no process data in Bootstrap) → else 0x0015.
pub fn validate_boot_mailbox(
    sm0: &SmRegs,
    sm1: &SmRegs,
    boot: &BootMailbox,
    ram: RamWindow,
) -> Result<(), AlStatusCode> {
    let bad = Err(AlStatusCode::InvalidMailboxBoot);
    let sizes = crate::mailbox::MIN_MAILBOX_SIZE..=crate::mailbox::MAX_MAILBOX_SIZE;
    if sm0.start != boot.rx_start
        || sm0.len != boot.rx_len
        || sm1.start != boot.tx_start
        || sm1.len != boot.tx_len
        || !sizes.contains(&(boot.rx_len as usize))
        || !sizes.contains(&(boot.tx_len as usize))
    {
        return bad;
    }
    let limits = MailboxLimits {
        sm0_len: (boot.rx_len, boot.rx_len),
        sm1_len: (boot.tx_len, boot.tx_len),
    };
    validate_mailbox(sm0, sm1, &[], &limits, ram).or(bad)
}

/// Which process-data SyncManager is checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdDirection {
    /// SM2, outputs of the master (RxPDO), ECAT writes.
    Outputs,
    /// SM3, inputs of the master (TxPDO), ECAT reads.
    Inputs,
}

impl PdDirection {
    /// 0x001D for outputs, 0x001E for inputs.
    pub const fn error(self) -> AlStatusCode {
        match self {
            Self::Outputs => AlStatusCode::InvalidOutputConfig,
            Self::Inputs => AlStatusCode::InvalidInputConfig,
        }
    }
    const fn sm_direction(self) -> SmDirection {
        match self {
            Self::Outputs => SmDirection::Write,
            Self::Inputs => SmDirection::Read,
        }
    }
}

/// The P→S check of SM2 (outputs) or SM3 (inputs) against the mapped size in bytes.
/// `others` are the SyncManagers it must not overlap (the mailboxes and the other
/// process-data SM).
pub fn validate_process_data(
    sm: &SmRegs,
    dir: PdDirection,
    mapped_bytes: u16,
    others: &[SmRegs],
    ram: RamWindow,
) -> Result<(), AlStatusCode> {
    let bad = Err(dir.error());
    if mapped_bytes == 0 {
        // Nothing mapped: the SM must not carry data.
        return if sm.enabled() && sm.len > 0 {
            bad
        } else {
            Ok(())
        };
    }
    if !sm.enabled() || sm.len != mapped_bytes {
        return bad;
    }
    if sm.mode() != SmMode::Buffered || sm.direction() != dir.sm_direction() {
        return bad;
    }
    // The runtime learns about new outputs from the SM2 AL event only.
    if dir == PdDirection::Outputs && !sm.control.al_event_irq() {
        return bad;
    }
    let (a, b) = sm.range();
    if !ram.contains(a, b) {
        return bad;
    }
    for o in others.iter().filter(|o| o.len > 0) {
        if overlap((a, b), o.range()) {
            return bad;
        }
    }
    Ok(())
}

/// Process-data watchdog time in ns from the divider (0x0400) and the time (0x0420).
pub const fn watchdog_ns(divider: u16, time: u16) -> u64 {
    (divider as u64 + 2) * 40 * time as u64
}

/// The P→S watchdog check: with outputs, 0x0420 ≠ 0 exactly when SM2 control bit 6
/// is set; an enabled watchdog must be at least 2 × `cycle_ns` (0 = cycle unknown,
/// not checked) → else 0x001F.
pub fn validate_watchdog(
    sm2: &SmRegs,
    outputs: bool,
    divider: u16,
    time: u16,
    cycle_ns: u32,
) -> Result<(), AlStatusCode> {
    if !outputs {
        return Ok(());
    }
    let trigger = sm2.control.watchdog();
    if (time != 0) != trigger {
        return Err(AlStatusCode::InvalidWatchdogConfig);
    }
    if time != 0 && cycle_ns != 0 && watchdog_ns(divider, time) < 2 * cycle_ns as u64 {
        return Err(AlStatusCode::InvalidWatchdogConfig);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sm(start: u16, len: u16, control: u8) -> SmRegs {
        SmRegs {
            start,
            len,
            control: Control(control),
            status: Status(0),
            activate: Activate(1),
            pdi_control: PdiControl(0),
        }
    }
    const RAM: RamWindow = RamWindow::from_kib(4);

    #[test]
    fn standard_layout_is_accepted() {
        let sm0 = sm(0x1000, 128, 0x26);
        let sm1 = sm(0x1080, 128, 0x22);
        let sm2 = sm(0x1100, 12, 0x64);
        let sm3 = sm(0x1400, 19, 0x20);
        assert_eq!(
            validate_mailbox(&sm0, &sm1, &[sm2, sm3], &MailboxLimits::ANY, RAM),
            Ok(())
        );
        assert_eq!(
            validate_process_data(&sm2, PdDirection::Outputs, 12, &[sm0, sm1, sm3], RAM),
            Ok(())
        );
        assert_eq!(
            validate_process_data(&sm3, PdDirection::Inputs, 19, &[sm0, sm1, sm2], RAM),
            Ok(())
        );
        assert_eq!(validate_watchdog(&sm2, true, 2498, 1000, 1_000_000), Ok(()));
    }

    #[test]
    fn boot_mailbox_check() {
        let b = BootMailbox::STANDARD;
        assert_eq!(b.sii_words(), [0x1000, 128, 0x1080, 128]);
        assert_eq!(&b.esi_hex(), b"0010800080108000");
        let sm0 = sm(0x1000, 128, 0x26);
        let sm1 = sm(0x1080, 128, 0x22);
        assert_eq!(validate_boot_mailbox(&sm0, &sm1, &b, RAM), Ok(()));
        let bad = Err(AlStatusCode::InvalidMailboxBoot);
        for (s0, s1) in [
            (sm(0x1000, 64, 0x26), sm1),
            (sm(0x1002, 128, 0x26), sm1),
            (sm0, sm(0x1080, 128, 0x26)),
            (
                sm0,
                SmRegs {
                    activate: Activate(0),
                    ..sm1
                },
            ),
            (sm(0x1000, 128, 0x24), sm1),
        ] {
            assert_eq!(validate_boot_mailbox(&s0, &s1, &b, RAM), bad);
        }
        // A configuration with overlapping or oversized mailboxes never passes.
        let overlap = BootMailbox {
            tx_start: 0x1040,
            ..b
        };
        let s1 = sm(0x1040, 128, 0x22);
        assert_eq!(validate_boot_mailbox(&sm0, &s1, &overlap, RAM), bad);
        let big = BootMailbox {
            rx_len: 512,
            tx_start: 0x1200,
            ..b
        };
        let (s0, s1) = (sm(0x1000, 512, 0x26), sm(0x1200, 128, 0x22));
        assert_eq!(validate_boot_mailbox(&s0, &s1, &big, RAM), bad);
    }

    #[test]
    fn control_status_activate_views() {
        let mbx_out = Control(0x26);
        assert_eq!(mbx_out.mode(), SmMode::Mailbox);
        assert_eq!(mbx_out.direction(), SmDirection::Write);
        assert!(mbx_out.al_event_irq() && !mbx_out.watchdog() && !mbx_out.ecat_event_irq());
        let outputs = Control(0x64);
        assert_eq!(outputs.mode(), SmMode::Buffered);
        assert!(outputs.watchdog() && outputs.al_event_irq());
        assert_eq!(Control(0x01).mode(), SmMode::Reserved(1));
        assert_eq!(Control(0x08).direction(), SmDirection::Reserved(2));
        assert!(Control(0x10).ecat_event_irq());
        assert_eq!(
            Control::new(SmMode::Mailbox, SmDirection::Write).with_al_event_irq(true),
            mbx_out
        );
        assert_eq!(
            Control::new(SmMode::Buffered, SmDirection::Write)
                .with_al_event_irq(true)
                .with_watchdog(true),
            outputs
        );
        assert_eq!(
            Control::new(SmMode::Mailbox, SmDirection::Read).with_al_event_irq(true),
            Control(0x22)
        );
        assert_eq!(Control(0x64).with_watchdog(false), Control(0x24));
        let st = Status(0x2B);
        assert!(st.interrupt_write() && st.interrupt_read() && st.mailbox_full());
        assert_eq!(st.buffer_state(), 2);
        assert!(!Status(0x04).mailbox_full());
        assert!(Activate(3).enabled() && Activate(3).repeat_request());
        assert!(!Activate(2).enabled());
        assert_eq!(PdiControl::new(true, false), PdiControl(1));
        assert_eq!(PdiControl::new(false, true), PdiControl(2));
        assert!(PdiControl(3).deactivate() && PdiControl(3).repeat_ack());
    }

    #[test]
    fn register_bytes_round_trip() {
        let r = SmRegs {
            start: 0x1234,
            len: 0x0056,
            control: Control(0x64),
            status: Status(0x08),
            activate: Activate(3),
            pdi_control: PdiControl(2),
        };
        assert_eq!(SmRegs::from_bytes(&r.to_bytes()), r);
        assert_eq!(SmRegs::from_block(&[0u8; 3], 1), SmRegs::default());
    }
}
