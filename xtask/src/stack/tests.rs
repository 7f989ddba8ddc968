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
    // SUB.W SP, SP, #ThumbExpandImm(imm12): i:imm3:imm8 spread over the two halfwords.
    let sub_sp = |imm12: u16| {
        decode32(
            0xF1AD | (imm12 >> 11) << 10,
            0x0D00 | ((imm12 >> 8) & 7) << 12 | (imm12 & 0xFF),
            0,
        )
    };
    assert_eq!(sub_sp(0x0AB), Insn::SpDown(0xAB));
    assert_eq!(sub_sp(0x1AB), Insn::SpDown(0x00AB_00AB));
    assert_eq!(sub_sp(0x2AB), Insn::SpDown(0xAB00_AB00));
    assert_eq!(sub_sp(0x3AB), Insn::SpDown(0xABAB_ABAB));
    // rotation 8 (imm12 = 0x400): 0x80 ror 8
    assert_eq!(sub_sp(0x400), Insn::SpDown(0x8000_0000));
    // 1024 = 0x80 ror 29 (imm12 = 29 << 7 = 0xE80)
    assert_eq!(sub_sp(0xE80), Insn::SpDown(0x400));
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
    // thread: Reset 8 + f 36; ADC1_2 (its level) 8 + g 16; one exception frame.
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
    // The firmware's table (`firmware::irq_priority`): the break above the current
    // loop.
    assert_eq!(priority_of(&["TIM1_BRK_TIM15"]), Some(0));
    assert_eq!(priority_of(&["TIM8_BRK"]), Some(0));
    assert_eq!(priority_of(&["ADC1_2"]), Some(1));
    assert_eq!(priority_of(&["DMA1_CHANNEL2"]), Some(2));
    assert_eq!(priority_of(&["EXTI1", "EXTI2", "EXTI3"]), Some(3));
    assert_eq!(priority_of(&["ADC1_2", "TIM8_BRK"]), Some(0));
    assert_eq!(priority_of(&["TIM5"]), Some(4));
    assert_eq!(priority_of(&["DefaultHandler", "USART1"]), None);
}
