//! The block-lower-triangular form of the reduced system Φ(q, t) = 0, from the structure of Φ_q.
//!
//! A square system whose Jacobian has a perfect structural matching (every equation paired with
//! a distinct unknown it depends on) can be permuted, rows and columns, to block-lower-triangular
//! form: the equations of block b depend only on the unknowns of blocks 1 … b, so the blocks are
//! solved one after the other, each for its own unknowns with the earlier ones known. This is
//! the decomposition equation-based code generators (Modelica compilers) use:
//!
//! 1. a maximum matching of equations to unknowns on the structural non-zeros of Φ_q
//!    (Hopcroft–Karp, O(E √V));
//! 2. the dependency graph on unknowns, k → j when the equation matched to k involves q_j;
//! 3. its strongly connected components (Tarjan), which Tarjan's algorithm emits with every
//!    component after the components it depends on: that is the solve order.
//!
//! The blocks (their sets of equations and unknowns) do not depend on which perfect matching is
//! found, so they are a property of the system's structure. A block of one equation affine in
//! its unknown (∂Φ_r/∂q_k free of q_k, for instance a body's x held by a joint to a known point)
//! is solved in closed form, q_k ← q_k − Φ_r / (∂Φ_r/∂q_k); every other block needs Newton on
//! its own unknowns, except one: the normalisation pᵀp − 1 of a body couples its four Euler
//! parameters, so a body whose orientation is set by a driven rotation about a revolute's axis
//! to a known body is a block of four (two axis rows, the driver and the normalisation), and
//! that block has a closed form too, p_j = p_k ⊗ f_k ⊗ (cos θ/2, sin θ/2 · z) ⊗ f_j* with θ
//! from the driver's row ([`rotation`]), which Newton block by block runs as straight-line code.

use std::collections::BTreeMap;

use crate::model::Mechanism;
use crate::symbolic::Symbolic;

pub mod outputs;
pub mod rotation;

pub use rotation::Rotation;

/// How a block is solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// One equation affine in its one unknown (for example the x row of a revolute joint's
    /// coincident point, `x_j + (A_j s'_j)_x − (x_i + (A_i s'_i)_x) = 0`, with body i known):
    /// straight-line code, q_k ← q_k − Φ_r / (∂Φ_r/∂q_k).
    ClosedForm,
    /// A body's four Euler parameters turned by a driven rotation about a joint axis to a
    /// known body (a link of a driven chain, the R-S-S-R's crank): straight-line code too
    /// ([`Rotation`]).
    Rotation(Rotation),
    /// Newton on the block's unknowns (a closed loop).
    Implicit,
}

impl Kind {
    /// Whether the block is solved without iteration.
    #[must_use]
    pub fn is_closed_form(self) -> bool {
        !matches!(self, Kind::Implicit)
    }
}

/// One diagonal block: equations solved together for their unknowns once every earlier block
/// is known.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Block {
    /// The block's equations: indices into [`Symbolic::rows`], increasing.
    pub rows: Vec<usize>,
    /// The block's unknowns: indices into [`Symbolic::unknowns`], increasing, as many as rows.
    pub unknowns: Vec<usize>,
    /// How the block is solved.
    pub kind: Kind,
}

/// The block-lower-triangular form of a reduced system.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Blocks {
    /// The blocks in solve order: the equations of a block involve only its own unknowns and
    /// those of the blocks before it.
    pub blocks: Vec<Block>,
}

/// A structure with no perfect matching: some equations compete for too few unknowns.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "the Jacobian's structure pairs only {matched} of {rows} equations with distinct unknowns \
     ({unknowns} unknowns)"
)]
pub struct StructurallySingular {
    /// The number of equations.
    pub rows: usize,
    /// The number of unknowns.
    pub unknowns: usize,
    /// The size of a maximum matching.
    pub matched: usize,
}

impl Blocks {
    /// The blocks of a reduced system, classified (the rotation blocks recognised against
    /// the mechanism the system was built from).
    ///
    /// # Panics
    /// Never for a system [`Symbolic::build`] returned: it is square with full numeric rank at
    /// the initial configuration, and a non-zero determinant has a non-zero term, that is a
    /// perfect matching on the structural non-zeros.
    #[must_use]
    pub fn of(sys: &Symbolic, mech: &Mechanism) -> Self {
        let pattern: Vec<Vec<usize>> =
            sys.jac.iter().map(|row| row.iter().map(|&(c, _)| c).collect()).collect();
        let parts = triangular(&pattern, sys.unknowns.len())
            .expect("a system of full rank has a perfect structural matching");
        let blocks = parts
            .into_iter()
            .map(|(rows, unknowns)| {
                let kind = if let ([r], [k]) = (rows.as_slice(), unknowns.as_slice()) {
                    let entry = sys.jac[*r].iter().find(|&&(c, _)| c == *k).map(|&(_, e)| e);
                    let affine = entry.is_some_and(|e| {
                        !sys.pool
                            .depends_on(e, crate::expr::Var::Q(u32::try_from(*k).expect("small")))
                    });
                    if affine { Kind::ClosedForm } else { Kind::Implicit }
                } else {
                    rotation::recognise(sys, mech, &rows, &unknowns)
                        .map_or(Kind::Implicit, Kind::Rotation)
                };
                Block { rows, unknowns, kind }
            })
            .collect();
        Self { blocks }
    }

    /// The number of blocks solved in closed form (affine ones and rotations).
    #[must_use]
    pub fn closed_form(&self) -> usize {
        self.blocks.iter().filter(|b| b.kind.is_closed_form()).count()
    }

    /// The number of rotation blocks among them.
    #[must_use]
    pub fn rotations(&self) -> usize {
        self.blocks.iter().filter(|b| matches!(b.kind, Kind::Rotation(_))).count()
    }

    /// The size of the largest block that needs Newton, 0 when there is none.
    #[must_use]
    pub fn largest_implicit(&self) -> usize {
        self.blocks
            .iter()
            .filter(|b| b.kind == Kind::Implicit)
            .map(|b| b.unknowns.len())
            .max()
            .unwrap_or(0)
    }

    /// How many blocks there are of each size, by increasing size.
    #[must_use]
    pub fn sizes(&self) -> BTreeMap<usize, usize> {
        let mut sizes = BTreeMap::new();
        for b in &self.blocks {
            *sizes.entry(b.unknowns.len()).or_insert(0) += 1;
        }
        sizes
    }
}

/// A diagonal block of a bare structure: its rows and its columns.
pub type Part = (Vec<usize>, Vec<usize>);

/// The irreducible diagonal blocks `(rows, columns)` of a square sparse structure (`pattern[r]`
/// lists the columns, below `n`, of row r's structural non-zeros), each sorted increasingly, in
/// an order that makes the permuted matrix block-lower-triangular.
///
/// # Errors
/// When the structure is not square or has no perfect matching.
pub fn triangular(pattern: &[Vec<usize>], n: usize) -> Result<Vec<Part>, StructurallySingular> {
    let row_of_column = matching(pattern, n);
    let matched = row_of_column.iter().flatten().count();
    if pattern.len() != n || matched != n {
        return Err(StructurallySingular { rows: pattern.len(), unknowns: n, matched });
    }
    let row_of_column: Vec<usize> = row_of_column.into_iter().flatten().collect();
    // Unknown k depends on the other unknowns of the row matched to it.
    let successors: Vec<&[usize]> = row_of_column.iter().map(|&r| pattern[r].as_slice()).collect();
    Ok(strong_components(&successors)
        .into_iter()
        .map(|mut columns| {
            columns.sort_unstable();
            let mut rows: Vec<usize> = columns.iter().map(|&c| row_of_column[c]).collect();
            rows.sort_unstable();
            (rows, columns)
        })
        .collect())
}

/// A maximum matching of rows to columns on a sparse structure (Hopcroft–Karp): for every
/// column below `n`, the row matched to it, if any. Every matched pair is a structural non-zero.
#[must_use]
pub fn matching(pattern: &[Vec<usize>], n: usize) -> Vec<Option<usize>> {
    const FAR: usize = usize::MAX;
    let m = pattern.len();
    let mut row_of = vec![None::<usize>; n];
    let mut column_of = vec![None::<usize>; m];
    // Greedy start: most rows of a mechanism's Jacobian find a free column at once.
    for (r, columns) in pattern.iter().enumerate() {
        if let Some(&c) = columns.iter().find(|&&c| c < n && row_of[c].is_none()) {
            row_of[c] = Some(r);
            column_of[r] = Some(c);
        }
    }
    let mut layer = vec![FAR; m];
    let mut next = vec![0usize; m];
    loop {
        // Breadth-first: the layers of alternating paths from the free rows.
        let mut queue: std::collections::VecDeque<usize> =
            (0..m).filter(|&r| column_of[r].is_none()).collect();
        for r in 0..m {
            layer[r] = if column_of[r].is_none() { 0 } else { FAR };
        }
        let mut reaches_free = false;
        while let Some(r) = queue.pop_front() {
            for &c in pattern[r].iter().filter(|&&c| c < n) {
                match row_of[c] {
                    None => reaches_free = true,
                    Some(s) if layer[s] == FAR => {
                        layer[s] = layer[r] + 1;
                        queue.push_back(s);
                    }
                    Some(_) => {}
                }
            }
        }
        if !reaches_free {
            return row_of;
        }
        // Depth-first along the layers from every free row, without recursion: `path` holds
        // the rows of the current alternating path, each at its current column `next[r]`.
        next.fill(0);
        for root in 0..m {
            if column_of[root].is_some() {
                continue;
            }
            let mut path = vec![root];
            while let Some(&r) = path.last() {
                let Some(&c) = pattern[r].get(next[r]) else {
                    // A dead end for this phase.
                    layer[r] = FAR;
                    path.pop();
                    if let Some(&p) = path.last() {
                        next[p] += 1;
                    }
                    continue;
                };
                match (c < n).then(|| row_of[c]) {
                    Some(None) => {
                        // A free column: flip the path.
                        for &s in &path {
                            let c = pattern[s][next[s]];
                            row_of[c] = Some(s);
                            column_of[s] = Some(c);
                        }
                        break;
                    }
                    Some(Some(s)) if layer[s] == layer[r] + 1 => path.push(s),
                    _ => next[r] += 1,
                }
            }
        }
    }
}

/// The strongly connected components of a directed graph (`successors[v]`; entries `v` itself
/// are ignored), by Tarjan's algorithm without recursion. A component comes after every
/// component it reaches.
fn strong_components(successors: &[&[usize]]) -> Vec<Vec<usize>> {
    const NONE: usize = usize::MAX;
    let n = successors.len();
    let mut index = vec![NONE; n];
    let mut low = vec![0usize; n];
    let mut on_stack = vec![false; n];
    let mut stack = Vec::new();
    let mut components = Vec::new();
    let mut count = 0;
    for start in 0..n {
        if index[start] != NONE {
            continue;
        }
        // The call stack: (vertex, position of its next successor).
        let mut calls = vec![(start, 0usize)];
        index[start] = count;
        low[start] = count;
        count += 1;
        stack.push(start);
        on_stack[start] = true;
        while let Some(top) = calls.last_mut() {
            let v = top.0;
            if let Some(&w) = successors[v].get(top.1) {
                top.1 += 1;
                if index[w] == NONE {
                    index[w] = count;
                    low[w] = count;
                    count += 1;
                    stack.push(w);
                    on_stack[w] = true;
                    calls.push((w, 0));
                } else if on_stack[w] {
                    low[v] = low[v].min(index[w]);
                }
                continue;
            }
            calls.pop();
            if let Some(&(u, _)) = calls.last() {
                low[u] = low[u].min(low[v]);
            }
            if low[v] == index[v] {
                let mut component = Vec::new();
                loop {
                    let w = stack.pop().expect("v is on the stack");
                    on_stack[w] = false;
                    component.push(w);
                    if w == v {
                        break;
                    }
                }
                components.push(component);
            }
        }
    }
    components
}

#[cfg(test)]
mod tests;
