//! Depth over the call graph: memoised DFS, recursion found as back edges.

use std::collections::HashMap;

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
