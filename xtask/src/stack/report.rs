//! Depths from the roots, the nesting of the priority levels, the coarse bound for the
//! unresolved indirect calls, and the printed report.

use std::collections::HashMap;
use std::fmt::Write as _;

use super::depth::{Depth, Solver};
use super::graph::{Program, Root, Roots, Tasks};
use super::{StackReport, EXCEPTION_FRAME, INTERRUPT_EXECUTOR};

type Edges = Vec<(usize, usize)>;

/// The depth of one root.
struct Evaluated {
    label: String,
    level: Option<i32>,
    depth: Depth,
    chain: Vec<usize>,
}

/// Everything the report is made of.
struct Analysis<'a> {
    prog: &'a Program,
    tasks: &'a Tasks,
    roots: &'a Roots,
    /// Per vector-table root, in the roots' order.
    levels: Vec<Evaluated>,
    /// Per task root, in the roots' order.
    per_task: Vec<Evaluated>,
    /// Functions no direct call reaches, deepest first, with their depth.
    orphans: Vec<(u64, usize)>,
    /// Worst case with every unresolved indirect call reaching every orphan.
    alt_worst: u64,
}

/// Thread + per priority level the deepest handler + one exception frame per level.
struct Nesting<'a> {
    thread: &'a Evaluated,
    worst: u64,
    /// The terms of `worst`, as printed.
    sum: String,
    /// Recursion through the panic handler (only ever on the way to the reset).
    panic_cycles: Edges,
    other_cycles: Edges,
}

/// Computes the depths and writes the report.
pub fn report(prog: &Program, tasks: &Tasks, roots: &Roots) -> Result<StackReport, String> {
    let mut cycles: Edges = Vec::new();
    let levels = evaluate(prog, &roots.vectors, &mut cycles);
    let per_task = evaluate(prog, &roots.tasks, &mut cycles);
    let orphans = orphans(prog, tasks, roots);
    let alt_worst = coarse_bound(prog, roots, &orphans);
    let a = Analysis {
        prog,
        tasks,
        roots,
        levels,
        per_task,
        orphans,
        alt_worst,
    };
    let nest = a.nesting(&cycles)?;
    let mut text = String::new();
    a.write_headline(&mut text, &nest);
    let on_chains = a.write_deepest(&mut text);
    a.write_caveats(&mut text, &nest, &on_chains);
    a.write_assumptions(&mut text);
    Ok(StackReport {
        worst: nest.worst,
        bounded: nest.other_cycles.is_empty(),
        with_indirect: a.alt_worst,
        text,
    })
}

/// Depth and deepest chain of each root; the back edges found are added to `cycles`.
fn evaluate(prog: &Program, roots: &[Root], cycles: &mut Edges) -> Vec<Evaluated> {
    roots
        .iter()
        .map(|r| {
            let mut s = Solver::new(&prog.frame, &prog.edges, r.extra.clone());
            let depth = s.depth(r.func);
            let chain = s.chain(r.func);
            for c in s.cycles {
                if !cycles.contains(&c) {
                    cycles.push(c);
                }
            }
            Evaluated {
                label: r.label.clone(),
                level: r.level,
                depth,
                chain,
            }
        })
        .collect()
}

/// What an unresolved indirect call could add: the functions no direct call reaches
/// (their address is taken somewhere) and their depth, deepest first.
fn orphans(prog: &Program, tasks: &Tasks, roots: &Roots) -> Vec<(u64, usize)> {
    let mut called = vec![false; prog.funcs.len()];
    for e in &prog.edges {
        for &c in e {
            called[c] = true;
        }
    }
    for r in &roots.vectors {
        called[r.func] = true;
    }
    for &p in &tasks.polls {
        called[p] = true;
    }
    let mut s0 = Solver::new(&prog.frame, &prog.edges, HashMap::new());
    let mut orphans: Vec<(u64, usize)> = (0..prog.funcs.len())
        .filter(|&f| !called[f])
        .map(|f| (s0.depth(f).bytes, f))
        .collect();
    orphans.sort_by_key(|&(d, _)| std::cmp::Reverse(d));
    orphans
}

/// The same nesting with every unresolved indirect call resolved to every orphan (a
/// coarse bound for what the indirect calls can add).
fn coarse_bound(prog: &Program, roots: &Roots, orphans: &[(u64, usize)]) -> u64 {
    let orphan_ids: Vec<usize> = orphans.iter().map(|&(_, f)| f).collect();
    let alt_depths: Vec<(Option<i32>, u64)> = roots
        .vectors
        .iter()
        .map(|r| {
            let mut extra = r.extra.clone();
            for (f, func) in prog.funcs.iter().enumerate() {
                if func.indirect > 0 && !extra.contains_key(&f) {
                    extra.insert(f, orphan_ids.clone());
                }
            }
            let mut s = Solver::new(&prog.frame, &prog.edges, extra);
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
    alt_worst
}

fn level_name(l: Option<i32>) -> String {
    match l {
        None => "thread".to_string(),
        Some(p) => format!("P{p}"),
    }
}

impl Analysis<'_> {
    fn display(&self, f: usize) -> String {
        self.tasks.display(&self.prog.funcs, f)
    }

    /// Thread + per priority level the deepest handler + one frame per level; the
    /// recursion split into that through the panic handler and the rest.
    fn nesting(&self, cycles: &Edges) -> Result<Nesting<'_>, String> {
        let thread = self
            .levels
            .iter()
            .find(|r| r.level.is_none())
            .ok_or("no thread root")?;
        let mut levels: Vec<i32> = self.levels.iter().filter_map(|r| r.level).collect();
        levels.sort_unstable();
        levels.dedup();
        levels.reverse(); // least urgent first
        let funcs = &self.prog.funcs;
        let panic_handler = (0..funcs.len()).find(|&i| {
            funcs[i].name == "__rustc::rust_begin_unwind" || funcs[i].name == "rust_begin_unwind"
        });
        let (panic_cycles, other_cycles): (Edges, Edges) = cycles.iter().partition(|&&(a, b)| {
            panic_handler.is_some_and(|p| self.prog.reaches(b, p) && self.prog.reaches(p, a))
        });
        let mut worst = thread.depth.bytes;
        let mut sum = format!("thread {}", thread.depth.bytes);
        for &l in &levels {
            let Some(top) = self
                .levels
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
        Ok(Nesting {
            thread,
            worst,
            sum,
            panic_cycles,
            other_cycles,
        })
    }

    /// The worst case, and the figure once the start-up is done.
    fn write_headline(&self, text: &mut String, nest: &Nesting) {
        let _ = writeln!(
            text,
            "  stack (static analysis of the ELF): worst case {} B{} = {}",
            nest.worst,
            if nest.other_cycles.is_empty() {
                ""
            } else {
                " + RECURSION (unbounded)"
            },
            nest.sum
        );
        // For information: once the start-up (`main` task) has finished, the thread level
        // is the deepest other thread task. The figure above keeps the start-up, since the
        // interrupts already run during it.
        let startup = &self.roots.startup;
        if let Some(steady) = self
            .per_task
            .iter()
            .zip(&self.roots.tasks)
            .filter(|(r, root)| {
                r.level.is_none() && !root.extra.values().flatten().any(|p| startup.contains(p))
            })
            .map(|(r, _)| r)
            .max_by_key(|r| r.depth.bytes)
        {
            if steady.depth.bytes < nest.thread.depth.bytes {
                let _ = writeln!(
                    text,
                    "  after start-up (the main task done; thread = {} {} B): {} B",
                    steady.label,
                    steady.depth.bytes,
                    nest.worst - nest.thread.depth.bytes + steady.depth.bytes
                );
            }
        }
    }

    /// The ten deepest roots (the handlers and the per-task paths) with their chains;
    /// returns the functions on those chains.
    fn write_deepest(&self, text: &mut String) -> Vec<usize> {
        let mut all: Vec<&Evaluated> = self.levels.iter().chain(self.per_task.iter()).collect();
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
                .map(|&f| format!("{} ({})", self.display(f), self.prog.frame[f]))
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
        on_chains
    }

    /// Indirect calls not followed, orphans, dynamic SP, recursion.
    fn write_caveats(&self, text: &mut String, nest: &Nesting, on_chains: &[usize]) {
        let funcs = &self.prog.funcs;
        let mut dispatch_all = self.roots.thread_dispatchers.clone();
        dispatch_all.extend(self.roots.irq_handler);
        let indirect: Vec<String> = on_chains
            .iter()
            .filter(|&&f| funcs[f].indirect > 0 && !dispatch_all.contains(&f))
            .map(|&f| format!("{} ({})", self.display(f), funcs[f].indirect))
            .collect();
        if !indirect.is_empty() {
            let _ = writeln!(
                text,
                "  caveat: indirect calls not followed (BLX/BX register; count) in functions on these chains: {}",
                indirect.join(", ")
            );
        }
        // Indirect calls anywhere else the roots reach (the task polls included).
        let from: Vec<usize> = self
            .roots
            .vectors
            .iter()
            .map(|r| r.func)
            .chain(self.tasks.polls.iter().copied())
            .collect();
        let seen = self.prog.reachable(from);
        let elsewhere: Vec<String> = (0..funcs.len())
            .filter(|&f| {
                seen[f]
                    && funcs[f].indirect > 0
                    && !dispatch_all.contains(&f)
                    && !on_chains.contains(&f)
            })
            .map(|f| format!("{} ({})", self.display(f), funcs[f].indirect))
            .collect();
        if !elsewhere.is_empty() {
            let _ = writeln!(
                text,
                "  caveat: other reachable functions with indirect calls not followed: {}",
                elsewhere.join(", ")
            );
        }
        self.write_orphans(text);
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
        for (a, b) in &nest.other_cycles {
            let _ = writeln!(
                text,
                "  RECURSION: {} → {} (counted once)",
                self.display(*a),
                self.display(*b)
            );
        }
        if !nest.panic_cycles.is_empty() {
            let list: Vec<String> = nest
                .panic_cycles
                .iter()
                .map(|&(a, b)| format!("{} → {}", self.display(a), self.display(b)))
                .collect();
            let _ = writeln!(
                text,
                "  caveat: recursion through the panic handler, counted once (a panic inside the panic's own log line re-enters the handler once; the firmware logs only the first panic, hw::safety PANICKED): {}",
                list.join("; ")
            );
        }
    }

    /// The functions no direct call reaches and the coarse bound.
    fn write_orphans(&self, text: &mut String) {
        if self.orphans.is_empty() {
            return;
        }
        let top: Vec<String> = self
            .orphans
            .iter()
            .take(5)
            .map(|&(d, f)| format!("{} {d} B", self.display(f)))
            .collect();
        let _ = writeln!(
            text,
            "  caveat: {} functions are reached by no direct call (indirect-call targets, not counted above); deepest: {}; with every unresolved indirect call assumed to reach each of them: worst case {} B",
            self.orphans.len(),
            top.join(", "),
            self.alt_worst
        );
    }

    /// What the figures assume, then the notes.
    fn write_assumptions(&self, text: &mut String) {
        let (irq_executor, cyclic_tasks) = INTERRUPT_EXECUTOR;
        let polls = self.tasks.polls.len();
        let unresolved_direct = self.prog.unresolved_direct;
        let _ = writeln!(
            text,
            "  assumptions: tasks on the interrupt executor {irq_executor}: {}; every other task on the thread executor; task polls identified by their POOL: {}/{}{}; exception frame {EXCEPTION_FRAME} B per nesting level (FPU context); {}{}",
            cyclic_tasks.join(", "),
            polls - self.tasks.unidentified,
            polls,
            if self.tasks.unidentified == 0 {
                String::new()
            } else {
                " (the others counted on both executors)".to_string()
            },
            if self.prog.have_mapping {
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
        for n in &self.roots.notes {
            let _ = writeln!(text, "  note: {n}");
        }
    }
}
