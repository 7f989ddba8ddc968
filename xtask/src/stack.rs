//! Static worst-case stack usage of the board firmware (printed by `cargo xtask size`).
//!
//! Reads the firmware ELF itself (std only, no external tool):
//!
//! 1. a minimal ELF32 little-endian reader: section headers, `.symtab`/`.strtab`, bytes
//!    at a load address;
//! 2. every function (`STT_FUNC`, size > 0) is walked instruction by instruction
//!    (Thumb-2, 16/32-bit length decoding; the `$t`/`$d` mapping symbols mark literal
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

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

// ---------------------------------------------------------------------------------------
// What the analysis must know about the firmware (keep in step with the sources)
// ---------------------------------------------------------------------------------------

/// NVIC priorities the firmware programs (0 = most urgent). Mirrors:
/// * `firmware/src/hw/adc.rs`: `interrupt::ADC1_2.set_priority(Priority::P0)`;
/// * `firmware/src/hw/pwm.rs`: `TIM1_BRK_TIM15` and `TIM8_BRK` `.set_priority(Priority::P1)`;
/// * `firmware/src/main.rs` `clock_config`: `c.bdma_interrupt_priority = Priority::P1` (every
///   DMA channel interrupt embassy binds: `DMA1_CHANNEL1`, `DMA1_CHANNEL2` in `bind_interrupts!`);
/// * `firmware/src/main.rs`: `EXTI1/2/3` and `UART4` (the cyclic interrupt executor) at
///   `CYCLIC_PRIORITY` (= `Priority::P2`, `firmware/src/hw/lock.rs`), `TIM5` (the embassy
///   time driver) `.set_priority(Priority::P3)`.
///
/// A name ending in `*` is a prefix. Every other handler in the vector table keeps the
/// reset priority 0 (NVIC IPR / SHPR reset value); NMI (-2) and HardFault (-1) are fixed.
pub const IRQ_PRIORITIES: &[(&str, i32)] = &[
    ("ADC1_2", 0),
    ("TIM1_BRK_TIM15", 1),
    ("TIM8_BRK", 1),
    ("DMA1_CHANNEL*", 1),
    ("DMA2_CHANNEL*", 1),
    ("UART4", 2),
    ("EXTI1", 2),
    ("EXTI2", 2),
    ("EXTI3", 2),
    ("TIM5", 3),
];

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
// ELF32 reader
// ---------------------------------------------------------------------------------------

const SHT_SYMTAB: u32 = 2;
const SHT_NOBITS: u32 = 8;
const STT_OBJECT: u8 = 1;
const STT_FUNC: u8 = 2;

fn u16_at(b: &[u8], o: usize) -> Result<u16, String> {
    b.get(o..o + 2)
        .map(|s| u16::from_le_bytes([s[0], s[1]]))
        .ok_or_else(|| format!("ELF truncated at {o:#x}"))
}

fn u32_at(b: &[u8], o: usize) -> Result<u32, String> {
    b.get(o..o + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
        .ok_or_else(|| format!("ELF truncated at {o:#x}"))
}

fn cstr(b: &[u8], o: usize) -> String {
    let s = b.get(o..).unwrap_or(&[]);
    let end = s.iter().position(|&c| c == 0).unwrap_or(s.len());
    String::from_utf8_lossy(&s[..end]).into_owned()
}

#[derive(Debug, Clone)]
pub struct Section {
    pub name: String,
    pub kind: u32,
    pub addr: u32,
    pub offset: u32,
    pub size: u32,
    pub link: u32,
}

#[derive(Debug, Clone)]
pub struct Symbol {
    pub name: String,
    pub value: u32,
    pub size: u32,
    pub kind: u8,
}

pub struct Elf {
    bytes: Vec<u8>,
    pub sections: Vec<Section>,
}

impl Elf {
    pub fn parse(bytes: Vec<u8>) -> Result<Self, String> {
        if bytes.len() < 52 || bytes[..4] != *b"\x7fELF" {
            return Err("not an ELF file".into());
        }
        if bytes[4] != 1 || bytes[5] != 1 {
            return Err("not a little-endian ELF32 file".into());
        }
        let shoff = u32_at(&bytes, 0x20)? as usize;
        let shentsize = u16_at(&bytes, 0x2E)? as usize;
        let shnum = u16_at(&bytes, 0x30)? as usize;
        let shstrndx = u16_at(&bytes, 0x32)? as usize;
        if shentsize < 40 {
            return Err("bad section header size".into());
        }
        let mut raw = Vec::with_capacity(shnum);
        for i in 0..shnum {
            let h = shoff + i * shentsize;
            raw.push((
                u32_at(&bytes, h)?,
                Section {
                    name: String::new(),
                    kind: u32_at(&bytes, h + 4)?,
                    addr: u32_at(&bytes, h + 12)?,
                    offset: u32_at(&bytes, h + 16)?,
                    size: u32_at(&bytes, h + 20)?,
                    link: u32_at(&bytes, h + 24)?,
                },
            ));
        }
        let strtab = raw
            .get(shstrndx)
            .map(|(_, s)| s.clone())
            .ok_or("no section name table")?;
        let names = bytes
            .get(
                strtab.offset as usize
                    ..(strtab.offset as usize).saturating_add(strtab.size as usize),
            )
            .ok_or("section name table outside the file")?
            .to_vec();
        let sections = raw
            .into_iter()
            .map(|(n, mut s)| {
                s.name = cstr(&names, n as usize);
                s
            })
            .collect();
        Ok(Elf { bytes, sections })
    }

    pub fn section(&self, name: &str) -> Option<&Section> {
        self.sections.iter().find(|s| s.name == name)
    }

    pub fn data(&self, s: &Section) -> Result<&[u8], String> {
        if s.kind == SHT_NOBITS {
            return Ok(&[]);
        }
        let start = s.offset as usize;
        self.bytes
            .get(start..start.saturating_add(s.size as usize))
            .ok_or_else(|| format!("section {} outside the file", s.name))
    }

    pub fn symbols(&self) -> Result<Vec<Symbol>, String> {
        let symtab = self
            .sections
            .iter()
            .find(|s| s.kind == SHT_SYMTAB)
            .ok_or("no .symtab (stripped ELF?)")?;
        let strtab = self
            .sections
            .get(symtab.link as usize)
            .ok_or("no string table for .symtab")?;
        let (syms, strs) = (self.data(symtab)?, self.data(strtab)?);
        let mut out = Vec::with_capacity(syms.len() / 16);
        for e in syms.chunks_exact(16) {
            out.push(Symbol {
                name: cstr(strs, u32_at(e, 0)? as usize),
                value: u32_at(e, 4)?,
                size: u32_at(e, 8)?,
                kind: e[12] & 0xF,
            });
        }
        Ok(out)
    }

    /// `len` bytes at load address `addr` of an allocated section with contents.
    pub fn at(&self, addr: u32, len: u32) -> Option<&[u8]> {
        let s = self.sections.iter().find(|s| {
            s.addr != 0
                && s.kind != SHT_NOBITS
                && addr >= s.addr
                && u64::from(addr) + u64::from(len) <= u64::from(s.addr) + u64::from(s.size)
        })?;
        let o = s.offset as usize + (addr - s.addr) as usize;
        self.bytes.get(o..o + len as usize)
    }
}

// ---------------------------------------------------------------------------------------
// Thumb-2 decoding (only what the analysis needs)
// ---------------------------------------------------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Insn {
    /// SP moves down by this many bytes.
    SpDown(u32),
    /// SP moved by a register amount (`SUB SP, SP, Rm`): not bounded statically.
    SpByRegister,
    /// BL to this address.
    Call(u32),
    /// B / B.W / B<c> / CBZ / CBNZ to this address (a tail call when it leaves the function).
    Branch(u32),
    /// BLX Rm.
    IndirectCall,
    /// BX Rm (not LR), MOV PC, Rm, LDR PC from a register other than SP.
    IndirectJump,
    /// MOVW Rd, #imm16.
    Movw(u8, u16),
    /// MOVT Rd, #imm16.
    Movt(u8, u16),
    /// LDR Rt, [PC, #imm] — the literal's address.
    LdrLiteral(u8, u32),
    Other,
}

/// A first halfword whose top five bits are 0b11101, 0b11110 or 0b11111 starts a
/// 32-bit instruction.
pub fn is_32bit(hw1: u16) -> bool {
    matches!(hw1 >> 11, 0b11101..=0b11111)
}

fn sext(v: u32, bits: u32) -> i32 {
    let shift = 32 - bits;
    ((v << shift) as i32) >> shift
}

fn rel(pc: u32, off: i32) -> u32 {
    pc.wrapping_add(4).wrapping_add(off as u32)
}

/// ThumbExpandImm of a 12-bit modified immediate (ARMv7-M ARM A5.3.2).
pub fn thumb_expand_imm(imm12: u32) -> u32 {
    let imm8 = imm12 & 0xFF;
    if imm12 >> 10 == 0 {
        match (imm12 >> 8) & 3 {
            0 => imm8,
            1 => (imm8 << 16) | imm8,
            2 => (imm8 << 24) | (imm8 << 8),
            _ => imm8 * 0x0101_0101,
        }
    } else {
        (0x80 | (imm12 & 0x7F)).rotate_right((imm12 >> 7) & 0x1F)
    }
}

/// A 16-bit instruction at `pc`.
pub fn decode16(hw: u16, pc: u32) -> Insn {
    let h = u32::from(hw);
    if hw & 0xFE00 == 0xB400 {
        // PUSH {reglist} (+ LR with the M bit)
        return Insn::SpDown(4 * ((h & 0xFF).count_ones() + ((h >> 8) & 1)));
    }
    if hw & 0xFF80 == 0xB080 {
        // SUB SP, SP, #imm7*4
        return Insn::SpDown((h & 0x7F) * 4);
    }
    if hw & 0xFF87 == 0x4780 {
        return Insn::IndirectCall; // BLX Rm
    }
    if hw & 0xFF87 == 0x4700 {
        // BX Rm: BX LR is a return
        return if (h >> 3) & 0xF == 14 {
            Insn::Other
        } else {
            Insn::IndirectJump
        };
    }
    if hw & 0xFF87 == 0x4687 {
        return Insn::IndirectJump; // MOV PC, Rm
    }
    if hw & 0xF800 == 0xE000 {
        return Insn::Branch(rel(pc, sext((h & 0x7FF) << 1, 12)));
    }
    if hw & 0xF000 == 0xD000 && (h >> 8) & 0xF < 0xE {
        return Insn::Branch(rel(pc, sext((h & 0xFF) << 1, 9)));
    }
    if hw & 0xF500 == 0xB100 {
        // CBZ / CBNZ: forward only
        let off = (((h >> 9) & 1) << 6) | (((h >> 3) & 0x1F) << 1);
        return Insn::Branch(rel(pc, off as i32));
    }
    if hw & 0xF800 == 0x4800 {
        let base = (pc.wrapping_add(4)) & !3;
        return Insn::LdrLiteral(((h >> 8) & 7) as u8, base.wrapping_add((h & 0xFF) * 4));
    }
    Insn::Other
}

/// A 32-bit instruction (halfwords `hw1`, `hw2`) at `pc`.
pub fn decode32(hw1: u16, hw2: u16, pc: u32) -> Insn {
    let (a, b) = (u32::from(hw1), u32::from(hw2));
    let rd_is_sp = b & 0x8F00 == 0x0D00;
    if hw1 == 0xE92D {
        // STMDB SP!, {reglist} (PUSH.W)
        return Insn::SpDown(4 * (b & 0x5FFF).count_ones());
    }
    if hw1 == 0xF84D && b & 0x0F00 == 0x0D00 {
        // STR.W Rt, [SP, #-imm8]!
        return Insn::SpDown(b & 0xFF);
    }
    if hw1 == 0xE96D {
        // STRD Rt, Rt2, [SP, #-imm8*4]!
        return Insn::SpDown((b & 0xFF) * 4);
    }
    if hw1 & 0xFFBF == 0xED2D && b & 0x0E00 == 0x0A00 {
        // VPUSH (double 0x0B00 / single 0x0A00 form): imm8 words
        return Insn::SpDown((b & 0xFF) * 4);
    }
    let imm12 = ((a >> 10) & 1) << 11 | ((b >> 12) & 7) << 8 | (b & 0xFF);
    if hw1 & 0xFBEF == 0xF1AD && rd_is_sp {
        // SUB.W SP, SP, #ThumbExpandImm
        return Insn::SpDown(thumb_expand_imm(imm12));
    }
    if hw1 & 0xFBFF == 0xF2AD && rd_is_sp {
        // SUBW SP, SP, #imm12
        return Insn::SpDown(imm12);
    }
    if hw1 & 0xFFEF == 0xEBAD && rd_is_sp {
        return Insn::SpByRegister; // SUB.W SP, SP, Rm
    }
    if hw1 & 0xF800 == 0xF000 && b & 0x8000 != 0 {
        let s = (a >> 10) & 1;
        let (j1, j2) = ((b >> 13) & 1, (b >> 11) & 1);
        match b & 0xD000 {
            0xD000 | 0x9000 => {
                let (i1, i2) = (!(j1 ^ s) & 1, !(j2 ^ s) & 1);
                let off =
                    (s << 24) | (i1 << 23) | (i2 << 22) | ((a & 0x3FF) << 12) | ((b & 0x7FF) << 1);
                let target = rel(pc, sext(off, 25));
                return if b & 0xD000 == 0xD000 {
                    Insn::Call(target)
                } else {
                    Insn::Branch(target)
                };
            }
            0x8000 if (a >> 6) & 0xF < 0xE => {
                let off =
                    (s << 20) | (j2 << 19) | (j1 << 18) | ((a & 0x3F) << 12) | ((b & 0x7FF) << 1);
                return Insn::Branch(rel(pc, sext(off, 21)));
            }
            _ => return Insn::Other,
        }
    }
    if hw1 & 0xFBF0 == 0xF240 && b & 0x8000 == 0 {
        let imm16 = ((a & 0xF) << 12) | ((a >> 10) & 1) << 11 | ((b >> 12) & 7) << 8 | (b & 0xFF);
        return Insn::Movw(((b >> 8) & 0xF) as u8, imm16 as u16);
    }
    if hw1 & 0xFBF0 == 0xF2C0 && b & 0x8000 == 0 {
        let imm16 = ((a & 0xF) << 12) | ((a >> 10) & 1) << 11 | ((b >> 12) & 7) << 8 | (b & 0xFF);
        return Insn::Movt(((b >> 8) & 0xF) as u8, imm16 as u16);
    }
    if hw1 & 0xFF7F == 0xF85F {
        // LDR.W Rt, [PC, #±imm12]
        let base = (pc.wrapping_add(4)) & !3;
        let addr = if a & 0x80 != 0 {
            base.wrapping_add(b & 0xFFF)
        } else {
            base.wrapping_sub(b & 0xFFF)
        };
        return if b >> 12 == 15 {
            Insn::IndirectJump
        } else {
            Insn::LdrLiteral((b >> 12) as u8, addr)
        };
    }
    if (hw1 & 0xFFF0 == 0xF8D0 || hw1 & 0xFFF0 == 0xF850) && b >> 12 == 15 && a & 0xF != 13 {
        return Insn::IndirectJump; // LDR PC, [Rn, ...] with Rn != SP (not a pop)
    }
    Insn::Other
}

// ---------------------------------------------------------------------------------------
// Per-function scan
// ---------------------------------------------------------------------------------------

#[derive(Debug, Clone, Default)]
pub struct Func {
    pub name: String,
    pub addr: u32,
    pub size: u32,
    pub frame: u32,
    pub calls: Vec<u32>,
    pub branches: Vec<u32>,
    pub indirect: u32,
    pub sp_by_register: bool,
    /// 32-bit constants the function builds (MOVW/MOVT pairs, literal loads), in order.
    pub constants: Vec<u32>,
}

/// Walks `code` (the function's bytes at `addr`); `is_data(pc)` tells mapping-symbol
/// data regions, which are skipped.
pub fn scan(
    name: &str,
    addr: u32,
    code: &[u8],
    elf: Option<&Elf>,
    is_data: &dyn Fn(u32) -> bool,
) -> Func {
    let mut f = Func {
        name: name.to_string(),
        addr,
        size: code.len() as u32,
        ..Func::default()
    };
    let mut regs: [Option<u32>; 16] = [None; 16];
    let mut i = 0usize;
    while i + 2 <= code.len() {
        let pc = addr.wrapping_add(i as u32);
        if is_data(pc) {
            i += 2;
            continue;
        }
        let hw1 = u16::from_le_bytes([code[i], code[i + 1]]);
        let insn = if is_32bit(hw1) {
            if i + 4 > code.len() {
                break;
            }
            let hw2 = u16::from_le_bytes([code[i + 2], code[i + 3]]);
            i += 4;
            decode32(hw1, hw2, pc)
        } else {
            i += 2;
            decode16(hw1, pc)
        };
        match insn {
            Insn::SpDown(n) => f.frame = f.frame.saturating_add(n),
            Insn::SpByRegister => f.sp_by_register = true,
            Insn::Call(t) => f.calls.push(t),
            Insn::Branch(t) => f.branches.push(t),
            Insn::IndirectCall | Insn::IndirectJump => f.indirect += 1,
            Insn::Movw(r, v) => regs[r as usize & 15] = Some(u32::from(v)),
            Insn::Movt(r, v) => {
                if let Some(lo) = regs[r as usize & 15].take() {
                    f.constants.push((lo & 0xFFFF) | (u32::from(v) << 16));
                }
            }
            Insn::LdrLiteral(_, at) => {
                if let Some(w) = elf.and_then(|e| e.at(at, 4)) {
                    f.constants
                        .push(u32::from_le_bytes([w[0], w[1], w[2], w[3]]));
                }
            }
            Insn::Other => {}
        }
    }
    f
}

// ---------------------------------------------------------------------------------------
// Depth over the call graph
// ---------------------------------------------------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Depth {
    /// Bytes (a cycle on the way is counted once).
    pub bytes: u64,
    /// The callee on the deepest path.
    pub next: Option<usize>,
    /// A recursion is reachable: the real figure is unbounded.
    pub recursive: bool,
}

#[derive(Clone, Copy)]
enum Mark {
    New,
    Active,
    Done(Depth),
}

/// Depths in one context: the static edges plus `extra` edges (indirect calls resolved
/// for this context, e.g. an executor calling its tasks' poll functions).
pub struct Solver<'a> {
    frame: &'a [u32],
    edges: &'a [Vec<usize>],
    extra: HashMap<usize, Vec<usize>>,
    marks: Vec<Mark>,
    /// Back edges found (caller, callee): recursion.
    pub cycles: Vec<(usize, usize)>,
}

impl<'a> Solver<'a> {
    pub fn new(
        frame: &'a [u32],
        edges: &'a [Vec<usize>],
        extra: HashMap<usize, Vec<usize>>,
    ) -> Self {
        Solver {
            frame,
            edges,
            extra,
            marks: vec![Mark::New; frame.len()],
            cycles: Vec::new(),
        }
    }

    pub fn depth(&mut self, f: usize) -> Depth {
        match self.marks[f] {
            Mark::Done(d) => return d,
            Mark::Active => {
                return Depth {
                    bytes: 0,
                    next: None,
                    recursive: true,
                }
            }
            Mark::New => {}
        }
        self.marks[f] = Mark::Active;
        let mut best = Depth {
            bytes: 0,
            next: None,
            recursive: false,
        };
        let callees: Vec<usize> = self.edges[f]
            .iter()
            .chain(self.extra.get(&f).into_iter().flatten())
            .copied()
            .collect();
        for c in callees {
            if matches!(self.marks[c], Mark::Active) {
                self.cycles.push((f, c));
            }
            let d = self.depth(c);
            best.recursive |= d.recursive;
            if best.next.is_none() || d.bytes > best.bytes {
                best.bytes = d.bytes;
                best.next = Some(c);
            }
        }
        let d = Depth {
            bytes: u64::from(self.frame[f]) + best.bytes,
            next: best.next,
            recursive: best.recursive,
        };
        self.marks[f] = Mark::Done(d);
        d
    }

    /// The deepest chain from `f` (stops at a repeated function).
    pub fn chain(&mut self, f: usize) -> Vec<usize> {
        let mut out = vec![f];
        let mut at = f;
        while let Some(n) = self.depth(at).next {
            if out.contains(&n) {
                out.push(n);
                break;
            }
            out.push(n);
            at = n;
        }
        out
    }
}

// ---------------------------------------------------------------------------------------
// Names
// ---------------------------------------------------------------------------------------

/// Legacy Rust mangling (`_ZN` length-prefixed parts `E`) → readable path, without the
/// `17h<hash>` part. Other names are returned unchanged.
pub fn demangle(name: &str) -> String {
    if let Some(v0) = name.strip_prefix("_R") {
        return demangle_v0(v0).unwrap_or_else(|| name.to_string());
    }
    let Some(rest) = name.strip_prefix("_ZN") else {
        return name.to_string();
    };
    let b = rest.as_bytes();
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < b.len() && b[i] != b'E' {
        let start = i;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
        let Ok(len) = rest[start..i].parse::<usize>() else {
            return name.to_string();
        };
        let Some(part) = rest.get(i..i + len) else {
            return name.to_string();
        };
        i += len;
        let is_hash =
            len == 17 && part.starts_with('h') && part[1..].bytes().all(|c| c.is_ascii_hexdigit());
        if !is_hash {
            parts.push(unescape(part));
        }
    }
    parts.join("::")
}

/// The v0 mangling (`_R`), plain paths only: crate roots (`C`) and nested paths (`N`);
/// anything else (impls, generic arguments, back references) → `None`.
fn demangle_v0(s: &str) -> Option<String> {
    fn ident(b: &[u8], i: &mut usize) -> Option<String> {
        if b.get(*i) == Some(&b's') {
            // disambiguator: s <base62> _
            *i += 1;
            while *b.get(*i)? != b'_' {
                *i += 1;
            }
            *i += 1;
        }
        if b.get(*i) == Some(&b'u') {
            return None; // punycode
        }
        let start = *i;
        while b.get(*i)?.is_ascii_digit() {
            *i += 1;
        }
        let len: usize = std::str::from_utf8(&b[start..*i]).ok()?.parse().ok()?;
        if b.get(*i) == Some(&b'_') {
            *i += 1;
        }
        let id = std::str::from_utf8(b.get(*i..*i + len)?).ok()?.to_string();
        *i += len;
        Some(id)
    }
    fn path(b: &[u8], i: &mut usize, depth: u32) -> Option<String> {
        if depth > 64 {
            return None;
        }
        let tag = *b.get(*i)?;
        *i += 1;
        match tag {
            b'C' => ident(b, i),
            b'N' => {
                let ns = *b.get(*i)?;
                *i += 1;
                let inner = path(b, i, depth + 1)?;
                let id = ident(b, i)?;
                Some(match (ns.is_ascii_uppercase(), id.is_empty()) {
                    (true, _) if ns == b'C' => format!("{inner}::{{closure}}"),
                    (true, true) => format!("{inner}::{{{}}}", ns as char),
                    _ => format!("{inner}::{id}"),
                })
            }
            _ => None,
        }
    }
    let b = s.as_bytes();
    let mut i = 0;
    let out = path(b, &mut i, 0)?;
    // A trailing instantiating crate is allowed; anything else is not understood.
    (i == b.len() || b[i] == b'C').then_some(out)
}

fn unescape(part: &str) -> String {
    let part = part
        .strip_prefix("_$")
        .map_or(part.to_string(), |p| format!("${p}"));
    let mut out = String::new();
    let mut rest = part.as_str();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("..") {
            out.push_str("::");
            rest = r;
        } else if let Some(r) = rest.strip_prefix('$') {
            let Some(end) = r.find('$') else {
                out.push_str(rest);
                break;
            };
            let code = &r[..end];
            let s = match code {
                "LT" => "<".to_string(),
                "GT" => ">".to_string(),
                "RF" => "&".to_string(),
                "BP" => "*".to_string(),
                "C" => ",".to_string(),
                "SP" => "@".to_string(),
                "LP" => "(".to_string(),
                "RP" => ")".to_string(),
                _ => code
                    .strip_prefix('u')
                    .and_then(|h| u32::from_str_radix(h, 16).ok())
                    .and_then(char::from_u32)
                    .map_or_else(|| format!("${code}$"), String::from),
            };
            out.push_str(&s);
            rest = &r[end + 1..];
        } else {
            let c = rest.chars().next().unwrap_or(' ');
            out.push(c);
            rest = &rest[c.len_utf8()..];
        }
    }
    out
}

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

struct Root {
    label: String,
    level: Option<i32>,
    func: usize,
    extra: HashMap<usize, Vec<usize>>,
}

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

pub fn analyse_elf(elf: &Elf) -> Result<StackReport, String> {
    let symbols = elf.symbols()?;
    // Mapping symbols: $d… = data, $t… / $a… = code.
    let mut mapping: Vec<(u32, bool)> = symbols
        .iter()
        .filter(|s| {
            s.name.starts_with("$d") || s.name.starts_with("$t") || s.name.starts_with("$a")
        })
        .map(|s| (s.value & !1, s.name.starts_with("$d")))
        .collect();
    mapping.sort();
    let have_mapping = !mapping.is_empty();
    let is_data = |pc: u32| {
        let i = mapping.partition_point(|&(a, _)| a <= pc);
        i > 0 && mapping[i - 1].1
    };

    // Functions, one per start address.
    let mut funcs: Vec<Func> = Vec::new();
    let mut fsyms: Vec<&Symbol> = symbols
        .iter()
        .filter(|s| s.kind == STT_FUNC && s.size > 0)
        .collect();
    fsyms.sort_by_key(|s| (s.value & !1, s.name.starts_with("_ZN")));
    fsyms.dedup_by_key(|s| s.value & !1);
    for s in fsyms {
        let addr = s.value & !1;
        let Some(code) = elf.at(addr, s.size) else {
            continue;
        };
        funcs.push(scan(&demangle(&s.name), addr, code, Some(elf), &is_data));
    }
    if funcs.is_empty() {
        return Err("no functions with a size in .symtab".into());
    }
    let start_of: HashMap<u32, usize> =
        funcs.iter().enumerate().map(|(i, f)| (f.addr, i)).collect();
    let containing = |a: u32| -> Option<usize> {
        let i = funcs.partition_point(|f| f.addr <= a);
        (i > 0 && u64::from(a) < u64::from(funcs[i - 1].addr) + u64::from(funcs[i - 1].size))
            .then(|| i - 1)
    };

    // Edges.
    let mut edges: Vec<Vec<usize>> = vec![Vec::new(); funcs.len()];
    let mut unresolved_direct = 0usize;
    for (i, f) in funcs.iter().enumerate() {
        for &t in &f.calls {
            match start_of
                .get(&(t & !1))
                .copied()
                .or_else(|| containing(t & !1))
            {
                Some(j) => edges[i].push(j),
                None => unresolved_direct += 1,
            }
        }
        for &t in &f.branches {
            if t >= f.addr && u64::from(t) < u64::from(f.addr) + u64::from(f.size) {
                continue;
            }
            match start_of
                .get(&(t & !1))
                .copied()
                .or_else(|| containing(t & !1))
            {
                Some(j) => edges[i].push(j),
                None => unresolved_direct += 1,
            }
        }
        edges[i].sort_unstable();
        edges[i].dedup();
    }
    let frame: Vec<u32> = funcs.iter().map(|f| f.frame).collect();

    // Task poll functions, named by the task pool whose address is built just before
    // the poll function's address (the spawn code stores the poll function pointer
    // into that task's `POOL` storage).
    let pools: Vec<(u32, u32, String)> = symbols
        .iter()
        .filter(|s| s.kind == STT_OBJECT && s.size > 0)
        .filter_map(|s| {
            let n = demangle(&s.name);
            let task = n.strip_suffix("::POOL")?;
            let short = task.rsplit("::").next().unwrap_or(task).to_string();
            Some((s.value, s.size, short))
        })
        .collect();
    let polls: Vec<usize> = (0..funcs.len())
        .filter(|&i| funcs[i].name.starts_with(TASK_POLL))
        .collect();
    let mut task_of: HashMap<usize, String> = HashMap::new();
    // The functions that store each poll function's address (spawn code).
    let mut spawned_by: HashMap<usize, Vec<usize>> = HashMap::new();
    for (fi, f) in funcs.iter().enumerate() {
        let mut last_pool: Option<&str> = None;
        for &c in &f.constants {
            if let Some((_, _, t)) = pools.iter().find(|(a, s, _)| c >= *a && c < a + s) {
                last_pool = Some(t);
            } else if let Some(&p) = start_of.get(&(c & !1)) {
                if c & 1 == 1 && polls.contains(&p) {
                    spawned_by.entry(p).or_default().push(fi);
                    if let Some(t) = last_pool {
                        task_of.entry(p).or_insert_with(|| t.to_string());
                    }
                }
            }
        }
    }
    let (irq_executor, cyclic_tasks) = INTERRUPT_EXECUTOR;
    let unidentified: Vec<usize> = polls
        .iter()
        .copied()
        .filter(|p| !task_of.contains_key(p))
        .collect();
    // Unidentified polls are counted on both executors.
    let cyclic_polls: Vec<usize> = polls
        .iter()
        .copied()
        .filter(|p| {
            task_of
                .get(p)
                .is_none_or(|t| cyclic_tasks.contains(&t.as_str()))
        })
        .collect();
    let thread_polls: Vec<usize> = polls
        .iter()
        .copied()
        .filter(|p| {
            task_of
                .get(p)
                .is_none_or(|t| !cyclic_tasks.contains(&t.as_str()))
        })
        .collect();
    let display = |i: usize| -> String {
        match task_of.get(&i) {
            Some(t) => format!("{}[{t}]", funcs[i].name),
            None => funcs[i].name.clone(),
        }
    };

    // Vector table: initial SP, then handlers.
    let vt = elf
        .section(".vector_table")
        .ok_or("no .vector_table section")?;
    let vt_bytes = elf.data(vt)?;
    let names_at = |addr: u32| -> Vec<&str> {
        symbols
            .iter()
            .filter(|s| {
                s.value & !1 == addr && s.kind == STT_FUNC || (s.value == (addr | 1) && s.kind == 0)
            })
            .map(|s| s.name.as_str())
            .collect()
    };
    let thread_dispatchers: Vec<usize> = (0..funcs.len())
        .filter(|&i| DISPATCHERS.iter().any(|d| funcs[i].name.starts_with(d)))
        .collect();
    let extra_for = |dispatchers: &[usize], targets: &[usize]| -> HashMap<usize, Vec<usize>> {
        dispatchers.iter().map(|&d| (d, targets.to_vec())).collect()
    };

    let mut roots: Vec<Root> = Vec::new();
    let mut handled: Vec<u32> = Vec::new();
    let mut irq_handler: Option<usize> = None;
    let mut notes: Vec<String> = Vec::new();
    for (index, w) in vt_bytes.chunks_exact(4).enumerate().skip(1) {
        let v = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
        if v == 0 || handled.contains(&v) {
            continue;
        }
        handled.push(v);
        let Some(&f) = start_of.get(&(v & !1)) else {
            notes.push(format!(
                "vector {index} → {v:#010x}: no function there, not analysed"
            ));
            continue;
        };
        let names = names_at(v & !1);
        let named: Vec<String> = names.iter().map(|n| demangle(n)).collect();
        let is = |n: &str| named.iter().any(|m| m == n);
        let (level, label) = match index {
            1 => (None, "Reset (thread mode)".to_string()),
            2 => (Some(-2), "NMI".to_string()),
            3 => (Some(-1), "HardFault".to_string()),
            _ => {
                let p = priority_of(&names);
                let mut label: Vec<&str> = names
                    .iter()
                    .copied()
                    .filter(|n| priority_of(&[n]).is_some())
                    .collect();
                if label.is_empty() {
                    label = if is("DefaultHandler") {
                        vec!["DefaultHandler"]
                    } else {
                        names.clone()
                    };
                }
                (Some(p.unwrap_or(0)), label.join("/"))
            }
        };
        let mut extra = HashMap::new();
        if level.is_none() {
            extra = extra_for(&thread_dispatchers, &thread_polls);
        } else if is(irq_executor) {
            irq_handler = Some(f);
            let mut d = thread_dispatchers.clone();
            d.push(f);
            extra = extra_for(&d, &cyclic_polls);
        }
        roots.push(Root {
            label,
            level,
            func: f,
            extra,
        });
    }
    let reset = roots
        .iter()
        .find(|r| r.level.is_none())
        .map(|r| r.func)
        .ok_or("no Reset handler in the vector table")?;

    // Every task the interrupt executor is said to run must exist: a renamed task
    // would otherwise be counted on the thread executor only (an image without tasks
    // has nothing to check).
    for t in cyclic_tasks.iter().filter(|_| !polls.is_empty()) {
        if !task_of.values().any(|n| n == t) {
            return Err(format!(
                "task `{t}` of the interrupt executor {irq_executor} not found (no `{t}::POOL` \
                 beside a task poll): update INTERRUPT_EXECUTOR in xtask/src/stack.rs"
            ));
        }
    }
    // The start-up task(s): spawned by code the reset handler reaches through direct
    // calls alone (the entry's `executor.run` closure), not by another task — found
    // from the code, whatever the task is called.
    let from_reset = {
        let mut seen = vec![false; funcs.len()];
        let mut todo = vec![reset];
        while let Some(f) = todo.pop() {
            if !std::mem::replace(&mut seen[f], true) {
                todo.extend(edges[f].iter().copied());
            }
        }
        seen
    };
    let startup: Vec<usize> = polls
        .iter()
        .copied()
        .filter(|p| {
            spawned_by
                .get(p)
                .is_some_and(|by| by.iter().any(|&f| from_reset[f]))
        })
        .collect();

    // Per-task roots: the executor's path to the dispatch + that task's poll.
    let mut task_roots: Vec<Root> = Vec::new();
    for &p in &polls {
        let mut name = task_of
            .get(&p)
            .cloned()
            .unwrap_or_else(|| format!("{:#010x}", funcs[p].addr));
        if startup.contains(&p) {
            name.push_str(", start-up");
        }
        let on_irq = task_of
            .get(&p)
            .is_some_and(|t| cyclic_tasks.contains(&t.as_str()));
        match (on_irq, irq_handler) {
            (true, Some(h)) => {
                let mut d = thread_dispatchers.clone();
                d.push(h);
                task_roots.push(Root {
                    label: format!("task {name} (interrupt executor {irq_executor})"),
                    level: Some(2),
                    func: h,
                    extra: extra_for(&d, &[p]),
                });
            }
            _ => task_roots.push(Root {
                label: format!("task {name} (thread executor)"),
                level: None,
                func: reset,
                extra: extra_for(&thread_dispatchers, &[p]),
            }),
        }
    }

    // Depths.
    struct Result1 {
        label: String,
        level: Option<i32>,
        depth: Depth,
        chain: Vec<usize>,
    }
    let mut cycles: Vec<(usize, usize)> = Vec::new();
    let mut eval = |r: &Root| -> Result1 {
        let mut s = Solver::new(&frame, &edges, r.extra.clone());
        let depth = s.depth(r.func);
        let chain = s.chain(r.func);
        for c in s.cycles {
            if !cycles.contains(&c) {
                cycles.push(c);
            }
        }
        Result1 {
            label: r.label.clone(),
            level: r.level,
            depth,
            chain,
        }
    };
    let level_results: Vec<Result1> = roots.iter().map(&mut eval).collect();
    let task_results: Vec<Result1> = task_roots.iter().map(&mut eval).collect();

    // What an unresolved indirect call could add: the functions no direct call reaches
    // (their address is taken somewhere) and their depth.
    let mut called = vec![false; funcs.len()];
    for e in &edges {
        for &c in e {
            called[c] = true;
        }
    }
    for r in &roots {
        called[r.func] = true;
    }
    for &p in &polls {
        called[p] = true;
    }
    let mut s0 = Solver::new(&frame, &edges, HashMap::new());
    let mut orphans: Vec<(u64, usize)> = (0..funcs.len())
        .filter(|&f| !called[f])
        .map(|f| (s0.depth(f).bytes, f))
        .collect();
    orphans.sort_by_key(|&(d, _)| std::cmp::Reverse(d));
    // The same nesting with every unresolved indirect call resolved to every orphan
    // (a coarse bound for what the indirect calls can add).
    let orphan_ids: Vec<usize> = orphans.iter().map(|&(_, f)| f).collect();
    let alt_depths: Vec<(Option<i32>, u64)> = roots
        .iter()
        .map(|r| {
            let mut extra = r.extra.clone();
            for (f, func) in funcs.iter().enumerate() {
                if func.indirect > 0 && !extra.contains_key(&f) {
                    extra.insert(f, orphan_ids.clone());
                }
            }
            let mut s = Solver::new(&frame, &edges, extra);
            (r.level, s.depth(r.func).bytes)
        })
        .collect();
    let alt_thread = alt_depths
        .iter()
        .filter(|(l, _)| l.is_none())
        .map(|&(_, d)| d)
        .max()
        .unwrap_or(0);
    let mut alt_worst = alt_thread;
    {
        let mut ls: Vec<i32> = alt_depths.iter().filter_map(|&(l, _)| l).collect();
        ls.sort_unstable();
        ls.dedup();
        for l in ls {
            let top = alt_depths
                .iter()
                .filter(|(x, _)| *x == Some(l))
                .map(|&(_, d)| d)
                .max()
                .unwrap_or(0);
            alt_worst += top + EXCEPTION_FRAME;
        }
    }

    // Nesting: thread + per priority level the deepest handler + one frame per level.
    let thread = level_results
        .iter()
        .find(|r| r.level.is_none())
        .ok_or("no thread root")?;
    let mut levels: Vec<i32> = level_results.iter().filter_map(|r| r.level).collect();
    levels.sort_unstable();
    levels.dedup();
    levels.reverse(); // least urgent first
                      // Recursion through the panic handler (a panic while the panic's logging runs)
                      // is reported apart: it only ever happens on the way to the reset.
    let panic_handler = (0..funcs.len()).find(|&i| {
        funcs[i].name == "__rustc::rust_begin_unwind" || funcs[i].name == "rust_begin_unwind"
    });
    let reaches = |from: usize, to: usize| -> bool {
        let mut seen = vec![false; funcs.len()];
        let mut todo = vec![from];
        while let Some(f) = todo.pop() {
            if f == to {
                return true;
            }
            if !std::mem::replace(&mut seen[f], true) {
                todo.extend(edges[f].iter().copied());
            }
        }
        false
    };
    type Edges = Vec<(usize, usize)>;
    let (panic_cycles, other_cycles): (Edges, Edges) = cycles
        .iter()
        .partition(|&&(a, b)| panic_handler.is_some_and(|p| reaches(b, p) && reaches(p, a)));
    let mut worst = thread.depth.bytes;
    let bounded = other_cycles.is_empty();
    let mut sum = format!("thread {}", thread.depth.bytes);
    for &l in &levels {
        let Some(top) = level_results
            .iter()
            .filter(|r| r.level == Some(l))
            .max_by_key(|r| r.depth.bytes)
        else {
            continue;
        };
        worst += top.depth.bytes + EXCEPTION_FRAME;
        let _ = write!(sum, " + P{l} {} {}", top.label, top.depth.bytes);
    }
    let _ = write!(
        sum,
        " + {} exception frames × {EXCEPTION_FRAME}",
        levels.len()
    );

    let mut text = String::new();
    let _ = writeln!(
        text,
        "  stack (static analysis of the ELF): worst case {worst} B{} = {sum}",
        if bounded {
            ""
        } else {
            " + RECURSION (unbounded)"
        }
    );
    // For information: once the start-up (`main` task) has finished, the thread level
    // is the deepest other thread task. The figure above keeps the start-up, since the
    // interrupts already run during it.
    if let Some(steady) = task_results
        .iter()
        .zip(&task_roots)
        .filter(|(r, root)| {
            r.level.is_none() && !root.extra.values().flatten().any(|p| startup.contains(p))
        })
        .map(|(r, _)| r)
        .max_by_key(|r| r.depth.bytes)
    {
        if steady.depth.bytes < thread.depth.bytes {
            let _ = writeln!(
                text,
                "  after start-up (the main task done; thread = {} {} B): {} B",
                steady.label,
                steady.depth.bytes,
                worst - thread.depth.bytes + steady.depth.bytes
            );
        }
    }
    let level_name = |l: Option<i32>| match l {
        None => "thread".to_string(),
        Some(p) => format!("P{p}"),
    };
    // The deepest roots: the handlers and the per-task paths.
    let mut all: Vec<&Result1> = level_results.iter().chain(task_results.iter()).collect();
    all.sort_by_key(|r| std::cmp::Reverse(r.depth.bytes));
    let _ = writeln!(
        text,
        "  deepest roots (bytes; chain with each function's frame):"
    );
    let mut on_chains: Vec<usize> = Vec::new();
    for (n, r) in all.iter().take(10).enumerate() {
        let chain: Vec<String> = r
            .chain
            .iter()
            .map(|&f| format!("{} ({})", display(f), frame[f]))
            .collect();
        let _ = writeln!(
            text,
            "   {:>2}. {} B{}  {} [{}]: {}",
            n + 1,
            r.depth.bytes,
            if r.depth.recursive {
                " (a recursion on the way counted once)"
            } else {
                ""
            },
            r.label,
            level_name(r.level),
            chain.join(" > ")
        );
        for &f in &r.chain {
            if !on_chains.contains(&f) {
                on_chains.push(f);
            }
        }
    }
    let mut dispatch_all = thread_dispatchers.clone();
    dispatch_all.extend(irq_handler);
    let indirect: Vec<String> = on_chains
        .iter()
        .filter(|&&f| funcs[f].indirect > 0 && !dispatch_all.contains(&f))
        .map(|&f| format!("{} ({})", display(f), funcs[f].indirect))
        .collect();
    if !indirect.is_empty() {
        let _ = writeln!(
            text,
            "  caveat: indirect calls not followed (BLX/BX register; count) in functions on these chains: {}",
            indirect.join(", ")
        );
    }
    // Indirect calls anywhere else the roots reach (the task polls included).
    let mut seen = vec![false; funcs.len()];
    let mut todo: Vec<usize> = roots
        .iter()
        .map(|r| r.func)
        .chain(polls.iter().copied())
        .collect();
    while let Some(f) = todo.pop() {
        if !std::mem::replace(&mut seen[f], true) {
            todo.extend(edges[f].iter().copied());
        }
    }
    let elsewhere: Vec<String> = (0..funcs.len())
        .filter(|&f| {
            seen[f]
                && funcs[f].indirect > 0
                && !dispatch_all.contains(&f)
                && !on_chains.contains(&f)
        })
        .map(|f| format!("{} ({})", display(f), funcs[f].indirect))
        .collect();
    if !elsewhere.is_empty() {
        let _ = writeln!(
            text,
            "  caveat: other reachable functions with indirect calls not followed: {}",
            elsewhere.join(", ")
        );
    }
    if !orphans.is_empty() {
        let top: Vec<String> = orphans
            .iter()
            .take(5)
            .map(|&(d, f)| format!("{} {d} B", display(f)))
            .collect();
        let _ = writeln!(
            text,
            "  caveat: {} functions are reached by no direct call (indirect-call targets, not counted above); deepest: {}; with every unresolved indirect call assumed to reach each of them: worst case {alt_worst} B",
            orphans.len(),
            top.join(", ")
        );
    }
    let dynamic: Vec<String> = funcs
        .iter()
        .filter(|f| f.sp_by_register)
        .map(|f| f.name.clone())
        .collect();
    if !dynamic.is_empty() {
        let _ = writeln!(
            text,
            "  caveat: SP lowered by a register (not counted) in: {}",
            dynamic.join(", ")
        );
    }
    for (a, b) in &other_cycles {
        let _ = writeln!(
            text,
            "  RECURSION: {} → {} (counted once)",
            display(*a),
            display(*b)
        );
    }
    if !panic_cycles.is_empty() {
        let list: Vec<String> = panic_cycles
            .iter()
            .map(|&(a, b)| format!("{} → {}", display(a), display(b)))
            .collect();
        let _ = writeln!(
            text,
            "  caveat: recursion through the panic handler, counted once (a panic inside the panic's own log line re-enters the handler once; the firmware logs only the first panic, hw::safety PANICKED): {}",
            list.join("; ")
        );
    }
    let _ = writeln!(
        text,
        "  assumptions: tasks on the interrupt executor {irq_executor}: {}; every other task on the thread executor; task polls identified by their POOL: {}/{}{}; exception frame {EXCEPTION_FRAME} B per nesting level (FPU context); {}{}",
        cyclic_tasks.join(", "),
        polls.len() - unidentified.len(),
        polls.len(),
        if unidentified.is_empty() {
            String::new()
        } else {
            " (the others counted on both executors)".to_string()
        },
        if have_mapping {
            "literal pools skipped by the $d mapping symbols"
        } else {
            "no mapping symbols: literal pools decoded as code (over-estimates)"
        },
        if unresolved_direct > 0 {
            format!("; {unresolved_direct} branch/call targets outside any function")
        } else {
            String::new()
        }
    );
    for n in notes {
        let _ = writeln!(text, "  note: {n}");
    }
    Ok(StackReport {
        worst,
        bounded,
        with_indirect: alt_worst,
        text,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn instruction_length() {
        assert!(!is_32bit(0xB580)); // push {r7, lr}
        assert!(is_32bit(0xE92D)); // stmdb sp!
        assert!(is_32bit(0xF000)); // bl
        assert!(is_32bit(0xF84D)); // str.w
        assert!(!is_32bit(0xE7FE)); // b . (16-bit, top bits 0b11100)
    }

    #[test]
    fn push_and_sub_forms() {
        // push {r7, lr}: r7 + M bit
        assert_eq!(decode16(0xB580, 0), Insn::SpDown(8));
        // push {r4, r5, r6, r7, lr}
        assert_eq!(decode16(0xB5F0, 0), Insn::SpDown(20));
        // push {r0}
        assert_eq!(decode16(0xB401, 0), Insn::SpDown(4));
        // sub sp, #8 (imm7 = 2)
        assert_eq!(decode16(0xB082, 0), Insn::SpDown(8));
        // sub sp, #508 (imm7 = 127)
        assert_eq!(decode16(0xB0FF, 0), Insn::SpDown(508));
        // add sp, #8 is not a decrement
        assert_eq!(decode16(0xB002, 0), Insn::Other);
        // pop {r7, pc}
        assert_eq!(decode16(0xBD80, 0), Insn::Other);
        // push.w {r4-r11, lr}: stmdb sp!, 0x4FF0 (9 registers)
        assert_eq!(decode32(0xE92D, 0x4FF0, 0), Insn::SpDown(36));
        // str.w r11, [sp, #-4]!
        assert_eq!(decode32(0xF84D, 0xBD04, 0), Insn::SpDown(4));
        // str.w r11, [sp], #4 (post-indexed, P=0) is not a push
        assert_eq!(decode32(0xF84D, 0xBB04, 0), Insn::Other);
        // strd r4, r5, [sp, #-8]!
        assert_eq!(decode32(0xE96D, 0x4502, 0), Insn::SpDown(8));
        // vpush {d8-d11}: imm8 = 8 words
        assert_eq!(decode32(0xED2D, 0x8B08, 0), Insn::SpDown(32));
        // vpush {d8} with D = 1 (d16-d31 form)
        assert_eq!(decode32(0xED6D, 0x0B02, 0), Insn::SpDown(8));
        // vpush {s16-s18}: single form, imm8 = 3
        assert_eq!(decode32(0xED2D, 0x8A03, 0), Insn::SpDown(12));
        // sub.w sp, sp, #1024: i=0, imm3=6, imm8=0x80 → 0x80 ror 12
        assert_eq!(decode32(0xF5AD, 0x6D80, 0), Insn::SpDown(1024));
        // sub.w sp, sp, #200 (imm12 = 200, unrotated)
        assert_eq!(decode32(0xF1AD, 0x0DC8, 0), Insn::SpDown(200));
        // subw sp, sp, #1000: imm12 = 0x3E8 → i=0 imm3=3 imm8=0xE8
        assert_eq!(decode32(0xF2AD, 0x3DE8, 0), Insn::SpDown(1000));
        // subw sp, sp, #2052: imm12 = 0x804 → i=1 imm3=0 imm8=0x04
        assert_eq!(decode32(0xF6AD, 0x0D04, 0), Insn::SpDown(2052));
        // sub.w r0, sp, #8 (Rd = r0) is not an SP decrement
        assert_eq!(decode32(0xF1AD, 0x0008, 0), Insn::Other);
        // sub.w sp, sp, r0
        assert_eq!(decode32(0xEBAD, 0x0D00, 0), Insn::SpByRegister);
    }

    #[test]
    fn modified_immediates() {
        assert_eq!(thumb_expand_imm(0x0AB), 0xAB);
        assert_eq!(thumb_expand_imm(0x1AB), 0x00AB_00AB);
        assert_eq!(thumb_expand_imm(0x2AB), 0xAB00_AB00);
        assert_eq!(thumb_expand_imm(0x3AB), 0xABAB_ABAB);
        // rotation 8 (imm12 = 0x400): 0x80 ror 8
        assert_eq!(thumb_expand_imm(0x400), 0x8000_0000);
        // 1024 = 0x80 ror 29 (imm12 = 29 << 7 = 0xE80)
        assert_eq!(thumb_expand_imm(0xE80), 0x400);
    }

    #[test]
    fn branches_and_calls() {
        // bl +0x1000 at 0x0800_0000: target 0x0800_1004; imm32 = 0x1000 → imm10 = 1, imm11 = 0,
        // S = 0, J1 = J2 = 1 (I1 = I2 = 0)
        assert_eq!(
            decode32(0xF001, 0xF800, 0x0800_0000),
            Insn::Call(0x0800_1004)
        );
        // bl -4 (to itself): imm32 = -4 → S=1, imm10 = 0x3FF, imm11 = 0x7FE, I1 = I2 = 1 → J = 1
        assert_eq!(
            decode32(0xF7FF, 0xFFFE, 0x0800_0100),
            Insn::Call(0x0800_0100)
        );
        // bl backwards by 0x10_0000: imm32 = -0x100000 → S=1, I1=1, I2=1, imm10 = 0x300
        assert_eq!(
            decode32(0xF700, 0xF800, 0x0810_0000),
            Insn::Call(0x0800_0004)
        );
        // bl forward with I1 = 1 (J1 = 0 with S = 0): +0x80_0000
        assert_eq!(
            decode32(0xF000, 0xD800, 0x0800_0000),
            Insn::Call(0x0880_0004)
        );
        // b.w +0x20: T4 with hw2 bit 12 set, bit 14 clear
        assert_eq!(
            decode32(0xF000, 0xB810, 0x0800_0000),
            Insn::Branch(0x0800_0024)
        );
        // beq.w -0x10 (T3, cond 0): S=1, J1=J2=1, imm6=0x3F, imm11=0x7F8
        assert_eq!(
            decode32(0xF43F, 0xAFF8, 0x0800_0100),
            Insn::Branch(0x0800_00F4)
        );
        // 16-bit b -4 (b .): 0xE7FE
        assert_eq!(decode16(0xE7FE, 0x0800_0010), Insn::Branch(0x0800_0010));
        // beq +4: 0xD002
        assert_eq!(decode16(0xD002, 0x0800_0010), Insn::Branch(0x0800_0018));
        // cbz r0, +8: i=0, imm5=4
        assert_eq!(decode16(0xB120, 0x0800_0010), Insn::Branch(0x0800_001C));
        // blx r1 / bx r2 / bx lr
        assert_eq!(decode16(0x4788, 0), Insn::IndirectCall);
        assert_eq!(decode16(0x4710, 0), Insn::IndirectJump);
        assert_eq!(decode16(0x4770, 0), Insn::Other);
        // udf / svc are not branches
        assert_eq!(decode16(0xDE00, 0), Insn::Other);
        assert_eq!(decode16(0xDF00, 0), Insn::Other);
        // ldr.w pc, [sp], #4 is a pop (return); ldr.w pc, [r0, #4] is an indirect jump
        assert_eq!(decode32(0xF85D, 0xFB04, 0), Insn::Other);
        assert_eq!(decode32(0xF8D0, 0xF004, 0), Insn::IndirectJump);
    }

    #[test]
    fn constants() {
        // movw r0, #0x6237 ; movt r0, #0x0800
        assert_eq!(decode32(0xF246, 0x2037, 0), Insn::Movw(0, 0x6237));
        assert_eq!(decode32(0xF6C0, 0x0000, 0), Insn::Movt(0, 0x0800));
        assert_eq!(decode32(0xF2C2, 0x0000, 0), Insn::Movt(0, 0x2000));
        // ldr r0, [pc, #56] at 0x080001DC: literal at align4(pc + 4) + 56 = 0x0800_0218
        assert_eq!(
            decode16(0x480E, 0x0800_01DC),
            Insn::LdrLiteral(0, 0x0800_0218)
        );
    }

    #[test]
    fn scan_a_function() {
        // push {r4, r5, r7, lr}; sub sp, #16; bl +0; blx r1; <data word>; pop {r4, r5, r7, pc}
        let words: [u16; 8] = [
            0xB5B0, 0xB084, 0xF000, 0xF800, 0x4788, 0xF000, 0xF000, 0xBDB0,
        ];
        let code: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let base = 0x0800_0000;
        let data = |pc: u32| pc == base + 10 || pc == base + 12;
        let f = scan("f", base, &code, None, &data);
        assert_eq!(f.frame, 32);
        assert_eq!(f.calls, vec![base + 8]);
        assert_eq!(f.indirect, 1);
        // Without the mapping symbols the data word decodes as a BL: more edges, never fewer.
        let g = scan("f", base, &code, None, &|_| false);
        assert_eq!(g.frame, 32);
        assert_eq!(g.calls.len(), 2);
    }

    #[test]
    fn depth_of_a_graph() {
        // 0 → 1 → 3, 0 → 2 → 3; 3 is a leaf.
        let frame = [8, 100, 16, 40];
        let edges = vec![vec![1, 2], vec![3], vec![3], vec![]];
        let mut s = Solver::new(&frame, &edges, HashMap::new());
        let d = s.depth(0);
        assert_eq!(d.bytes, 148);
        assert!(!d.recursive);
        assert_eq!(s.chain(0), vec![0, 1, 3]);
        assert!(s.cycles.is_empty());
        // An extra (resolved indirect) edge 2 → 4 makes 2's side the deeper one.
        let frame = [8, 100, 16, 40, 200];
        let edges = vec![vec![1, 2], vec![3], vec![3], vec![], vec![]];
        let extra: HashMap<usize, Vec<usize>> = [(2, vec![4])].into_iter().collect();
        let mut s = Solver::new(&frame, &edges, extra);
        assert_eq!(s.depth(0).bytes, 8 + 16 + 200);
        assert_eq!(s.chain(0), vec![0, 2, 4]);
    }

    #[test]
    fn recursion_is_reported() {
        // 0 → 1 → 2 → 1 (cycle), 0 → 3
        let frame = [4, 10, 20, 8];
        let edges = vec![vec![1, 3], vec![2], vec![1], vec![]];
        let mut s = Solver::new(&frame, &edges, HashMap::new());
        let d = s.depth(0);
        assert!(d.recursive);
        assert_eq!(d.bytes, 34); // the cycle counted once
        assert_eq!(s.cycles, vec![(2, 1)]);
        // A root that does not reach the cycle stays bounded.
        assert!(!s.depth(3).recursive);
        // Self-recursion.
        let frame = [4];
        let edges = vec![vec![0]];
        let mut s = Solver::new(&frame, &edges, HashMap::new());
        assert!(s.depth(0).recursive);
        assert_eq!(s.cycles, vec![(0, 0)]);
    }

    #[test]
    fn demangling() {
        assert_eq!(
            demangle("_ZN16embassy_executor3raw20TaskStorage$LT$F$GT$4poll17h45d492a386c24c63E"),
            "embassy_executor::raw::TaskStorage<F>::poll"
        );
        assert_eq!(
            demangle("_ZN8firmware6cyclic28_$u7b$$u7b$closure$u7d$$u7d$17h0123456789abcdefE"),
            "firmware::cyclic::{{closure}}"
        );
        assert_eq!(
            demangle("_ZN4core3ptr61drop_in_place$LT$embassy_futures..join..Join$LT$A$C$B$GT$$GT$17hd1a5fea42ad40495E"),
            "core::ptr::drop_in_place<embassy_futures::join::Join<A,B>>"
        );
        assert_eq!(
            demangle("_RNvNtNtCs7ldSeZOOJos_4core5slice5index16slice_index_fail"),
            "core::slice::index::slice_index_fail"
        );
        assert_eq!(
            demangle("_RNvCsfLfy6EI15iL_7___rustc17rust_begin_unwind"),
            "__rustc::rust_begin_unwind"
        );
        // v0 forms not understood stay as they are.
        assert_eq!(
            demangle("_RNvMs_Cs1_3fooNtB2_3Bar3baz"),
            "_RNvMs_Cs1_3fooNtB2_3Bar3baz"
        );
        assert_eq!(demangle("_RNvC9"), "_RNvC9");
        assert_eq!(demangle("main"), "main");
        // Garbage stays as it is, no panic.
        assert_eq!(demangle("_ZN99abcE"), "_ZN99abcE");
        assert_eq!(demangle("_ZNxE"), "_ZNxE");
        assert_eq!(demangle("_ZN3a$bE"), "a$b");
    }

    #[test]
    fn elf_reader_rejects_garbage() {
        assert!(Elf::parse(Vec::new()).is_err());
        assert!(Elf::parse(vec![0u8; 64]).is_err());
        let mut h = vec![0u8; 64];
        h[..4].copy_from_slice(b"\x7fELF");
        h[4] = 2; // ELF64
        h[5] = 1;
        assert!(Elf::parse(h.clone()).is_err());
        h[4] = 1;
        // Section headers far outside the file.
        h[0x20..0x24].copy_from_slice(&0x1000u32.to_le_bytes());
        h[0x2E..0x30].copy_from_slice(&40u16.to_le_bytes());
        h[0x30..0x32].copy_from_slice(&3u16.to_le_bytes());
        assert!(Elf::parse(h).is_err());
    }

    /// A minimal ELF32: sections (name, type, address, bytes, link), section 0 = null.
    fn build_elf(sections: &[(&str, u32, u32, Vec<u8>, u32)]) -> Vec<u8> {
        let mut shstr = vec![0u8];
        let mut names = Vec::new();
        for (n, ..) in sections {
            names.push(shstr.len() as u32);
            shstr.extend_from_slice(n.as_bytes());
            shstr.push(0);
        }
        let shstr_name = shstr.len() as u32;
        shstr.extend_from_slice(b".shstrtab\0");
        let mut out = vec![0u8; 52];
        let mut headers = vec![0u8; 40]; // null section
        let all: Vec<(u32, u32, u32, &[u8], u32)> = sections
            .iter()
            .zip(&names)
            .map(|((_, k, a, d, l), n)| (*n, *k, *a, d.as_slice(), *l))
            .chain(std::iter::once((shstr_name, 3, 0, shstr.as_slice(), 0)))
            .collect();
        for (name, kind, addr, data, link) in &all {
            let offset = out.len() as u32;
            out.extend_from_slice(data);
            for v in [
                *name,
                *kind,
                0,
                *addr,
                offset,
                data.len() as u32,
                *link,
                0,
                4,
                0,
            ] {
                headers.extend_from_slice(&v.to_le_bytes());
            }
        }
        let shoff = out.len() as u32;
        out.extend_from_slice(&headers);
        out[..6].copy_from_slice(b"\x7fELF\x01\x01");
        out[0x20..0x24].copy_from_slice(&shoff.to_le_bytes());
        out[0x2E..0x30].copy_from_slice(&40u16.to_le_bytes());
        out[0x30..0x32].copy_from_slice(&(all.len() as u16 + 1).to_le_bytes());
        out[0x32..0x34].copy_from_slice(&(all.len() as u16).to_le_bytes());
        out
    }

    fn halfwords(h: &[u16]) -> Vec<u8> {
        h.iter().flat_map(|w| w.to_le_bytes()).collect()
    }

    #[test]
    fn whole_analysis_of_a_synthetic_image() {
        // 0x0800_0100 Reset: push {r7, lr}; bl f; b .
        // 0x0800_0108 f:     push {r4-r7, lr}; sub sp, #16; blx r3; pop {r4-r7, pc}
        // 0x0800_0110 ADC1_2: push {r7, lr}; bl g; pop {r7, pc}
        // 0x0800_0118 g:     push {r7, lr}; sub sp, #8; pop {r7, pc}; nop
        let text = halfwords(&[
            0xB580, 0xF000, 0xF801, 0xE7FE, // Reset
            0xB5F0, 0xB084, 0x4798, 0xBDF0, // f
            0xB580, 0xF000, 0xF801, 0xBD80, // ADC1_2
            0xB580, 0xB082, 0xBD80, 0xBF00, // g
            0xB580, 0xBD80, // h: called by no one (an indirect-call target)
        ]);
        // Vector table: SP, Reset, NMI, HardFault, … ADC1_2 is IRQ 18 (vector 34).
        let mut vt = [0u32; 35];
        vt[0] = 0x2000_8000;
        vt[1] = 0x0800_0101;
        vt[34] = 0x0800_0111;
        let vt: Vec<u8> = vt.iter().flat_map(|w| w.to_le_bytes()).collect();
        let mut strtab = vec![0u8];
        let mut symtab = vec![0u8; 16];
        for (name, value, size, kind) in [
            ("Reset", 0x0800_0101u32, 8u32, STT_FUNC),
            ("f", 0x0800_0109, 8, STT_FUNC),
            ("ADC1_2", 0x0800_0111, 8, STT_FUNC),
            ("g", 0x0800_0119, 8, STT_FUNC),
            ("h", 0x0800_0121, 4, STT_FUNC),
            ("$t", 0x0800_0100, 0, 0),
        ] {
            symtab.extend_from_slice(&(strtab.len() as u32).to_le_bytes());
            symtab.extend_from_slice(&value.to_le_bytes());
            symtab.extend_from_slice(&size.to_le_bytes());
            symtab.extend_from_slice(&[kind, 0, 1, 0]);
            strtab.extend_from_slice(name.as_bytes());
            strtab.push(0);
        }
        let bytes = build_elf(&[
            (".vector_table", 1, 0x0800_0000, vt, 0),
            (".text", 1, 0x0800_0100, text, 0),
            (".symtab", SHT_SYMTAB, 0, symtab, 4),
            (".strtab", 3, 0, strtab, 0),
        ]);
        let elf = Elf::parse(bytes.clone()).unwrap();
        let r = analyse_elf(&elf).unwrap();
        // thread: Reset 8 + f 36; P0: ADC1_2 8 + g 16; one exception frame.
        assert_eq!(r.worst, 44 + 24 + EXCEPTION_FRAME, "{}", r.text);
        assert!(r.bounded);
        assert!(r.text.contains("f (1)"), "{}", r.text);
        // The coarse bound lets f's BLX reach h (frame 8).
        assert!(
            r.text.contains("1 functions are reached by no direct call"),
            "{}",
            r.text
        );
        assert_eq!(r.with_indirect, r.worst + 8);
        // Truncated images give an error or a report, never a panic.
        for cut in (0..bytes.len()).step_by(7) {
            if let Ok(elf) = Elf::parse(bytes[..cut].to_vec()) {
                let _ = analyse_elf(&elf);
            }
        }
        // Garbage in every byte of the code and the table: no panic.
        for seed in 1..40u32 {
            let mut noisy = bytes.clone();
            let mut x = seed;
            for b in noisy.iter_mut().skip(52) {
                x = x.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                if x >> 28 == 0 {
                    *b = (x >> 16) as u8;
                }
            }
            if let Ok(elf) = Elf::parse(noisy) {
                let _ = analyse_elf(&elf);
            }
        }
    }

    #[test]
    fn priorities() {
        assert_eq!(priority_of(&["ADC1_2"]), Some(0));
        assert_eq!(priority_of(&["DMA1_CHANNEL2"]), Some(1));
        assert_eq!(priority_of(&["EXTI1", "EXTI2", "EXTI3"]), Some(2));
        assert_eq!(priority_of(&["TIM5"]), Some(3));
        assert_eq!(priority_of(&["DefaultHandler", "USART1"]), None);
    }
}
