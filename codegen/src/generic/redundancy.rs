//! The one rule that names redundant equations, shared by `check`, the generic engine and the
//! symbolic layer (the generated engine).
//!
//! The rule: at a configuration, Φ_q is seen in balanced units (translational columns times
//! the mechanism's characteristic length, [`super::scaling`]) and its rows are taken in this
//! order: the Euler-parameter normalisations first, then joints, constraints and drivers in
//! the order of the description. A row is redundant when it depends on the rows taken before
//! it: what is left of it after elimination by them is below [`REDUNDANT_ROW_TOLERANCE`] of
//! its largest entry. So a dependency is blamed on the joint, constraint or driver row that
//! closes it, the last one written, and never on a normalisation, which holds by construction.
//!
//! The generic engine does not leave the redundant rows out: it solves with every row at
//! every step ([`super::Analysis`]) and names the redundant ones by this rule at the initial
//! configuration and wherever the set changes along the motion. The symbolic layer eliminates
//! the coordinates that `fix` constraints, coordinate differences against a ground body and
//! absolute x, y, z drivers set, and leaves out the rows of its reduced system that depend on
//! the others; it names the redundant equations by this rule on the whole Φ_q all the same,
//! so that the three agree (when a named row is one of the eliminated ones, the reduced system
//! leaves out the row that this one makes dependent instead).

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::DVector;

use super::Equations;

/// A row whose part outside the span of the rows kept before it is below this fraction of its
/// largest entry depends on them: an exact dependency leaves round-off (≈1e-16 relative, times
/// the elimination's small growth), a genuine but poorly conditioned row far more.
pub const REDUNDANT_ROW_TOLERANCE: f64 = 1e-8;

/// The rows of a sparse matrix with `n` columns (rows of `(column, value)`) that do not
/// depend on the rows taken before them: the rows marked in `first` (the normalisations)
/// before all others, each group in row order (the rule of the module docs). Each row is
/// reduced by the rows kept so far (row echelon form, each kept row pivoting on its largest
/// remaining entry) and kept when something is left. The test is relative to each row's
/// largest entry, so only the columns' units matter: pass Φ_q with balanced columns. In exact
/// arithmetic the set is that of Gram–Schmidt in the same order, at the cost of the sparse
/// elimination only.
#[must_use]
pub fn independent(rows: &[Vec<(usize, f64)>], n: usize, first: &[bool]) -> BTreeSet<usize> {
    // Kept rows in echelon form: (pivot column, entries by column).
    let mut basis: Vec<(usize, BTreeMap<usize, f64>)> = Vec::new();
    let mut pivot_of = vec![None; n];
    let mut kept = BTreeSet::new();
    let is_first = |k: usize| first.get(k).copied().unwrap_or(false);
    let order =
        (0..rows.len()).filter(|&k| is_first(k)).chain((0..rows.len()).filter(|&k| !is_first(k)));
    for k in order {
        let row = &rows[k];
        let scale = row.iter().fold(0.0_f64, |m, &(_, x)| m.max(x.abs()));
        let mut w: BTreeMap<usize, f64> = row.iter().copied().collect();
        // Reduce by the kept rows in the order they were kept: row b has no entry in the
        // pivot columns of the rows kept before it, so each elimination is final.
        let mut pending: BTreeSet<usize> = w.keys().filter_map(|&c| pivot_of[c]).collect();
        while let Some(b) = pending.pop_first() {
            let (pc, p) = &basis[b];
            let Some(x) = w.remove(pc) else { continue };
            if x == 0.0 {
                continue;
            }
            let l = x / p[pc];
            for (&c, &y) in p.iter().filter(|&(c, _)| c != pc) {
                *w.entry(c).or_insert(0.0) -= l * y;
                if let Some(o) = pivot_of[c] {
                    pending.insert(o);
                }
            }
        }
        let (pc, big) = w.iter().fold((usize::MAX, 0.0_f64), |(bc, bv), (&c, &x)| {
            if x.abs() > bv { (c, x.abs()) } else { (bc, bv) }
        });
        if scale > 0.0 && big > REDUNDANT_ROW_TOLERANCE * scale {
            w.retain(|_, x| *x != 0.0);
            pivot_of[pc] = Some(basis.len());
            basis.push((pc, w));
            kept.insert(k);
        }
    }
    kept
}

impl Equations<'_> {
    /// The rows named redundant at `(q, t)` by the rule of the module docs, in row order.
    #[must_use]
    pub fn redundant_rows(&self, q: &DVector<f64>, t: f64) -> Vec<usize> {
        let columns = self.column_scales();
        let mut rows = self.jacobian_rows(q, t);
        for row in &mut rows {
            for (c, x) in row.iter_mut() {
                *x *= columns[*c];
            }
        }
        let first: Vec<bool> = self.labels().iter().map(|l| l.is_normalisation()).collect();
        let kept = independent(&rows, self.unknowns(), &first);
        (0..rows.len()).filter(|k| !kept.contains(k)).collect()
    }
}
