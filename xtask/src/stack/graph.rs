//! The image as a call graph: its functions and their direct edges, the embassy tasks
//! (identified by the code that spawns them) and the roots the depths are taken from.

use std::collections::HashMap;

use super::decode::{scan, Func};
use super::elf::{Elf, Symbol, STT_FUNC, STT_OBJECT};
use super::names::demangle;
use super::{priority_of, DISPATCHERS, INTERRUPT_EXECUTOR, TASK_POLL};

/// The functions of the image and the direct edges between them.
pub struct Program {
    pub funcs: Vec<Func>,
    /// Function index by start address.
    pub start_of: HashMap<u32, usize>,
    /// Callees (calls and tail calls) of each function, sorted, without duplicates.
    pub edges: Vec<Vec<usize>>,
    /// Each function's frame, indexed like `funcs`.
    pub frame: Vec<u32>,
    /// Calls and branches whose target is in no function.
    pub unresolved_direct: usize,
    /// Whether the ELF has mapping symbols, i.e. literal pools were skipped.
    pub have_mapping: bool,
}

impl Program {
    /// Decodes every function with a size and links the direct calls and tail calls.
    pub fn load(elf: &Elf, symbols: &[Symbol]) -> Result<Self, String> {
        let (funcs, have_mapping) = decode_functions(elf, symbols)?;
        let start_of: HashMap<u32, usize> =
            funcs.iter().enumerate().map(|(i, f)| (f.addr, i)).collect();
        let (edges, unresolved_direct) = direct_edges(&funcs, &start_of);
        let frame = funcs.iter().map(|f| f.frame).collect();
        Ok(Program {
            funcs,
            start_of,
            edges,
            frame,
            unresolved_direct,
            have_mapping,
        })
    }

    /// Which functions the direct edges reach from `from` (included).
    pub fn reachable(&self, from: Vec<usize>) -> Vec<bool> {
        let mut seen = vec![false; self.funcs.len()];
        let mut todo = from;
        while let Some(f) = todo.pop() {
            if !std::mem::replace(&mut seen[f], true) {
                todo.extend(self.edges[f].iter().copied());
            }
        }
        seen
    }

    /// Whether `to` is reachable from `from` over direct edges.
    pub fn reaches(&self, from: usize, to: usize) -> bool {
        let mut seen = vec![false; self.funcs.len()];
        let mut todo = vec![from];
        while let Some(f) = todo.pop() {
            if f == to {
                return true;
            }
            if !std::mem::replace(&mut seen[f], true) {
                todo.extend(self.edges[f].iter().copied());
            }
        }
        false
    }
}

/// Every `STT_FUNC` symbol with a size, one per start address, scanned with the
/// mapping symbols' data regions skipped; whether there were mapping symbols.
fn decode_functions(elf: &Elf, symbols: &[Symbol]) -> Result<(Vec<Func>, bool), String> {
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

    // Functions, one per start address (the mangled name wins over an alias).
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
    Ok((funcs, have_mapping))
}

/// The edges of each function (BL targets, and branches that leave the function:
/// tail calls) and how many targets lie in no function.
fn direct_edges(funcs: &[Func], start_of: &HashMap<u32, usize>) -> (Vec<Vec<usize>>, usize) {
    let containing = |a: u32| -> Option<usize> {
        let i = funcs.partition_point(|f| f.addr <= a);
        (i > 0 && u64::from(a) < u64::from(funcs[i - 1].addr) + u64::from(funcs[i - 1].size))
            .then(|| i - 1)
    };
    let target = |t: u32| {
        start_of
            .get(&(t & !1))
            .copied()
            .or_else(|| containing(t & !1))
    };
    let mut edges: Vec<Vec<usize>> = vec![Vec::new(); funcs.len()];
    let mut unresolved_direct = 0usize;
    for (i, f) in funcs.iter().enumerate() {
        let leaving = f
            .branches
            .iter()
            .filter(|&&t| !(t >= f.addr && u64::from(t) < u64::from(f.addr) + u64::from(f.size)));
        for &t in f.calls.iter().chain(leaving) {
            match target(t) {
                Some(j) => edges[i].push(j),
                None => unresolved_direct += 1,
            }
        }
        edges[i].sort_unstable();
        edges[i].dedup();
    }
    (edges, unresolved_direct)
}

/// The embassy tasks: their poll functions and which task each one polls.
pub struct Tasks {
    /// The `TaskStorage<F>::poll` functions.
    pub polls: Vec<usize>,
    /// The task (short name of its `POOL`) of each identified poll function.
    pub task_of: HashMap<usize, String>,
    /// The functions that store each poll function's address (spawn code).
    pub spawned_by: HashMap<usize, Vec<usize>>,
    /// How many poll functions have no task.
    pub unidentified: usize,
    /// Polls the interrupt executor may call (its tasks, and the unidentified ones).
    pub cyclic_polls: Vec<usize>,
    /// Polls the thread executor may call (the other tasks, and the unidentified ones).
    pub thread_polls: Vec<usize>,
}

impl Tasks {
    /// Task poll functions, named by the task pool whose address is built just before
    /// the poll function's address (the spawn code stores the poll function pointer
    /// into that task's `POOL` storage).
    pub fn find(symbols: &[Symbol], prog: &Program) -> Self {
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
        let funcs = &prog.funcs;
        let polls: Vec<usize> = (0..funcs.len())
            .filter(|&i| funcs[i].name.starts_with(TASK_POLL))
            .collect();
        let mut task_of: HashMap<usize, String> = HashMap::new();
        let mut spawned_by: HashMap<usize, Vec<usize>> = HashMap::new();
        for (fi, f) in funcs.iter().enumerate() {
            let mut last_pool: Option<&str> = None;
            for &c in &f.constants {
                if let Some((_, _, t)) = pools.iter().find(|(a, s, _)| c >= *a && c < a + s) {
                    last_pool = Some(t);
                } else if let Some(&p) = prog.start_of.get(&(c & !1)) {
                    if c & 1 == 1 && polls.contains(&p) {
                        spawned_by.entry(p).or_default().push(fi);
                        if let Some(t) = last_pool {
                            task_of.entry(p).or_insert_with(|| t.to_string());
                        }
                    }
                }
            }
        }
        let cyclic_tasks = INTERRUPT_EXECUTOR.1;
        let unidentified = polls.iter().filter(|p| !task_of.contains_key(p)).count();
        // Unidentified polls are counted on both executors.
        let on = |cyclic: bool| -> Vec<usize> {
            polls
                .iter()
                .copied()
                .filter(|p| {
                    task_of
                        .get(p)
                        .is_none_or(|t| cyclic_tasks.contains(&t.as_str()) == cyclic)
                })
                .collect()
        };
        let (cyclic_polls, thread_polls) = (on(true), on(false));
        Tasks {
            polls,
            task_of,
            spawned_by,
            unidentified,
            cyclic_polls,
            thread_polls,
        }
    }

    /// Whether poll `p` is of a task declared on the interrupt executor.
    pub fn on_interrupt_executor(&self, p: usize) -> bool {
        self.task_of
            .get(&p)
            .is_some_and(|t| INTERRUPT_EXECUTOR.1.contains(&t.as_str()))
    }

    /// Function `i`'s name, with its task for a poll function.
    pub fn display(&self, funcs: &[Func], i: usize) -> String {
        match self.task_of.get(&i) {
            Some(t) => format!("{}[{t}]", funcs[i].name),
            None => funcs[i].name.clone(),
        }
    }
}

/// A starting point of the depth: a function with the indirect calls resolved for it.
pub struct Root {
    pub label: String,
    /// NVIC priority; `None` for thread mode.
    pub level: Option<i32>,
    pub func: usize,
    /// Dispatcher → the poll functions it calls in this context.
    pub extra: HashMap<usize, Vec<usize>>,
}

/// The roots of the analysis.
pub struct Roots {
    /// One per vector-table handler (the reset handler is thread mode).
    pub vectors: Vec<Root>,
    /// One per task: the executor's path to the dispatch + that task's poll.
    pub tasks: Vec<Root>,
    /// The vector-table function of the interrupt executor.
    pub irq_handler: Option<usize>,
    /// The thread executor's functions that call a task's poll.
    pub thread_dispatchers: Vec<usize>,
    /// The start-up task(s)' polls.
    pub startup: Vec<usize>,
    /// Vector-table entries that were not analysed.
    pub notes: Vec<String>,
}

fn extra_for(dispatchers: &[usize], targets: &[usize]) -> HashMap<usize, Vec<usize>> {
    dispatchers.iter().map(|&d| (d, targets.to_vec())).collect()
}

impl Roots {
    pub fn find(
        elf: &Elf,
        symbols: &[Symbol],
        prog: &Program,
        tasks: &Tasks,
    ) -> Result<Self, String> {
        let funcs = &prog.funcs;
        let thread_dispatchers: Vec<usize> = (0..funcs.len())
            .filter(|&i| DISPATCHERS.iter().any(|d| funcs[i].name.starts_with(d)))
            .collect();
        let mut roots = Roots {
            vectors: Vec::new(),
            tasks: Vec::new(),
            irq_handler: None,
            thread_dispatchers,
            startup: Vec::new(),
            notes: Vec::new(),
        };
        roots.add_vectors(elf, symbols, prog, tasks)?;
        let reset = roots
            .vectors
            .iter()
            .find(|r| r.level.is_none())
            .map(|r| r.func)
            .ok_or("no Reset handler in the vector table")?;
        check_interrupt_tasks(tasks)?;
        // The start-up task(s): spawned by code the reset handler reaches through direct
        // calls alone (the entry's `executor.run` closure), not by another task — found
        // from the code, whatever the task is called.
        let from_reset = prog.reachable(vec![reset]);
        roots.startup = tasks
            .polls
            .iter()
            .copied()
            .filter(|p| {
                tasks
                    .spawned_by
                    .get(p)
                    .is_some_and(|by| by.iter().any(|&f| from_reset[f]))
            })
            .collect();
        roots.add_tasks(prog, tasks, reset);
        Ok(roots)
    }

    /// Vector table: initial SP, then handlers; one root per distinct handler.
    fn add_vectors(
        &mut self,
        elf: &Elf,
        symbols: &[Symbol],
        prog: &Program,
        tasks: &Tasks,
    ) -> Result<(), String> {
        let irq_executor = INTERRUPT_EXECUTOR.0;
        let vt = elf
            .section(".vector_table")
            .ok_or("no .vector_table section")?;
        let vt_bytes = elf.data(vt)?;
        let mut handled: Vec<u32> = Vec::new();
        for (index, w) in vt_bytes.chunks_exact(4).enumerate().skip(1) {
            let v = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
            if v == 0 || handled.contains(&v) {
                continue;
            }
            handled.push(v);
            let Some(&f) = prog.start_of.get(&(v & !1)) else {
                self.notes.push(format!(
                    "vector {index} → {v:#010x}: no function there, not analysed"
                ));
                continue;
            };
            let names = names_at(symbols, v & !1);
            let named: Vec<String> = names.iter().map(|n| demangle(n)).collect();
            let is = |n: &str| named.iter().any(|m| m == n);
            let (level, label) = vector_label(index, &names, is("DefaultHandler"));
            let mut extra = HashMap::new();
            if level.is_none() {
                extra = extra_for(&self.thread_dispatchers, &tasks.thread_polls);
            } else if is(irq_executor) {
                self.irq_handler = Some(f);
                let mut d = self.thread_dispatchers.clone();
                d.push(f);
                extra = extra_for(&d, &tasks.cyclic_polls);
            }
            self.vectors.push(Root {
                label,
                level,
                func: f,
                extra,
            });
        }
        Ok(())
    }

    /// Per-task roots: the executor's path to the dispatch + that task's poll.
    fn add_tasks(&mut self, prog: &Program, tasks: &Tasks, reset: usize) {
        let irq_executor = INTERRUPT_EXECUTOR.0;
        for &p in &tasks.polls {
            let mut name = tasks
                .task_of
                .get(&p)
                .cloned()
                .unwrap_or_else(|| format!("{:#010x}", prog.funcs[p].addr));
            if self.startup.contains(&p) {
                name.push_str(", start-up");
            }
            match (tasks.on_interrupt_executor(p), self.irq_handler) {
                (true, Some(h)) => {
                    let mut d = self.thread_dispatchers.clone();
                    d.push(h);
                    self.tasks.push(Root {
                        label: format!("task {name} (interrupt executor {irq_executor})"),
                        level: Some(2),
                        func: h,
                        extra: extra_for(&d, &[p]),
                    });
                }
                _ => self.tasks.push(Root {
                    label: format!("task {name} (thread executor)"),
                    level: None,
                    func: reset,
                    extra: extra_for(&self.thread_dispatchers, &[p]),
                }),
            }
        }
    }
}

/// The (raw) names of the function at `addr`: its `STT_FUNC` symbols and untyped
/// aliases of its Thumb address.
fn names_at(symbols: &[Symbol], addr: u32) -> Vec<&str> {
    symbols
        .iter()
        .filter(|s| {
            s.value & !1 == addr && s.kind == STT_FUNC || (s.value == (addr | 1) && s.kind == 0)
        })
        .map(|s| s.name.as_str())
        .collect()
}

/// Priority level and label of vector `index` whose handler has these names.
fn vector_label(index: usize, names: &[&str], is_default: bool) -> (Option<i32>, String) {
    match index {
        1 => (None, "Reset (thread mode)".to_string()),
        2 => (Some(-2), "NMI".to_string()),
        3 => (Some(-1), "HardFault".to_string()),
        _ => {
            let p = priority_of(names);
            let mut label: Vec<&str> = names
                .iter()
                .copied()
                .filter(|n| priority_of(&[n]).is_some())
                .collect();
            if label.is_empty() {
                label = if is_default {
                    vec!["DefaultHandler"]
                } else {
                    names.to_vec()
                };
            }
            (Some(p.unwrap_or(0)), label.join("/"))
        }
    }
}

/// Every task the interrupt executor is said to run must exist: a renamed task would
/// otherwise be counted on the thread executor only (an image without tasks has
/// nothing to check).
fn check_interrupt_tasks(tasks: &Tasks) -> Result<(), String> {
    let (irq_executor, cyclic_tasks) = INTERRUPT_EXECUTOR;
    for t in cyclic_tasks.iter().filter(|_| !tasks.polls.is_empty()) {
        if !tasks.task_of.values().any(|n| n == t) {
            return Err(format!(
                "task `{t}` of the interrupt executor {irq_executor} not found (no `{t}::POOL` \
                 beside a task poll): update INTERRUPT_EXECUTOR in xtask/src/stack/mod.rs"
            ));
        }
    }
    Ok(())
}
