//! The block-by-block LU: the layout of Φ_q's block-lower-triangular form
//! ([`crate::blocks`]) as a `static`, the function that evaluates Φ and Φ_q for it, straight-line
//! `factor_blocks_k` and `solve_blocks_k` functions (each diagonal block gathered into a
//! fixed-size array and factored by `runtime::lu` with partial pivoting inside the block, the
//! entries below the blocks moved to the right-hand side), and the `runtime::Mechanism` items
//! that select them instead of static pivot orders.
//!
//! With Newton block by block, each block factored alone (implicit and rotation blocks) first
//! tries static pivot orders of its own (`pivot::plan_blocks`, printed by
//! [`super::lu::block`]): the first whose guard passes and whose pivot ratio exceeds
//! `runtime::step::structured_bound` stores its factors and flags itself in `perm` at the
//! block's first position (the block's size plus the order's number, where the dense LU
//! writes a row within the block); otherwise the block's dense LU decides, as before. The
//! solves read the flag.

use syn::parse_quote;

use super::Rows;
use super::function::Signature;
use super::shared::{Array, Gathers, Output, Sharing, Slice};
use super::syntax::{ident, index};
use crate::blocks::{Blocks, Kind};
use crate::model::Mechanism;
use crate::pivot::Order;
use crate::symbolic::Symbolic;

/// A system of at least this many unknowns is factored block by block when it has more than one
/// block: below it the static pivot orders' straight-line code is faster than the runtime's
/// loops over index tables (the R-S-S-R, 20 unknowns: see BENCHMARKS.md).
pub(super) const MIN_UNKNOWNS: usize = 64;

/// Blocks larger than this keep the static pivot orders: each block is factored in a
/// `[[f64; s]; s]` on the stack, and a large block gains nothing from the decomposition.
pub(super) const MAX_BLOCK: usize = 32;

/// Entries (gathered, scattered or moved to the right-hand side) per emitted `factor_blocks_k`
/// or `solve_blocks_k`, which keeps every function small enough to compile fast (as
/// [`super::CHUNK_OPS`] does for the equations).
const CHUNK_ENTRIES: usize = 800;

/// How a solver uses the block-lower-triangular form of Φ_q.
pub(super) struct Plan {
    /// The blocks.
    pub(super) blocks: Blocks,
    /// Whether Newton runs block by block (`runtime::Mechanism::BLOCK_NEWTON`), each block on
    /// its own unknowns; else one Newton iteration over the whole system factors Φ_q block by
    /// block. Block by block needs a square system with no row left out as redundant (the
    /// dropped rows' checks and their re-selection at run time belong to the whole system).
    pub(super) newton: bool,
    /// With Newton block by block, the rotation blocks it solves in closed form.
    pub(super) rotations: Vec<Closed>,
    /// The static orders of the diagonal blocks.
    pub(super) orders: Orders,
    /// With Newton block by block, the blocks whose `block_b`, `block_residual_b` and
    /// `rotation_b` are one function per structure ([`super::shared`]).
    pub(super) shared: Shared,
}

/// Per block, the static pivot orders of its diagonal block in block coordinates (rows and
/// columns counted within the block), tried in turn before its dense LU: empty for the affine
/// blocks, without Newton block by block, and where planning found none.
pub(super) type Orders = Vec<Vec<Order>>;

/// The block functions grouped by structure, per kind of function.
pub(super) struct Shared {
    /// Whether `residual`, `velocity_rhs` and `acceleration_rhs` call functions per block
    /// ([`vectors`]): when some of those are shared.
    pub(super) vectors: bool,
    /// `block_b`: Φ and Φ_q of the block's rows.
    pub(super) both: Sharing,
    /// `block_residual_b`: Φ of the block's rows.
    pub(super) alone: Sharing,
    /// The runs of blocks Φ, ν and γ go by with [`Shared::vectors`]: an implicit or rotation
    /// block and the affine blocks after it.
    pub(super) runs: Vec<Vec<usize>>,
    /// `rows_residual_k`: Φ of the rows of run k (`residual` calls them all).
    pub(super) phi: Sharing,
    /// `rows_velocity_k`: ν of the rows of run k (`velocity_rhs` calls them all).
    pub(super) nu: Sharing,
    /// `rows_acceleration_k`: γ of the rows of run k (`acceleration_rhs` calls them all).
    pub(super) gamma: Sharing,
    /// `rotation_b`: a rotation block's coefficients.
    pub(super) rotations: Sharing,
    /// The arms of `factor_block_k` (Newton's factors of one block).
    pub(super) factor: Gathers,
    /// The arms of `solve_block_k`.
    pub(super) solve: Gathers,
    /// The blocks of two or more rows in `factor_blocks_k` (all blocks' factors at once).
    pub(super) factor_all: Gathers,
    /// The blocks of two or more rows in `solve_blocks_k`.
    pub(super) solve_all: Gathers,
}

/// The code of a block's LU with its indices as holes ([`Gathers`]): what the
/// `factor_block_k`, `solve_block_k`, `factor_blocks_k` and `solve_blocks_k` of shared
/// blocks run, the entries of Φ_q flat (in the packed storage).
struct Lu<'a> {
    sys: &'a Symbolic,
    blocks: &'a Blocks,
    orders: &'a [Vec<Order>],
    entries: &'a Entries,
    /// Where each block's rows start in the blocks' order (`perm`).
    starts: Vec<usize>,
    lower_starts: &'a [usize],
    lower: &'a [usize],
}

/// The arrays of [`Lu::factor`]: `jac` (0) and `perm` (1).
const FACTOR_SLICES: [Slice; 2] = [
    Slice { name: "jac", square: true, mutable: true },
    Slice { name: "perm", square: false, mutable: true },
];

/// The arrays of [`Lu::solve_one`]: `lu` (0), `perm` (1), `rhs` (2).
const SOLVE_ONE_SLICES: [Slice; 3] = [
    Slice { name: "lu", square: true, mutable: false },
    Slice { name: "perm", square: false, mutable: false },
    Slice { name: "rhs", square: false, mutable: false },
];

/// The arrays of [`Lu::solve_all`]: [`SOLVE_ONE_SLICES`] and `x` (3).
const SOLVE_ALL_SLICES: [Slice; 4] = [
    Slice { name: "lu", square: true, mutable: false },
    Slice { name: "perm", square: false, mutable: false },
    Slice { name: "rhs", square: false, mutable: false },
    Slice { name: "x", square: false, mutable: true },
];

type Hole<'h> = &'h mut dyn FnMut(usize, usize) -> syn::Expr;

/// Entry (i, j) of a diagonal block, in block coordinates.
type Place<'h> = &'h mut dyn FnMut(usize, usize) -> syn::Expr;

impl<'a> Lu<'a> {
    fn new(
        sys: &'a Symbolic,
        blocks: &'a Blocks,
        orders: &'a [Vec<Order>],
        entries: &'a Entries,
        lower_starts: &'a [usize],
        lower: &'a [usize],
    ) -> Self {
        let mut starts = Vec::with_capacity(blocks.blocks.len());
        let mut at = 0;
        for block in &blocks.blocks {
            starts.push(at);
            at += block.rows.len();
        }
        Lu { sys, blocks, orders, entries, starts, lower_starts, lower }
    }

    /// Static order `k` of block `b` ([`super::lu::block`]): its factorisation at the places
    /// `hole` gives in array 0 (`jac`) unless `solving`, else its solve with the factors read
    /// there (`lu`), the right-hand side by row from `input`, the solution by the block's
    /// column written by `output`; a refused guard leaves the labelled block `'order_k`.
    fn order(
        &self,
        b: usize,
        k: usize,
        solving: bool,
        hole: Hole<'_>,
        input: &mut dyn FnMut(usize) -> syn::Expr,
        output: &mut dyn FnMut(usize, syn::Expr) -> syn::Stmt,
    ) -> super::lu::BlockOrder {
        let block = &self.blocks.blocks[b];
        let (structure, constant) =
            crate::pivot::block_structure(self.sys, &block.rows, &block.unknowns);
        let entries = self.entries;
        let mut place =
            |i: usize, j: usize| hole(0, entries.flat(block.rows[i], block.unknowns[j]));
        // The half not asked for is built without holes and dropped.
        let mut unused = |_: usize, _: usize| -> syn::Expr { parse_quote!(unused) };
        let (jac, lu): (Place<'_>, Place<'_>) =
            if solving { (&mut unused, &mut place) } else { (&mut place, &mut unused) };
        let label = syn::Lifetime::new(&format!("'order_{k}"), proc_macro2::Span::call_site());
        super::lu::block(
            &self.orders[b][k],
            &structure,
            &constant,
            super::lu::BlockPlaces { jac, lu, input, output, fail: parse_quote!(break #label;) },
        )
    }

    /// The diagonal block gathered from array `a` (structural zeros as literals when
    /// `zeros`).
    fn gather(
        &self,
        b: usize,
        a: usize,
        zeros: bool,
        hole: Hole<'_>,
    ) -> Vec<proc_macro2::TokenStream> {
        let block = &self.blocks.blocks[b];
        block
            .rows
            .iter()
            .map(|&r| {
                let row: Vec<_> = block
                    .unknowns
                    .iter()
                    .map(|&c| {
                        if !zeros || self.sys.jac[r].iter().any(|&(j, _)| j == c) {
                            let e = hole(a, self.entries.flat(r, c));
                            quote::quote!(#e)
                        } else {
                            quote::quote!(0.0)
                        }
                    })
                    .collect();
                quote::quote!([#(#row),*])
            })
            .collect()
    }

    /// The flag in `perm` at block b's first position that says its static order `k` holds
    /// its factors: the block's size plus k, where the dense LU writes a row within the block.
    fn mark(&self, b: usize, k: usize) -> syn::Expr {
        let mark = index(self.blocks.blocks[b].rows.len() + k);
        parse_quote!(#mark)
    }

    /// Factors block b in place, its row order into `perm`: `factor_with_ratio`'s result
    /// (`?` on its error when `ratio`, else `.ok()?`). With `ratio` (Newton's factors of one
    /// block), the block's static orders are tried first: the first whose guard passes and
    /// whose pivot ratio exceeds `runtime::step::structured_bound(ratio)` stores its factors,
    /// writes its flag ([`Lu::mark`]) and returns; else the dense LU decides.
    fn factor(&self, b: usize, ratio: bool, hole: Hole<'_>) -> proc_macro2::TokenStream {
        let block = &self.blocks.blocks[b];
        let s = index(block.rows.len());
        let mut tried = Vec::new();
        for k in (0..self.orders[b].len()).filter(|_| ratio) {
            let mut input = |_: usize| -> syn::Expr { parse_quote!(unused) };
            let mut output = |_: usize, _: syn::Expr| -> syn::Stmt { parse_quote!(unused;) };
            let code = self.order(b, k, false, hole, &mut input, &mut output);
            let (factor, stores, extremes) = (code.factor, code.stores, code.extremes);
            let (flag, mark) = (hole(1, self.starts[b]), self.mark(b, k));
            let label = syn::Lifetime::new(&format!("'order_{k}"), proc_macro2::Span::call_site());
            tried.push(quote::quote! {
                #label: {
                    #(#factor)*
                    let info = #extremes;
                    if info.smallest <= runtime::step::structured_bound(ratio) * info.largest {
                        break #label;
                    }
                    #(#stores)*
                    #flag = #mark;
                    return Ok(info);
                }
            });
        }
        let rows = self.gather(b, 0, true, hole);
        let mut scatter = Vec::new();
        for (i, &r) in block.rows.iter().enumerate() {
            for (j, &c) in block.unknowns.iter().enumerate() {
                let (e, i, j) = (hole(0, self.entries.flat(r, c)), index(i), index(j));
                scatter.push(quote::quote!(#e = a[#i][#j];));
            }
        }
        let keep: Vec<_> = (0..block.rows.len())
            .map(|i| {
                let (e, i) = (hole(1, self.starts[b] + i), index(i));
                quote::quote!(#e = p[#i];)
            })
            .collect();
        let (factor, done) = if ratio {
            (
                quote::quote!(runtime::lu::factor_with_ratio(&mut a, &mut p, ratio)?),
                quote::quote!(Ok(info)),
            )
        } else {
            (
                quote::quote!(runtime::lu::factor_with_ratio(&mut a, &mut p, 0.0).ok()?),
                quote::quote!(Some(info)),
            )
        };
        quote::quote! {
            #(#tried)*
            let mut a = [#(#rows),*];
            let mut p = [0; #s];
            let info = #factor;
            #(#scatter)*
            #(#keep)*
            #done
        }
    }

    /// The solves of block b's static orders, each selected by its flag in `perm`
    /// ([`Lu::mark`]), with the right-hand side in `z` by the block's row, the solution written
    /// by `output`; `dense`, the solve of the dense LU's factors, otherwise.
    fn dispatch(
        &self,
        b: usize,
        hole: Hole<'_>,
        output: &mut dyn FnMut(usize, syn::Expr) -> syn::Stmt,
        dense: proc_macro2::TokenStream,
    ) -> proc_macro2::TokenStream {
        if self.orders[b].is_empty() {
            return dense;
        }
        let flag = hole(1, self.starts[b]);
        let mut arms = Vec::new();
        for k in 0..self.orders[b].len() {
            let mut input = |i: usize| -> syn::Expr {
                let i = index(i);
                parse_quote!(z[#i])
            };
            let code = self.order(b, k, true, hole, &mut input, output);
            let (solve, mark) = (code.solve, self.mark(b, k));
            arms.push(quote::quote!(if #flag == #mark { #(#solve)* }));
        }
        quote::quote!(#(#arms)else* else { #dense })
    }

    /// Solves block b alone (Newton's `solve_block`): the solution into `x[..s]`.
    fn solve_one(&self, b: usize, hole: Hole<'_>) -> proc_macro2::TokenStream {
        let block = &self.blocks.blocks[b];
        let s = index(block.rows.len());
        let z: Vec<_> = block.rows.iter().map(|&r| hole(2, r)).collect();
        let rows = self.gather(b, 0, false, hole);
        let order: Vec<_> = (0..block.rows.len()).map(|i| hole(1, self.starts[b] + i)).collect();
        if self.orders[b].is_empty() {
            let z = quote::quote!([#(#z),*]);
            return dense_solve(&rows, &order, &z, &quote::quote!(x[..#s].copy_from_slice(&z);));
        }
        let dense =
            dense_solve(&rows, &order, &quote::quote!(z), &quote::quote!(x.copy_from_slice(&z);));
        let mut output = |j: usize, v: syn::Expr| -> syn::Stmt {
            let j = index(j);
            parse_quote!(x[#j] = #v;)
        };
        let solve = self.dispatch(b, hole, &mut output, dense);
        quote::quote! {
            let x = &mut x[..#s];
            let z = [#(#z),*];
            #solve
        }
    }

    /// Solves for block b's unknowns, those of the blocks before it known (`solve_blocks`).
    fn solve_all(&self, b: usize, hole: Hole<'_>) -> proc_macro2::TokenStream {
        let block = &self.blocks.blocks[b];
        let z: Vec<_> = block
            .rows
            .iter()
            .map(|&r| {
                let first = hole(2, r);
                let terms: Vec<_> = self.lower[self.lower_starts[r]..self.lower_starts[r + 1]]
                    .iter()
                    .map(|&c| {
                        let (entry, x) = (hole(0, self.entries.flat(r, c)), hole(3, c));
                        quote::quote!(- #entry * #x)
                    })
                    .collect();
                quote::quote!(#first #(#terms)*)
            })
            .collect();
        let rows = self.gather(b, 0, false, hole);
        let order: Vec<_> = (0..block.rows.len()).map(|i| hole(1, self.starts[b] + i)).collect();
        let out: Vec<_> = block
            .unknowns
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                let (x, i) = (hole(3, c), index(i));
                quote::quote!(#x = z[#i];)
            })
            .collect();
        let out = quote::quote!(#(#out)*);
        if self.orders[b].is_empty() {
            return dense_solve(&rows, &order, &quote::quote!([#(#z),*]), &out);
        }
        let dense = dense_solve(&rows, &order, &quote::quote!(z), &out);
        let xs: Vec<_> = block.unknowns.iter().map(|&c| hole(3, c)).collect();
        let mut output = |j: usize, v: syn::Expr| -> syn::Stmt {
            let x = &xs[j];
            parse_quote!(#x = #v;)
        };
        let solve = self.dispatch(b, hole, &mut output, dense);
        quote::quote! {
            let z = [#(#z),*];
            #solve
        }
    }
}

/// A block's solve by its dense LU: the gathered `rows` and pivot `order`, the right-hand side
/// `z` (an array expression, or the name of one already built), then `tail` with the solution
/// in `z`.
fn dense_solve(
    rows: &[proc_macro2::TokenStream],
    order: &[syn::Expr],
    z: &proc_macro2::TokenStream,
    tail: &proc_macro2::TokenStream,
) -> proc_macro2::TokenStream {
    quote::quote! {
        let a = [#(#rows),*];
        let p = [#(#order),*];
        let mut z = #z;
        runtime::lu::solve(&a, &p, &mut z);
        #tail
    }
}

impl Shared {
    /// The block functions of `blocks` with the rotation blocks `rotations`, grouped.
    fn of(sys: &Symbolic, blocks: &Blocks, orders: &[Vec<Order>], rotations: &[Closed]) -> Shared {
        let n = sys.unknowns.len();
        let (lower_starts, lower) = lower(sys, blocks);
        let entries = Entries::packed(n, blocks, &lower_starts, &lower);
        let (both, alone): (Vec<_>, Vec<_>) = blocks
            .blocks
            .iter()
            .map(|block| {
                let (both, alone) = block_outputs(sys, block, &entries);
                (Some(both), Some(alone))
            })
            .unzip();
        let mut closed = vec![None; blocks.blocks.len()];
        for r in rotations {
            closed[r.block] = Some(
                r.coefficients.iter().enumerate().map(|(i, &e)| (Array::K, i, Some(e))).collect(),
            );
        }
        let lu = Lu::new(sys, blocks, orders, &entries, &lower_starts, &lower);
        let m = blocks.blocks.len();
        let implicit: Vec<usize> =
            (0..m).filter(|&b| blocks.blocks[b].kind != Kind::ClosedForm).collect();
        let square: Vec<usize> = (0..m).filter(|&b| blocks.blocks[b].rows.len() > 1).collect();
        // Φ, ν and γ go by runs of blocks (an implicit or rotation block and the affine blocks
        // after it: a body's orientation and its position, whose rows share most of their
        // terms) only when some of those runs share their functions: else the whole-system
        // functions stay (one straight-line function, the drivers' time functions computed
        // once).
        let mut runs: Vec<Vec<usize>> = Vec::new();
        for (b, block) in blocks.blocks.iter().enumerate() {
            match runs.last_mut() {
                Some(run) if block.kind == Kind::ClosedForm => run.push(b),
                _ => runs.push(vec![b]),
            }
        }
        let rows = |values: &[crate::expr::ExprId], array: Array| -> Vec<Option<Vec<Output>>> {
            runs.iter()
                .map(|run| {
                    let rows = run.iter().flat_map(|&b| &blocks.blocks[b].rows);
                    Some(rows.map(|&r| (array, r, Some(values[r]))).collect())
                })
                .collect()
        };
        let phi = Sharing::of(&sys.pool, &rows(&sys.phi, Array::Phi));
        let nu = Sharing::of(&sys.pool, &rows(&sys.nu, Array::Nu));
        let gamma = Sharing::of(&sys.pool, &rows(&sys.gamma, Array::Gamma));
        let vectors = phi.any() || nu.any() || gamma.any();
        let alone: Vec<_> = alone
            .into_iter()
            .zip(&blocks.blocks)
            .map(|(outputs, block)| outputs.filter(|_| block.kind != Kind::ClosedForm))
            .collect();
        let alone = Sharing::of(&sys.pool, &alone);
        Shared {
            vectors,
            runs,
            phi,
            nu,
            gamma,
            both: Sharing::of(&sys.pool, &both),
            alone,
            rotations: Sharing::of(&sys.pool, &closed),
            // Newton's factor and solve of one block share alike: `factor_block_k` and
            // `solve_block_k` take the same blocks.
            factor: Gathers::of(
                m,
                &implicit,
                2,
                &|b, hole| lu.factor(b, true, hole),
                Some(&|b, hole| lu.solve_one(b, hole)),
            ),
            solve: Gathers::of(
                m,
                &implicit,
                3,
                &|b, hole| lu.solve_one(b, hole),
                Some(&|b, hole| lu.factor(b, true, hole)),
            ),
            factor_all: Gathers::of(m, &square, 2, &|b, hole| lu.factor(b, false, hole), None),
            solve_all: Gathers::of(m, &square, 4, &|b, hole| lu.solve_all(b, hole), None),
        }
    }

    /// No sharing, for `blocks` blocks.
    fn none(blocks: usize) -> Shared {
        Shared {
            vectors: false,
            runs: Vec::new(),
            phi: Sharing::none(0),
            nu: Sharing::none(blocks),
            gamma: Sharing::none(blocks),
            both: Sharing::none(blocks),
            alone: Sharing::none(blocks),
            rotations: Sharing::none(blocks),
            factor: Gathers::none(blocks),
            solve: Gathers::none(blocks),
            factor_all: Gathers::none(blocks),
            solve_all: Gathers::none(blocks),
        }
    }
}

/// The outputs of `block_b` (Φ of the block's rows, their structural non-zeros of Φ_q, and
/// 0 at the structural zeros of the diagonal block) and of `block_residual_b` (Φ alone), in
/// the order the functions write them.
fn block_outputs(
    sys: &Symbolic,
    block: &crate::blocks::Block,
    entries: &Entries,
) -> (Vec<Output>, Vec<Output>) {
    let phi: Vec<Output> = block.rows.iter().map(|&r| (Array::Phi, r, Some(sys.phi[r]))).collect();
    let mut both = phi.clone();
    for &r in &block.rows {
        both.extend(sys.jac[r].iter().map(|&(c, e)| (Array::Jac, entries.flat(r, c), Some(e))));
    }
    for &r in &block.rows {
        for &c in &block.unknowns {
            if !sys.jac[r].iter().any(|&(j, _)| j == c) {
                both.push((Array::Jac, entries.flat(r, c), None));
            }
        }
    }
    (both, phi)
}

/// Row r's columns below the blocks, `lower[lower_starts[r]..lower_starts[r + 1]]`:
/// `(lower_starts, lower)`.
fn lower(sys: &Symbolic, blocks: &Blocks) -> (Vec<usize>, Vec<usize>) {
    let n = sys.unknowns.len();
    let (mut block_of_column, mut block_of_row) = (vec![0; n], vec![0; n]);
    for (b, block) in blocks.blocks.iter().enumerate() {
        for &c in &block.unknowns {
            block_of_column[c] = b;
        }
        for &r in &block.rows {
            block_of_row[r] = b;
        }
    }
    let (mut lower, mut lower_starts) = (Vec::new(), vec![0]);
    for (r, row) in sys.jac.iter().enumerate() {
        lower.extend(row.iter().map(|&(c, _)| c).filter(|&c| block_of_column[c] < block_of_row[r]));
        lower_starts.push(lower.len());
    }
    (lower_starts, lower)
}

/// A rotation block solved in closed form: `runtime::rotation::about_axis` on coefficients an
/// emitted function computes.
pub(super) struct Closed {
    /// The block.
    block: usize,
    /// The first of its unknowns e0 … e3 (consecutive).
    first: usize,
    /// Whether the driver's row is linear in e (an absolute rotation).
    linear: bool,
    /// u, w, f(u), f(w), f((u + w)/√2), in the pool.
    coefficients: [crate::expr::ExprId; 11],
}

/// Where the emitted block functions keep entry (r, c) of Φ_q in the `N × N` storage: packed
/// at its front with Newton block by block (`runtime::Mechanism::PACKED_BLOCKS`; the layout is
/// `runtime::blocks`' "Packed storage": row after row in the blocks' order, each row's
/// diagonal-block columns then its columns below the blocks), at `[r][c]` otherwise.
struct Entries {
    /// The number of unknowns, N.
    n: usize,
    /// The flat index of every entry, when packed.
    packed: Option<std::collections::HashMap<(usize, usize), usize>>,
    /// When packed, the flat index of every block's first entry, and the number of entries.
    starts: Vec<usize>,
}

impl Entries {
    /// The packed form of `blocks`, with row r's columns below the blocks in
    /// `lower[lower_starts[r]..lower_starts[r + 1]]`.
    fn packed(n: usize, blocks: &Blocks, lower_starts: &[usize], lower: &[usize]) -> Entries {
        let (mut at, mut starts) = (std::collections::HashMap::new(), Vec::new());
        for block in &blocks.blocks {
            starts.push(at.len());
            for &r in &block.rows {
                let below = &lower[lower_starts[r]..lower_starts[r + 1]];
                for &c in block.unknowns.iter().chain(below) {
                    let k = at.len();
                    at.insert((r, c), k);
                }
            }
        }
        starts.push(at.len());
        Entries { n, packed: Some(at), starts }
    }

    /// The flat index of entry (r, c) in the storage.
    fn flat(&self, r: usize, c: usize) -> usize {
        match &self.packed {
            Some(at) => at[&(r, c)],
            None => r * self.n + c,
        }
    }

    /// The indices `[i, j]` of entry (r, c) in the storage.
    fn at(&self, r: usize, c: usize) -> [usize; 2] {
        match &self.packed {
            Some(at) => {
                let k = at[&(r, c)];
                [k / self.n, k % self.n]
            }
            None => [r, c],
        }
    }

    /// `array[i][j]` for entry (r, c).
    fn element(&self, array: &syn::Ident, r: usize, c: usize) -> proc_macro2::TokenStream {
        let [i, j] = self.at(r, c).map(index);
        quote::quote!(#array[#i][#j])
    }
}

/// The blocks of `sys` when its solver factors Φ_q block by block: more than one block, none
/// larger than [`MAX_BLOCK`], and at least [`MIN_UNKNOWNS`] unknowns unless `newton` is
/// `Some(true)`. Newton runs block by block unless `newton` is `Some(false)` or rows are left
/// out as redundant; its rotation blocks' coefficients then join the pool.
///
/// Newton block by block is the plan wherever Φ_q is factored block by block: measured
/// (BENCHMARKS.md, "Closed-form orientation blocks"), with the orientation blocks in closed
/// form it took 21 % fewer instructions per step than one Newton iteration over the whole
/// system on a driven chain of 10 links, 57 % fewer on 100 links, 21 % fewer on ten 6R arms
/// and 27 % fewer on 34 R-S-S-R loops. Below [`MIN_UNKNOWNS`] the static orders stay: one 6R
/// arm took 5 % more instructions block by block and the R-S-S-R 85 % more (the runtime's
/// loops over a block's rows and its small LU cost more than the straight-line static order
/// of the whole 20 × 20 system).
pub(super) fn plan(sys: &mut Symbolic, mech: &Mechanism, newton: Option<bool>) -> Option<Plan> {
    let n = sys.unknowns.len();
    if n == 0 || (n < MIN_UNKNOWNS && newton != Some(true)) {
        return None;
    }
    let blocks = Blocks::of(sys, mech);
    let largest = blocks.blocks.iter().map(|b| b.rows.len()).max().unwrap_or(0);
    if blocks.blocks.len() <= 1 || largest > MAX_BLOCK {
        return None;
    }
    let newton = sys.dropped.is_empty() && newton != Some(false);
    if n < MIN_UNKNOWNS && !newton {
        return None;
    }
    let mut rotations = Vec::new();
    if newton {
        for (b, block) in blocks.blocks.iter().enumerate() {
            if let Kind::Rotation(r) = block.kind {
                let coefficients = r.coefficients(sys, mech);
                let first = r.first_unknown(sys);
                rotations.push(Closed { block: b, first, linear: r.linear, coefficients });
            }
        }
    }
    let orders = if newton { block_orders(sys, mech, &blocks) } else { Vec::new() };
    let orders = if orders.is_empty() { vec![Vec::new(); blocks.blocks.len()] } else { orders };
    let shared = if newton {
        Shared::of(sys, &blocks, &orders, &rotations)
    } else {
        Shared::none(blocks.blocks.len())
    };
    Some(Plan { blocks, newton, rotations, orders, shared })
}

/// The static pivot orders of the diagonal blocks Newton block by block factors (implicit and
/// rotation blocks), planned along the motion by `pivot::plan_blocks`: blocks with the same
/// structure and constant entries in block coordinates are planned together, so that one
/// list of orders serves them all and their code stays one shared function
/// ([`super::shared`]).
fn block_orders(sys: &Symbolic, mech: &Mechanism, blocks: &Blocks) -> Orders {
    type Key = (Vec<Vec<bool>>, Vec<Vec<Option<u64>>>);
    let mut keys: Vec<Key> = Vec::new();
    let mut groups: Vec<Vec<(Vec<usize>, Vec<usize>)>> = Vec::new();
    let mut group_of = vec![None; blocks.blocks.len()];
    for (b, block) in blocks.blocks.iter().enumerate() {
        if block.kind == Kind::ClosedForm {
            continue;
        }
        let (structure, constant) =
            crate::pivot::block_structure(sys, &block.rows, &block.unknowns);
        let constant =
            constant.iter().map(|row| row.iter().map(|c| c.map(f64::to_bits)).collect()).collect();
        let key = (structure, constant);
        let g = keys.iter().position(|k| *k == key).unwrap_or_else(|| {
            keys.push(key);
            groups.push(Vec::new());
            groups.len() - 1
        });
        group_of[b] = Some(g);
        groups[g].push((block.rows.clone(), block.unknowns.clone()));
    }
    let mut planned = crate::pivot::plan_blocks(mech, sys, &groups);
    // A large block's order is a long function per order; its dense LU is a call.
    for orders in &mut planned {
        orders.retain(|o| elimination_ops(o) <= super::CHUNK_OPS);
    }
    group_of.into_iter().map(|g| g.map(|g| planned[g].clone()).unwrap_or_default()).collect()
}

/// The multiplications and subtractions of the elimination with `order`: per step, a
/// multiplier for each row below the pivot, and an update of each of its entries right of the
/// pivot's column.
fn elimination_ops(order: &Order) -> usize {
    let n = order.rows.len();
    let mut below = vec![0; n];
    for (i, p) in order.pattern.iter().enumerate() {
        for &k in p.iter().filter(|&&k| k < i) {
            below[k] += 1;
        }
    }
    let right = |k: usize| order.pattern[k].iter().filter(|&&l| l > k).count();
    (0..n).map(|k| below[k] * (1 + 2 * right(k))).sum()
}

/// `static BLOCKS: runtime::blocks::Layout` and, for Newton block by block, the `block_k`
/// and `block_residual_k` functions; else `residual_jacobian_blocks` and the straight-line
/// block LU.
pub(super) fn items(rows: &Rows<'_>, plan: &Plan) -> Vec<syn::Item> {
    let (sys, blocks) = (rows.sys, &plan.blocks);
    let n = sys.unknowns.len();
    let (mut order_rows, mut order_columns, mut starts) = (Vec::new(), Vec::new(), vec![0]);
    for block in &blocks.blocks {
        order_rows.extend(&block.rows);
        order_columns.extend(&block.unknowns);
        starts.push(order_rows.len());
    }
    let (lower_starts, lower) = lower(sys, blocks);
    let list = |v: &[usize]| {
        let v = v.iter().map(|&k| index(k));
        quote::quote!(&[#(#v),*])
    };
    let (r, c, s, l, ls) =
        (list(&order_rows), list(&order_columns), list(&starts), list(&lower), list(&lower_starts));
    let solve = blocks.blocks.iter().map(|b| match b.kind {
        Kind::ClosedForm => quote::quote!(runtime::blocks::Solve::Affine),
        Kind::Rotation(_) => quote::quote!(runtime::blocks::Solve::Explicit),
        Kind::Implicit => quote::quote!(runtime::blocks::Solve::Newton),
    });
    let solve = if plan.newton { quote::quote!(&[#(#solve),*]) } else { quote::quote!(&[]) };
    let doc = format!(
        " The block-lower-triangular form of Φ_q: {} blocks (the largest of {}), {} entries below them.",
        blocks.blocks.len(),
        blocks.blocks.iter().map(|b| b.rows.len()).max().unwrap_or(0),
        lower.len()
    );
    let mut items: Vec<syn::Item> = vec![parse_quote! {
        #[doc = #doc]
        static BLOCKS: runtime::blocks::Layout = runtime::blocks::Layout {
            rows: #r,
            columns: #c,
            starts: #s,
            lower: #l,
            lower_starts: #ls,
            solve: #solve,
        };
    }];
    if plan.newton {
        let entries = Entries::packed(n, blocks, &lower_starts, &lower);
        let len = index(entries.starts.len());
        let starts = entries.starts.iter().map(|&k| index(k));
        let doc = format!(
            " Where each block's entries start in the packed storage of Φ_q (`runtime::blocks`), and their end: {} entries of the {} of `N × N`.",
            entries.starts.last().unwrap_or(&0),
            n * n
        );
        items.push(parse_quote! {
            #[doc = #doc]
            static PACKED_BLOCKS: [usize; #len] = [#(#starts),*];
        });
        items.extend(unpack(&entries));
        items.extend(block_functions(rows, blocks, &entries, &plan.shared));
        items.extend(rotation_functions(rows, &plan.rotations, &plan.shared.rotations));
        let lu = Lu::new(sys, blocks, &plan.orders, &entries, &lower_starts, &lower);
        let shared = &plan.shared;
        items.extend(shared.factor.items(
            "factor_block",
            &FACTOR_SLICES,
            &quote::quote!(jac: &mut [[f64; N]; N], perm: &mut [usize; N], ratio: f64),
            &quote::quote!(-> Result<runtime::lu::PivotInfo, runtime::lu::Singular>),
            "Factors the diagonal block alone (see `factor_block_k`)",
            &|b, hole| lu.factor(b, true, hole),
        ));
        items.extend(shared.solve.items(
            "solve_block",
            &SOLVE_ONE_SLICES,
            &quote::quote!(lu: &[[f64; N]; N], perm: &[usize; N], rhs: &[f64; N], x: &mut [f64]),
            &quote::quote!(),
            "Solves the diagonal block alone (see `solve_block_k`)",
            &|b, hole| lu.solve_one(b, hole),
        ));
        items.extend(shared.factor_all.items(
            "factor_blocks",
            &FACTOR_SLICES,
            &quote::quote!(jac: &mut [[f64; N]; N], perm: &mut [usize; N]),
            &quote::quote!(-> Option<runtime::lu::PivotInfo>),
            "Factors the diagonal block in place, its pivots returned (see `factor_blocks`)",
            &|b, hole| lu.factor(b, false, hole),
        ));
        items.extend(shared.solve_all.items(
            "solve_blocks",
            &SOLVE_ALL_SLICES,
            &quote::quote!(lu: &[[f64; N]; N], perm: &[usize; N], rhs: &[f64; N], x: &mut [f64; N]),
            &quote::quote!(),
            "Solves for the block's unknowns, those of the blocks before it known (see `solve_blocks`)",
            &|b, hole| lu.solve_all(b, hole),
        ));
        items.extend(straight_line(
            sys,
            blocks,
            &lower_starts,
            &lower,
            &entries,
            shared,
            Some(&lu),
        ));
        items.extend(block_factor_solve(sys, blocks, &entries, shared, &lu));
        return items;
    }
    let vec_ty = quote::quote!(&mut [f64; N]);
    let mat_ty = quote::quote!(&mut [[f64; N]; N]);
    let targets = [("phi", vec_ty), ("jac", mat_ty)];
    let mut outputs = rows.vector(0, "phi", &sys.phi);
    outputs.extend(rows.jacobian(1, false));
    let sig = Signature {
        name: "residual_jacobian_blocks",
        qd: false,
        qdd: false,
        public: false,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let what = "Φ and the structural non-zeros of Φ_q, the others of `jac` left as they were: what `factor_blocks_k` and `solve_blocks_k` read (the structural zeros of a diagonal block are literals there).";
    items.extend(rows.emit(&sig, what, Vec::new(), &outputs));
    let entries = Entries { n, packed: None, starts: Vec::new() };
    items.extend(straight_line(sys, blocks, &lower_starts, &lower, &entries, &plan.shared, None));
    items
}

/// The `factor_blocks_k` and `solve_blocks_k` functions, blocks in chunks of about
/// [`CHUNK_ENTRIES`] entries.
fn straight_line(
    sys: &Symbolic,
    blocks: &Blocks,
    lower_starts: &[usize],
    lower: &[usize],
    entries: &Entries,
    shared: &Shared,
    lu: Option<&Lu<'_>>,
) -> Vec<syn::Item> {
    let n = sys.unknowns.len();
    let mut chunks: Vec<Vec<usize>> = vec![Vec::new()];
    let mut size = 0;
    for (b, block) in blocks.blocks.iter().enumerate() {
        let s = block.rows.len();
        let entries = 2 * s * s
            + block.rows.iter().map(|&r| lower_starts[r + 1] - lower_starts[r]).sum::<usize>();
        if size + entries > CHUNK_ENTRIES && !chunks.last().is_some_and(Vec::is_empty) {
            chunks.push(Vec::new());
            size = 0;
        }
        size += entries;
        chunks.last_mut().expect("a chunk").push(b);
    }
    let mut starts = Vec::with_capacity(blocks.blocks.len());
    let mut at = 0;
    for block in &blocks.blocks {
        starts.push(at);
        at += block.rows.len();
    }
    let mut items = Vec::new();
    for (k, chunk) in chunks.iter().enumerate() {
        let (factor_body, solve_body): (Vec<_>, Vec<_>) = chunk
            .iter()
            .map(|&b| {
                let block = &blocks.blocks[b];
                let (mut factor, mut solve) =
                    block_code(sys, b, block, starts[b], lower_starts, lower, entries);
                if let Some(call) =
                    shared.factor_all.call("factor_blocks", b, &quote::quote!(jac, perm))
                {
                    let pivots = if b == 0 {
                        quote::quote!(*pivots = info;)
                    } else {
                        quote::quote! {
                            pivots.smallest = pivots.smallest.min(info.smallest);
                            pivots.largest = pivots.largest.max(info.largest);
                        }
                    };
                    factor = parse_quote! {
                        {
                            let Some(info) = #call else {
                                return false;
                            };
                            #pivots
                        }
                    };
                }
                if let Some(call) =
                    shared.solve_all.call("solve_blocks", b, &quote::quote!(lu, perm, rhs, x))
                {
                    solve = parse_quote!(#call;);
                } else if let Some(lu) = lu.filter(|lu| !lu.orders[b].is_empty()) {
                    let code = lu.solve_all(b, &mut direct(&SOLVE_ALL_SLICES, n));
                    solve = parse_quote!({ #code });
                }
                (factor, solve)
            })
            .unzip();
        let (first, last) = (chunk[0], chunk[chunk.len() - 1]);
        let factor = ident(&format!("factor_blocks_{k}"));
        let solve = ident(&format!("solve_blocks_{k}"));
        let doc = format!(
            " Factors blocks {first} to {last} in place (see `factor_blocks`); false when a pivot is 0 or an entry not finite."
        );
        items.push(parse_quote! {
            #[doc = #doc]
            fn #factor(jac: &mut [[f64; N]; N], perm: &mut [usize; N], pivots: &mut runtime::lu::PivotInfo) -> bool {
                #(#factor_body)*
                true
            }
        });
        let doc = format!(
            " Solves for the unknowns of blocks {first} to {last}, those of the blocks before them known (see `solve_blocks`)."
        );
        items.push(parse_quote! {
            #[doc = #doc]
            fn #solve(lu: &[[f64; N]; N], perm: &[usize; N], rhs: &[f64; N], x: &mut [f64; N]) {
                #(#solve_body)*
            }
        });
    }
    let factors = (0..chunks.len()).map(|k| ident(&format!("factor_blocks_{k}")));
    let solves = (0..chunks.len()).map(|k| ident(&format!("solve_blocks_{k}")));
    items.push(parse_quote! {
        /// Factors Φ_q's diagonal blocks in place, each by LU with partial pivoting inside the
        /// block, their row orders in `perm`; the smallest and largest |pivot|, or `None` when a
        /// pivot is 0 or an entry not finite.
        fn factor_blocks(jac: &mut [[f64; N]; N], perm: &mut [usize; N]) -> Option<runtime::lu::PivotInfo> {
            let mut pivots = runtime::lu::PivotInfo { smallest: 0.0, largest: 0.0 };
            (#(#factors(jac, perm, &mut pivots))&&*).then_some(pivots)
        }
    });
    items.push(parse_quote! {
        /// Solves Φ_q x = b in place (b by row in, x by column out), block after block, with
        /// the factors of `factor_blocks`.
        fn solve_blocks(lu: &[[f64; N]; N], perm: &[usize; N], b: &mut [f64; N]) {
            let rhs = *b;
            #(#solves(lu, perm, &rhs, b);)*
        }
    });
    items
}

/// The rows of `block` read from `array` (entry (r, c) where `entries` keeps it, in the
/// block's order), with Φ_q's structural zeros as literals when `zeros`.
fn gather(
    sys: &Symbolic,
    block: &crate::blocks::Block,
    array: &str,
    zeros: bool,
    entries: &Entries,
) -> Vec<proc_macro2::TokenStream> {
    let array = ident(array);
    block
        .rows
        .iter()
        .map(|&r| {
            let row = block.unknowns.iter().map(|&c| {
                if !zeros || sys.jac[r].iter().any(|&(j, _)| j == c) {
                    entries.element(&array, r, c)
                } else {
                    quote::quote!(0.0)
                }
            });
            quote::quote!([#(#row),*])
        })
        .collect()
}

/// `jac[r][c] = a[i][j];` for every entry of `block` (where `entries` keeps it): its factors
/// written back in place.
fn scatter(block: &crate::blocks::Block, entries: &Entries) -> Vec<proc_macro2::TokenStream> {
    let mut scatter = Vec::new();
    let jac = ident("jac");
    for (i, &r) in block.rows.iter().enumerate() {
        for (j, &c) in block.unknowns.iter().enumerate() {
            let (entry, i, j) = (entries.element(&jac, r, c), index(i), index(j));
            scatter.push(quote::quote!(#entry = a[#i][#j];));
        }
    }
    scatter
}

/// The statements that factor block `b` (gather, `runtime::lu::factor_with_ratio`, scatter,
/// its row order into `perm` from position `start`) and that solve for it.
fn block_code(
    sys: &Symbolic,
    b: usize,
    block: &crate::blocks::Block,
    start: usize,
    lower_starts: &[usize],
    lower: &[usize],
    entries: &Entries,
) -> (syn::Stmt, syn::Stmt) {
    let (jac, lu) = (ident("jac"), ident("lu"));
    let z = block.rows.iter().map(|&r| {
        let terms = lower[lower_starts[r]..lower_starts[r + 1]].iter().map(|&c| {
            let (entry, c) = (entries.element(&lu, r, c), index(c));
            quote::quote!(- #entry * x[#c])
        });
        let r = index(r);
        quote::quote!(rhs[#r] #(#terms)*)
    });
    if let ([r], [c]) = (block.rows.as_slice(), block.unknowns.as_slice()) {
        // One equation in one unknown: its entry is its pivot.
        let (entry, pivot) = (entries.element(&jac, *r, *c), entries.element(&lu, *r, *c));
        let c = index(*c);
        let pivots = if b == 0 {
            quote::quote!(*pivots = runtime::lu::PivotInfo { smallest: v, largest: v };)
        } else {
            quote::quote! {
                pivots.smallest = pivots.smallest.min(v);
                pivots.largest = pivots.largest.max(v);
            }
        };
        let factor = parse_quote! {
            {
                let v = #entry.abs();
                if !(v > 0.0 && v.is_finite()) {
                    return false;
                }
                #pivots
            }
        };
        let z: Vec<_> = z.collect();
        let solve = parse_quote!(x[#c] = (#(#z)*) / #pivot;);
        return (factor, solve);
    }
    // Φ_q's structural zeros in the block are literals; the factors fill the whole block.
    let rows_in = gather(sys, block, "jac", true, entries);
    let scatter = scatter(block, entries);
    let keep = (0..block.rows.len()).map(|i| {
        let (at, i) = (index(start + i), index(i));
        quote::quote!(perm[#at] = p[#i];)
    });
    let pivots = if b == 0 {
        quote::quote!(*pivots = info;)
    } else {
        quote::quote! {
            pivots.smallest = pivots.smallest.min(info.smallest);
            pivots.largest = pivots.largest.max(info.largest);
        }
    };
    let s = index(block.rows.len());
    let factor: syn::Stmt = parse_quote! {
        {
            let mut a = [#(#rows_in),*];
            let mut p = [0; #s];
            let Ok(info) = runtime::lu::factor_with_ratio(&mut a, &mut p, 0.0) else {
                return false;
            };
            #pivots
            #(#scatter)*
            #(#keep)*
        }
    };
    let rows_lu = gather(sys, block, "lu", false, entries);
    let order = (0..block.rows.len()).map(|i| {
        let at = index(start + i);
        quote::quote!(perm[#at])
    });
    let out = block.unknowns.iter().enumerate().map(|(i, &c)| {
        let (c, i) = (index(c), index(i));
        quote::quote!(x[#c] = z[#i];)
    });
    let solve: syn::Stmt = parse_quote! {
        {
            let a = [#(#rows_lu),*];
            let p = [#(#order),*];
            let mut z = [#(#z),*];
            runtime::lu::solve(&a, &p, &mut z);
            #(#out)*
        }
    };
    (factor, solve)
}

/// The `runtime::Mechanism` items that select the block-by-block LU (and Newton block by block
/// when planned), for a mechanism whose functions take its inputs at t when `inputs`.
pub(super) fn impl_items(plan: &Plan, inputs: bool) -> Vec<syn::ImplItem> {
    if plan.newton {
        return newton_impl_items(plan, inputs);
    }
    let [factor, solve] = factor_solve_blocks();
    vec![
        parse_quote!(
            const BLOCKS: Option<&'static runtime::blocks::Layout> = Some(&BLOCKS);
        ),
        factor,
        solve,
        if inputs {
            parse_quote! {
                fn residual_jacobian_blocks(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian_blocks(q, t, &self.inputs(t), phi, jac);
                }
            }
        } else {
            parse_quote! {
                fn residual_jacobian_blocks(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian_blocks(q, t, phi, jac);
                }
            }
        },
    ]
}

/// `UNPACKED`, the row-major index `r · N + c` of every packed entry (r, c), and `unpack`,
/// which moves the packed entries at the front of the storage to their places `[r][c]`, so
/// that `jacobian` and `residual_jacobian`, written as calls of the block functions
/// ([`super::from_blocks`]), return Φ_q row-major as the trait says.
fn unpack(entries: &Entries) -> Vec<syn::Item> {
    let Some(at) = &entries.packed else { return Vec::new() };
    let mut dense = vec![0; at.len()];
    for (&(r, c), &k) in at {
        dense[k] = r * entries.n + c;
    }
    let len = index(dense.len());
    let dense = dense.into_iter().map(index);
    vec![
        parse_quote! {
            /// The row-major index of every entry of the packed storage of Φ_q.
            static UNPACKED: [usize; #len] = [#(#dense),*];
        },
        parse_quote! {
            /// Moves the packed entries at the front of `jac`, the rest of which is 0, to their
            /// row-major places.
            fn unpack(jac: &mut [[f64; N]; N]) {
                let flat = jac.as_flattened_mut();
                let mut packed = [0.0; #len];
                packed.copy_from_slice(&flat[..#len]);
                flat[..#len].fill(0.0);
                for (&value, &k) in packed.iter().zip(&UNPACKED) {
                    flat[k] = value;
                }
            }
        },
    ]
}

/// Per block b: `block_b`, writing Φ and the structural non-zeros of Φ_q of the block's rows
/// (and 0 at the structural zeros of its diagonal block, where its last factors left fill-in),
/// and, unless the block is affine (solved in closed form from Φ with Φ_q), `block_residual_b`
/// writing Φ of its rows alone (for a rotation block, Newton's when its closed form fails). Each is a small straight-line function of its own, so that
/// Newton block by block evaluates only the block it iterates on.
fn block_functions(
    rows: &Rows<'_>,
    blocks: &Blocks,
    entries: &Entries,
    shared: &Shared,
) -> Vec<syn::Item> {
    let sys = rows.sys;
    let n = sys.unknowns.len();
    let vec_ty = quote::quote!(&mut [f64; N]);
    let mat_ty = quote::quote!(&mut [[f64; N]; N]);
    let both = [("phi", vec_ty.clone()), ("jac", mat_ty)];
    let alone = [("phi", vec_ty)];
    let signature = |targets| Signature {
        name: "",
        qd: false,
        qdd: false,
        public: false,
        targets,
        inputs: rows.inputs(),
    };
    let mut items = shared.both.items(
        "block",
        &signature(&both[..]),
        "Φ and the structural non-zeros of Φ_q of the rows (see `block_b`)",
    );
    items.extend(shared.alone.items("block_residual", &signature(&alone[..]), "Φ of the rows"));
    for (b, block) in blocks.blocks.iter().enumerate() {
        let phi: Vec<_> = block
            .rows
            .iter()
            .map(|&r| (super::syntax::element("phi", &[r]), sys.phi[r], Some(r)))
            .collect();
        let mut all = phi.clone();
        for &r in &block.rows {
            all.extend(
                sys.jac[r]
                    .iter()
                    .map(|&(c, e)| (super::syntax::element("jac", &entries.at(r, c)), e, Some(r))),
            );
        }
        // The structural zeros of the diagonal block, which the factorisation before filled in.
        let zeros: Vec<syn::Stmt> = block
            .rows
            .iter()
            .flat_map(|&r| {
                block
                    .unknowns
                    .iter()
                    .filter(move |&&c| !sys.jac[r].iter().any(|&(j, _)| j == c))
                    .map(move |&c| {
                        let entry = entries.element(&ident("jac"), r, c);
                        parse_quote!(#entry = 0.0;)
                    })
            })
            .collect();
        let mut emit = |name: String,
                        outputs: &[(syn::Expr, crate::expr::ExprId, Option<usize>)],
                        targets,
                        extra: &[syn::Stmt]| {
            let mut f = super::function::function_with(&sys.pool, n, outputs, true);
            f.stmts.extend(extra.iter().cloned());
            let arrays = [true, true];
            let used = super::function::Used::of(&f, &arrays);
            let doc = format!(" {name}: {} operations.", f.ops);
            let item = signature(targets).item(&ident(&name), &doc, &used, true);
            items.push(super::syntax::item_fn(item, f.stmts));
        };
        if shared.both.shared(b).is_none() {
            emit(format!("block_{b}"), &all, &both[..], &zeros);
        }
        if block.kind != Kind::ClosedForm && shared.alone.shared(b).is_none() {
            emit(format!("block_residual_{b}"), &phi, &alone[..], &[]);
        }
    }
    items
}

/// Per rotation block b solved in closed form, `rotation_b` writing what
/// `runtime::rotation::about_axis` reads: u and w (the family of the body's Euler parameters,
/// from the known body's) and the driver's row at u, at w and at (u + w)/√2.
fn rotation_functions(rows: &Rows<'_>, rotations: &[Closed], shared: &Sharing) -> Vec<syn::Item> {
    let sys = rows.sys;
    let n = sys.unknowns.len();
    let targets = [("k", quote::quote!(&mut [f64; runtime::rotation::COEFFICIENTS]))];
    let signature = Signature {
        name: "",
        qd: false,
        qdd: false,
        public: false,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let mut items = shared.items(
        "rotation",
        &signature,
        "u, w, the driver's row at u, at w and at (u + w)/√2 (`runtime::rotation`)",
    );
    for r in rotations.iter().filter(|r| shared.shared(r.block).is_none()) {
        let outputs: Vec<_> = r
            .coefficients
            .iter()
            .enumerate()
            .map(|(i, &e)| (super::syntax::element("k", &[i]), e, None))
            .collect();
        let f = super::function::function_with(&sys.pool, n, &outputs, true);
        let arrays = [true];
        let used = super::function::Used::of(&f, &arrays);
        let name = format!("rotation_{}", r.block);
        let doc = format!(
            " {name}: u, w, the driver's row at u, at w and at (u + w)/√2 (`runtime::rotation`): {} operations.",
            f.ops
        );
        let item = signature.item(&ident(&name), &doc, &used, true);
        items.push(super::syntax::item_fn(item, f.stmts));
    }
    items
}

/// The `runtime::Mechanism` items that hand the runtime the emitted `factor_blocks` and
/// `solve_blocks`.
fn factor_solve_blocks() -> [syn::ImplItem; 2] {
    [
        parse_quote! {
            fn factor_blocks(&self, jac: &mut [[f64; N]; N], perm: &mut [usize; N]) -> Option<runtime::lu::PivotInfo> {
                factor_blocks(jac, perm)
            }
        },
        parse_quote! {
            fn solve_blocks(&self, lu: &[[f64; N]; N], perm: &[usize; N], b: &mut [f64; N]) {
                solve_blocks(lu, perm, b);
            }
        },
    ]
}

/// The `runtime::Mechanism` items of Newton block by block: the layout, `BLOCK_NEWTON` and
/// `block_residual` dispatching to the block functions.
fn newton_impl_items(plan: &Plan, inputs: bool) -> Vec<syn::ImplItem> {
    let blocks = &plan.blocks;
    let chunks = implicit_chunks(blocks, &plan.shared.factor);
    let range = |chunk: &[usize]| {
        let (first, last) = (index(chunk[0]), index(chunk[chunk.len() - 1]));
        quote::quote!(#first..=#last)
    };
    let shared = &plan.shared;
    let mut factor_arms = Vec::new();
    let mut solve_arms = Vec::new();
    for b in 0..blocks.blocks.len() {
        let lit = index(b);
        if let Some(call) = shared.factor.call("factor_block", b, &quote::quote!(jac, perm, ratio))
        {
            factor_arms.push(quote::quote!(#lit => #call,));
        }
        if let Some(call) = shared.solve.call("solve_block", b, &quote::quote!(lu, perm, rhs, x)) {
            solve_arms.push((quote::quote!(#lit), call));
        }
    }
    factor_arms.extend(chunks.iter().enumerate().map(|(k, chunk)| {
        let (r, f) = (range(chunk), ident(&format!("factor_block_{k}")));
        quote::quote!(#r => #f(b, jac, perm, ratio),)
    }));
    solve_arms.extend(chunks.iter().enumerate().map(|(k, chunk)| {
        let (r, f) = (range(chunk), ident(&format!("solve_block_{k}")));
        (r, quote::quote!(#f(b, lu, perm, rhs, x)))
    }));
    let u = inputs.then(|| quote::quote!(&u,));
    let both = blocks.blocks.iter().enumerate().map(|(b, _)| {
        let lit = index(b);
        (quote::quote!(#lit), plan.shared.both.call("block", b, &quote::quote!(q, t, #u phi, jac)))
    });
    let alone = blocks.blocks.iter().enumerate().filter(|(_, k)| k.kind != Kind::ClosedForm).map(
        |(b, _)| {
            let lit = index(b);
            let args = quote::quote!(q, t, #u phi);
            (quote::quote!(#lit), plan.shared.alone.call("block_residual", b, &args))
        },
    );
    let (solve_arms, both, alone) =
        (unit_dispatch(solve_arms), unit_dispatch(both.collect()), unit_dispatch(alone.collect()));
    let read = inputs.then(|| quote::quote!(let u = self.inputs(t).to_array();));
    let [factor, solve] = factor_solve_blocks();
    let mut items = Vec::new();
    if !plan.rotations.is_empty() {
        let arms = plan.rotations.iter().map(|r| {
            let lit = index(r.block);
            let call =
                plan.shared.rotations.call("rotation", r.block, &quote::quote!(q, t, #u &mut k));
            let (first, linear) = (index(r.first), r.linear);
            quote::quote!(#lit => { #call; (#first, #linear) })
        });
        items.push(parse_quote! {
            fn closed_form_block(&self, b: usize, q: &mut [f64; N], t: f64) -> bool {
                #read
                let mut k = [0.0; runtime::rotation::COEFFICIENTS];
                let (at, linear) = match b {
                    #(#arms)*
                    _ => return false,
                };
                let previous = [q[at], q[at + 1], q[at + 2], q[at + 3]];
                let Some(e) = runtime::rotation::about_axis(&k, linear, &previous) else {
                    return false;
                };
                q[at..at + 4].copy_from_slice(&e);
                true
            }
        });
    }
    items.extend([
        parse_quote!(
            const BLOCKS: Option<&'static runtime::blocks::Layout> = Some(&BLOCKS);
        ),
        parse_quote!(
            const BLOCK_NEWTON: bool = true;
        ),
        parse_quote!(
            const PACKED_BLOCKS: Option<&'static [usize]> = Some(&PACKED_BLOCKS);
        ),
        factor,
        solve,
        parse_quote! {
            fn factor_block(&self, b: usize, jac: &mut [[f64; N]; N], perm: &mut [usize; N], ratio: f64) -> Result<runtime::lu::PivotInfo, runtime::lu::Singular> {
                match b {
                    #(#factor_arms)*
                    _ => Err(runtime::lu::Singular::NonFinite { column: 0 }),
                }
            }
        },
        parse_quote! {
            fn solve_block(&self, b: usize, lu: &[[f64; N]; N], perm: &[usize; N], rhs: &[f64; N], x: &mut [f64]) {
                #solve_arms
            }
        },
        parse_quote! {
            fn block_residual(&self, b: usize, jacobian: bool, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                #read
                if jacobian {
                    #both
                } else {
                    #alone
                }
            }
        },
    ]);
    items
}

/// The blocks factored alone (implicit and rotation blocks) in chunks of about
/// [`CHUNK_ENTRIES`] entries of their diagonal blocks, each chunk a run of consecutive block
/// indices (the affine blocks between them have no arm).
fn implicit_chunks(blocks: &Blocks, shared: &Gathers) -> Vec<Vec<usize>> {
    let mut chunks: Vec<Vec<usize>> = vec![Vec::new()];
    let mut size = 0;
    for (b, block) in blocks.blocks.iter().enumerate() {
        if block.kind == Kind::ClosedForm || shared.shared(b).is_some() {
            continue;
        }
        let entries = 2 * block.rows.len() * block.rows.len();
        if size + entries > CHUNK_ENTRIES && !chunks.last().is_some_and(Vec::is_empty) {
            chunks.push(Vec::new());
            size = 0;
        }
        size += entries;
        chunks.last_mut().expect("a chunk").push(b);
    }
    chunks.retain(|c| !c.is_empty());
    chunks
}

/// `factor_block_k` and `solve_block_k`: for each implicit block b of chunk k, an arm that
/// factors its diagonal block alone (gathered into a fixed-size array, `runtime::lu` with
/// partial pivoting, scattered back in the layout of `factor_blocks`) and one that solves it
/// alone, for Newton block by block.
fn block_factor_solve(
    sys: &Symbolic,
    blocks: &Blocks,
    entries: &Entries,
    shared: &Shared,
    lu: &Lu<'_>,
) -> Vec<syn::Item> {
    let n = sys.unknowns.len();
    let mut starts = Vec::with_capacity(blocks.blocks.len());
    let mut at = 0;
    for block in &blocks.blocks {
        starts.push(at);
        at += block.rows.len();
    }
    let mut items = Vec::new();
    for (k, chunk) in implicit_chunks(blocks, &shared.factor).iter().enumerate() {
        let mut factor_arms = Vec::new();
        let mut solve_arms = Vec::new();
        for &b in chunk {
            let block = &blocks.blocks[b];
            let s = index(block.rows.len());
            let lit = index(b);
            if !lu.orders[b].is_empty() {
                let factor = lu.factor(b, true, &mut direct(&FACTOR_SLICES, n));
                factor_arms.push(quote::quote!(#lit => { #factor }));
                let solve = lu.solve_one(b, &mut direct(&SOLVE_ONE_SLICES, n));
                solve_arms.push((quote::quote!(#lit), quote::quote!({ #solve })));
                continue;
            }
            let rows_in = gather(sys, block, "jac", true, entries);
            let scatter = scatter(block, entries);
            let keep = (0..block.rows.len()).map(|i| {
                let (at, i) = (index(starts[b] + i), index(i));
                quote::quote!(perm[#at] = p[#i];)
            });
            factor_arms.push(quote::quote! {
                #lit => {
                    let mut a = [#(#rows_in),*];
                    let mut p = [0; #s];
                    let info = runtime::lu::factor_with_ratio(&mut a, &mut p, ratio)?;
                    #(#scatter)*
                    #(#keep)*
                    Ok(info)
                }
            });
            let rows_lu = gather(sys, block, "lu", false, entries);
            let order = (0..block.rows.len()).map(|i| {
                let at = index(starts[b] + i);
                quote::quote!(perm[#at])
            });
            let z = block.rows.iter().map(|&r| {
                let r = index(r);
                quote::quote!(rhs[#r])
            });
            solve_arms.push((
                quote::quote!(#lit),
                quote::quote! {
                    {
                        let a = [#(#rows_lu),*];
                        let p = [#(#order),*];
                        let mut z = [#(#z),*];
                        runtime::lu::solve(&a, &p, &mut z);
                        x[..#s].copy_from_slice(&z);
                    }
                },
            ));
        }
        let solve_dispatch = unit_dispatch(solve_arms);
        let (first, last) = (chunk[0], chunk[chunk.len() - 1]);
        let factor = ident(&format!("factor_block_{k}"));
        let solve = ident(&format!("solve_block_{k}"));
        let doc = format!(
            " Factors the diagonal block `b` (an implicit one of blocks {first} to {last}) alone, as `factor_blocks` does, refusing it when its smallest |pivot| ≤ `ratio` · its largest."
        );
        items.push(parse_quote! {
            #[doc = #doc]
            fn #factor(b: usize, jac: &mut [[f64; N]; N], perm: &mut [usize; N], ratio: f64) -> Result<runtime::lu::PivotInfo, runtime::lu::Singular> {
                match b {
                    #(#factor_arms)*
                    _ => Err(runtime::lu::Singular::NonFinite { column: 0 }),
                }
            }
        });
        let doc = format!(
            " Solves the diagonal block `b` (an implicit one of blocks {first} to {last}) alone with the factors of `{factor}`: the right-hand side by row from `rhs`, the solution in the order of the block's unknowns into `x`."
        );
        items.push(parse_quote! {
            #[doc = #doc]
            fn #solve(b: usize, lu: &[[f64; N]; N], perm: &[usize; N], rhs: &[f64; N], x: &mut [f64]) {
                #solve_dispatch
            }
        });
    }
    items
}

/// The hole of [`Lu`]'s code that names its place directly, for a block whose LU code is not
/// shared: element k of array `slices[a]` (`[k / n][k % n]` of a square one).
fn direct(slices: &[Slice], n: usize) -> impl FnMut(usize, usize) -> syn::Expr + '_ {
    move |a, k| {
        let name = ident(slices[a].name);
        if slices[a].square {
            let (i, j) = (index(k / n), index(k % n));
            parse_quote!(#name[#i][#j])
        } else {
            let k = index(k);
            parse_quote!(#name[#k])
        }
    }
}

/// A dispatch on the block index `b` to calls that return nothing: `if let` for one arm (what
/// clippy asks of a `match` with one arm), a `match` for several, nothing for none.
fn unit_dispatch(
    arms: Vec<(proc_macro2::TokenStream, proc_macro2::TokenStream)>,
) -> proc_macro2::TokenStream {
    match arms.as_slice() {
        [] => proc_macro2::TokenStream::new(),
        [(pattern, body)] => quote::quote!(if let #pattern = b { #body }),
        _ => {
            let (patterns, bodies): (Vec<_>, Vec<_>) = arms.into_iter().unzip();
            quote::quote!(match b { #(#patterns => #bodies,)* _ => {} })
        }
    }
}

/// `residual`, `velocity_rhs` and `acceleration_rhs` of a module solved by Newton block by
/// block, as calls of functions per block (`block_residual_b`, `block_velocity_b`,
/// `block_acceleration_b`, or the function their structure shares, [`super::shared`]): the
/// same expressions as the whole-system functions, row for row, so the same values, with
/// the copies of one structure running one function.
pub(super) fn vectors(rows: &Rows<'_>, plan: &Plan) -> Vec<syn::Item> {
    let sys = rows.sys;
    let n = sys.unknowns.len();
    let inputs = rows.inputs();
    let vec_ty = quote::quote!(&mut [f64; N]);
    let mut items = Vec::new();
    // (public function, block functions, array, sharing, values, reads q̇, doc).
    type Vector<'s> = (&'s str, &'s str, &'s str, &'s Sharing, &'s [crate::expr::ExprId]);
    let kinds: [(Vector<'_>, bool, String); 3] = [
        (
            ("residual", "rows_residual", "phi", &plan.shared.phi, &sys.phi),
            false,
            format!(" Constraint residuals Φ(q, t), {n} rows, by runs of blocks."),
        ),
        (
            ("velocity_rhs", "rows_velocity", "nu", &plan.shared.nu, &sys.nu),
            false,
            " Velocity right-hand side ν = −Φ_t, by runs of blocks.".to_owned(),
        ),
        (
            ("acceleration_rhs", "rows_acceleration", "gamma", &plan.shared.gamma, &sys.gamma),
            true,
            " Acceleration right-hand side γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt, by runs of blocks."
                .to_owned(),
        ),
    ];
    for ((public, name, array, sharing, values), qd, doc) in kinds {
        let targets = [(array, vec_ty.clone())];
        let sig = Signature { name: "", qd, qdd: false, public: false, targets: &targets, inputs };
        {
            let what = match array {
                "phi" => "Φ of the rows of a run of blocks",
                "nu" => "ν of the rows of a run of blocks",
                _ => "γ of the rows of a run of blocks",
            };
            items.extend(sharing.items(name, &sig, what));
            for (b, run) in plan.shared.runs.iter().enumerate() {
                if sharing.shared(b).is_some() {
                    continue;
                }
                let outputs: Vec<_> = run
                    .iter()
                    .flat_map(|&k| &plan.blocks.blocks[k].rows)
                    .map(|&r| (super::syntax::element(array, &[r]), values[r], Some(r)))
                    .collect();
                let f = super::function::function_with(&sys.pool, n, &outputs, true);
                let arrays = [true];
                let used = super::function::Used::of(&f, &arrays);
                let fname = format!("{name}_{b}");
                let doc = format!(" {fname}: {} operations.", f.ops);
                let item = sig.item(&ident(&fname), &doc, &used, true);
                items.push(super::syntax::item_fn(item, f.stmts));
            }
        }
        let out = ident(array);
        let rate = qd.then(|| quote::quote!(qd,));
        let u = inputs.then(|| quote::quote!(&u,));
        let calls = sharing.calls_all(name, &quote::quote!(q, #rate t, #u #out));
        let public = ident(public);
        let qd_param = qd.then(|| quote::quote!(qd: &[f64; N],));
        let (param, gather) = if inputs {
            (Some(quote::quote!(inputs: &Inputs,)), Some(quote::quote!(let u = inputs.to_array();)))
        } else {
            (None, None)
        };
        items.push(parse_quote! {
            #[doc = #doc]
            pub fn #public(q: &[f64; N], #qd_param t: f64, #param #out: &mut [f64; N]) {
                #gather
                #(#calls)*
            }
        });
    }
    items
}
