//! The structured LU of Φ_q: static pivot orders chosen at generation time, emitted as
//! straight-line `factor` and `solve` functions that touch only the entries of L and U.
//!
//! An order is a sequence of pivots (row, column) of Φ_q. It is chosen by Markowitz's rule
//! with threshold pivoting (as in Harwell's MA28 and MA48) on the numeric Jacobian at one
//! configuration: at every step of the elimination the pivot is, among the entries whose
//! magnitude is at least [`CHOICE_THRESHOLD`] of the largest in their column of the active
//! submatrix, one with the smallest (r − 1)(c − 1), r and c being the structurally non-zero
//! entries in its row and column, which bounds the fill-in the step creates. The fill-in
//! is tracked structurally, so the emitted code is valid for every value of q.
//!
//! A static order is only safe where its pivots stay large, and over a motion an entry that is
//! a fine pivot at one crank angle passes through zero at another. The generator therefore
//! walks the configurations the generic engine computes over the description's time grid,
//! and whenever no order chosen so far passes the run-time guard with a margin there
//! ([`COVER_THRESHOLD`]), it chooses a new one at that configuration, up to [`MAX_ORDERS`].
//! At run time the guard decides (see `runtime::lu::MAX_MULTIPLIER`), and a factorisation
//! that no order passes falls back to dense LU with partial pivoting.

use syn::{Expr, Ident, parse_quote};

use super::{Prec, binary, ident, index, literal_signed, neg, paren};
use crate::generic::{Analysis, Equations};
use crate::model::Mechanism;
use crate::symbolic::Symbolic;

/// A candidate pivot qualifies when its magnitude is at least this fraction of the largest in
/// its column of the active submatrix at the configuration the order is chosen at.
///
/// The run-time guard accepts multipliers up to 10 (a fraction of 0.1); choosing with 0.5
/// leaves a factor of 5 for the entries to change along the motion before the guard refuses
/// the order, while still leaving Markowitz's rule several candidates to pick the sparsest.
pub const CHOICE_THRESHOLD: f64 = 0.5;

/// A configuration is covered by an order whose multipliers there are at most 1 / this
/// fraction (|l| ≤ 4): a margin of 2.5 below the run-time bound of 10, so that the Newton
/// iterates near a sampled configuration pass the guard too.
pub const COVER_THRESHOLD: f64 = 0.25;

/// At most this many orders are emitted. Each costs one factor and one solve function; a
/// configuration none of them covers is factored by the dense fallback.
pub const MAX_ORDERS: usize = 4;

/// The bound on |l| that the run-time guard applies (`runtime::lu::MAX_MULTIPLIER`), used here
/// to count the configurations the emitted orders leave to the fallback.
pub const RUNTIME_MAX_MULTIPLIER: f64 = 10.0;

/// A static pivot order for Φ_q and the structure of its L and U factors.
///
/// Step coordinates: step k pivots on row `rows[k]` and column `cols[k]` of Φ_q, so the
/// permuted matrix B = P Φ_q Q has B[k][l] = Φ_q[rows[k]][cols[l]], and B = L U.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Order {
    /// The row of Φ_q pivoted at each step.
    pub rows: Vec<usize>,
    /// The column of Φ_q pivoted at each step.
    pub cols: Vec<usize>,
    /// For each step k, the steps l (ascending) where B[k][l] is a structural non-zero of L
    /// (l < k) or of U (l ≥ k).
    pub pattern: Vec<Vec<usize>>,
}

impl Order {
    /// The number of entries of L and U (the unit diagonal of L not counted).
    #[must_use]
    pub fn entries(&self) -> usize {
        self.pattern.iter().map(Vec::len).sum()
    }
}

/// The structure of Φ_q: `structure[i][j]` when entry (i, j) is not identically zero.
#[must_use]
pub fn structure(sys: &Symbolic) -> Vec<Vec<bool>> {
    let n = sys.unknowns.len();
    let mut s = vec![vec![false; n]; n];
    for (i, row) in sys.jac.iter().enumerate() {
        for &(j, _) in row {
            s[i][j] = true;
        }
    }
    s
}

/// The entries of Φ_q that depend on neither q nor t, with their values.
#[must_use]
pub fn constants(sys: &Symbolic) -> Vec<Vec<Option<f64>>> {
    let n = sys.unknowns.len();
    let mut c = vec![vec![None; n]; n];
    for (i, row) in sys.jac.iter().enumerate() {
        for &(j, e) in row {
            c[i][j] = sys.pool.as_const(e);
        }
    }
    c
}

/// Φ_q at (q, t) as a dense matrix.
#[must_use]
pub fn numeric(sys: &Symbolic, q: &[f64], t: f64) -> Vec<Vec<f64>> {
    let n = sys.unknowns.len();
    let roots: Vec<_> = sys.jac.iter().flatten().map(|&(_, e)| e).collect();
    let mut vals = sys.pool.eval(&roots, q, &[], t).into_iter();
    let mut m = vec![vec![0.0; n]; n];
    for (i, row) in sys.jac.iter().enumerate() {
        for &(j, _) in row {
            m[i][j] = vals.next().expect("one value per entry");
        }
    }
    m
}

/// The order Markowitz's rule with threshold pivoting picks for `a` (structure `s`), or `None`
/// when some step finds no non-zero candidate (`a` is singular).
#[must_use]
pub fn choose(s: &[Vec<bool>], a: &[Vec<f64>]) -> Option<Order> {
    let n = a.len();
    let mut s = s.to_vec();
    let mut v = a.to_vec();
    let (mut row_done, mut col_done) = (vec![false; n], vec![false; n]);
    let (mut rows, mut cols) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let active = |done: &[bool]| (0..n).filter(|&k| !done[k]).collect::<Vec<_>>();
        let (ar, ac) = (active(&row_done), active(&col_done));
        let row_count: Vec<usize> =
            (0..n).map(|i| ac.iter().filter(|&&j| s[i][j]).count()).collect();
        let mut best: Option<(usize, f64, usize, usize)> = None;
        for &j in &ac {
            let in_col: Vec<usize> = ar.iter().copied().filter(|&i| s[i][j]).collect();
            let big = in_col.iter().map(|&i| v[i][j].abs()).fold(0.0, f64::max);
            if big == 0.0 || !big.is_finite() {
                continue;
            }
            for &i in &in_col {
                let m = v[i][j].abs();
                if m < CHOICE_THRESHOLD * big {
                    continue;
                }
                let cost = (row_count[i] - 1) * (in_col.len() - 1);
                let ratio = m / big;
                // Fewest fill-in first, then the largest entry relative to its column (the most
                // margin along the motion), then the lowest column and row.
                let better = best.is_none_or(|(bc, br, bj, bi)| {
                    cost.cmp(&bc).then(br.total_cmp(&ratio)).then(j.cmp(&bj)).then(i.cmp(&bi))
                        == std::cmp::Ordering::Less
                });
                if better {
                    best = Some((cost, ratio, j, i));
                }
            }
        }
        let (_, _, pc, pr) = best?;
        for &i in &ar {
            if i == pr || !s[i][pc] {
                continue;
            }
            let l = v[i][pc] / v[pr][pc];
            for &j in &ac {
                if j != pc && s[pr][j] {
                    s[i][j] = true;
                    v[i][j] -= l * v[pr][j];
                }
            }
            v[i][pc] = l;
        }
        row_done[pr] = true;
        col_done[pc] = true;
        rows.push(pr);
        cols.push(pc);
    }
    let pattern = (0..n).map(|k| (0..n).filter(|&l| s[rows[k]][cols[l]]).collect()).collect();
    Some(Order { rows, cols, pattern })
}

/// The largest |multiplier| when `a` is factored with `order`, or `None` when a pivot is zero
/// or not finite.
#[must_use]
pub fn largest_multiplier(order: &Order, a: &[Vec<f64>]) -> Option<f64> {
    let n = a.len();
    let mut b: Vec<Vec<f64>> =
        (0..n).map(|k| (0..n).map(|l| a[order.rows[k]][order.cols[l]]).collect()).collect();
    let mut worst = 0.0_f64;
    for k in 0..n {
        let p = b[k][k];
        if p == 0.0 || !p.is_finite() {
            return None;
        }
        for i in k + 1..n {
            if !order.pattern[i].contains(&k) {
                continue;
            }
            let l = b[i][k] / p;
            worst = worst.max(l.abs());
            for &j in order.pattern[k].iter().filter(|&&j| j > k) {
                b[i][j] -= l * b[k][j];
            }
            b[i][k] = l;
        }
    }
    worst.is_finite().then_some(worst)
}

/// The configurations (t, reduced q) the generic engine computes over the description's grid,
/// or the assembled initial configuration when the analysis stops at once.
#[must_use]
pub fn motion(mech: &Mechanism, sys: &Symbolic) -> Vec<(f64, Vec<f64>)> {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let mut out = Vec::new();
    let _ = Analysis::new(&eq, &prep).run(|f| {
        out.push((f.t, sys.reduce(&eq, &f.q).as_slice().to_vec()));
        Ok::<(), ()>(())
    });
    if out.is_empty() {
        out.push((mech.time.start, sys.reduce(&eq, &prep.q).as_slice().to_vec()));
    }
    out
}

/// The static orders for the configurations `samples`: the first chosen at the first sample,
/// each further one at the first sample the orders so far do not cover.
#[must_use]
pub fn plan(sys: &Symbolic, samples: &[(f64, Vec<f64>)]) -> Vec<Order> {
    let s = structure(sys);
    let mut orders: Vec<Order> = Vec::new();
    for (t, q) in samples {
        if orders.len() == MAX_ORDERS {
            break;
        }
        let a = numeric(sys, q, *t);
        let covered = orders
            .iter()
            .any(|o| largest_multiplier(o, &a).is_some_and(|m| m <= 1.0 / COVER_THRESHOLD));
        if !covered && let Some(o) = choose(&s, &a) {
            orders.push(o);
        }
    }
    orders
}

/// `jac[r][c]` (or `lu[r][c]`).
fn entry(array: &str, r: usize, c: usize) -> Expr {
    let (a, r, c) = (ident(array), index(r), index(c));
    parse_quote!(#a[#r][#c])
}

/// The local holding entry (k, l) of L or U in step coordinates (the reciprocal of the pivot on
/// the diagonal).
fn local(k: usize, l: usize) -> Ident {
    if k == l {
        ident(&format!("d{k}"))
    } else if k > l {
        ident(&format!("l{k}_{l}"))
    } else {
        ident(&format!("u{k}_{l}"))
    }
}

/// A value in the factorisation: known when the code is generated (the constant entries of
/// Φ_q, and what is computed from constants only), or computed at run time.
///
/// Folding follows IEEE arithmetic exactly: constants are combined with the same operations
/// in the same order as the run time would, and only multiplications by ±1, negations of
/// negations and subtractions of negations (all exact) are rewritten.
#[derive(Clone)]
enum Val {
    Const(f64),
    Run(Expr, Prec),
}

impl Val {
    fn expr(&self, at_least: Prec) -> Expr {
        let (e, p) = match self {
            Val::Const(c) if *c < 0.0 => (literal_signed(*c), Prec::Unary),
            Val::Const(c) => (literal_signed(*c), Prec::Atom),
            Val::Run(e, p) => (e.clone(), *p),
        };
        if p >= at_least { e } else { paren(e) }
    }

    fn negated(&self) -> Val {
        match self {
            Val::Const(c) => Val::Const(-c),
            Val::Run(Expr::Unary(u), _) if matches!(u.op, syn::UnOp::Neg(_)) => {
                let inner = (*u.expr).clone();
                // The operand was printed at unary strength at least.
                let p = if matches!(inner, Expr::Binary(_) | Expr::Paren(_)) {
                    Prec::Atom
                } else {
                    Prec::Unary
                };
                Val::Run(inner, p)
            }
            Val::Run(..) => Val::Run(neg(self.expr(Prec::Unary)), Prec::Unary),
        }
    }

    fn is_negation(&self) -> bool {
        matches!(self, Val::Run(Expr::Unary(u), _) if matches!(u.op, syn::UnOp::Neg(_)))
    }

    fn mul(&self, other: &Val) -> Val {
        match (self, other) {
            (Val::Const(a), Val::Const(b)) => Val::Const(a * b),
            (Val::Const(c), v) | (v, Val::Const(c)) if *c == 1.0 => v.clone(),
            (Val::Const(c), v) | (v, Val::Const(c)) if *c == -1.0 => v.negated(),
            (a, b) => Val::Run(
                binary(
                    a.expr(Prec::Product),
                    syn::BinOp::Mul(Default::default()),
                    b.expr(Prec::Unary),
                ),
                Prec::Product,
            ),
        }
    }

    fn div(&self, other: &Val) -> Val {
        match (self, other) {
            (Val::Const(a), Val::Const(b)) => Val::Const(a / b),
            (a, b) => Val::Run(
                binary(
                    a.expr(Prec::Product),
                    syn::BinOp::Div(Default::default()),
                    b.expr(Prec::Unary),
                ),
                Prec::Product,
            ),
        }
    }

    fn sub(&self, other: &Val) -> Val {
        match (self, other) {
            (Val::Const(a), Val::Const(b)) => Val::Const(a - b),
            (a, b) if b.is_negation() => {
                let b = b.negated();
                Val::Run(
                    binary(
                        a.expr(Prec::Sum),
                        syn::BinOp::Add(Default::default()),
                        b.expr(Prec::Product),
                    ),
                    Prec::Sum,
                )
            }
            (a, b) => Val::Run(
                binary(
                    a.expr(Prec::Sum),
                    syn::BinOp::Sub(Default::default()),
                    b.expr(Prec::Product),
                ),
                Prec::Sum,
            ),
        }
    }
}

/// What the emitted factor does with entry (k, l) of L or U.
struct Factored {
    /// The value of every entry of the pattern, by step coordinates.
    vals: Vec<Vec<Option<Val>>>,
}

/// The straight-line factor and solve functions of one order.
pub struct Emitted {
    /// `factor_k`.
    pub factor: syn::Item,
    /// `solve_k`.
    pub solve: syn::Item,
}

/// Emits `factor_{which}` and `solve_{which}` for `order` (of at least one step) of the
/// Jacobian with structure `s`, where `constant[i][j]` is the value of entry (i, j) when it does
/// not depend on q or t.
///
/// # Panics
///
/// When a constant pivot is zero or a constant multiplier exceeds the run-time bound: an order
/// chosen by [`choose`] at any configuration never has one.
#[must_use]
pub fn emit(
    order: &Order,
    s: &[Vec<bool>],
    constant: &[Vec<Option<f64>>],
    which: usize,
) -> Emitted {
    let n = order.rows.len();
    let original = |k: usize, l: usize| -> Option<Val> {
        let (r, c) = (order.rows[k], order.cols[l]);
        s[r][c].then(|| match constant[r][c] {
            Some(v) => Val::Const(v),
            None => Val::Run(entry("jac", r, c), Prec::Atom),
        })
    };
    let mut f = Factored { vals: vec![vec![None; n]; n] };
    let mut stmts: Vec<syn::Stmt> = Vec::new();
    let mut fill = 0usize;
    // a_kl − Σ_m l_km u_ml over the m < min(k, l) where both are non-zero, in ascending m (the
    // order in which right-looking elimination applies the updates).
    // Entries whose value is that of Φ_q at the same place: `jac` holds them already.
    let mut kept = vec![vec![false; n]; n];
    let mut eliminated = |f: &Factored, kept: &mut Vec<Vec<bool>>, k: usize, l: usize| -> Val {
        let mut acc = original(k, l);
        fill += usize::from(acc.is_none());
        kept[k][l] = true;
        for &m in order.pattern[k].iter().filter(|&&m| m < k.min(l)) {
            let (Some(lkm), Some(uml)) = (&f.vals[k][m], &f.vals[m][l]) else { continue };
            let term = lkm.mul(uml);
            kept[k][l] = false;
            acc = Some(match acc {
                // A fill-in entry starts at 0, and 0 − x = −x exactly.
                None => term.negated(),
                Some(a) => a.sub(&term),
            });
        }
        acc.expect("an entry of the pattern is original or filled")
    };
    let bind = |stmts: &mut Vec<syn::Stmt>, name: Ident, v: Val| -> Val {
        match v {
            Val::Const(_) => v,
            Val::Run(..) => {
                let e = v.expr(Prec::Sum);
                stmts.push(parse_quote!(let #name = #e;));
                Val::Run(parse_quote!(#name), Prec::Atom)
            }
        }
    };
    // Each value computed at run time is stored as soon as it is known, so that it need not
    // stay in a register (or be spilled) until the end; no entry is read after its own place
    // has been written.
    let mut stored = 0usize;
    let mut store = |stmts: &mut Vec<syn::Stmt>, k: usize, l: usize, v: &Val| {
        if let Val::Run(e, _) = v {
            let target = entry("jac", order.rows[k], order.cols[l]);
            stmts.push(parse_quote!(#target = #e;));
            stored += 1;
        }
    };
    // The extremes of |pivot|: the constant pivots folded into one pair, the others
    // accumulated as they come (the first one declares the accumulators, at `first_run`).
    let mut known_pivots: Option<(f64, f64)> = None;
    let mut first_run: Option<(usize, Expr)> = None;
    let mut run_pivots = 0usize;
    for k in 0..n {
        // Row k of U (right of the pivot), then the pivot, then column k of L: every entry
        // read has been computed at an earlier step.
        for &l in order.pattern[k].iter().filter(|&&l| l > k) {
            let v = eliminated(&f, &mut kept, k, l);
            // An entry read unchanged is read where it is used (and not stored).
            let v = if kept[k][l] {
                v
            } else {
                let v = bind(&mut stmts, local(k, l), v);
                store(&mut stmts, k, l, &v);
                v
            };
            f.vals[k][l] = Some(v);
        }
        let p = eliminated(&f, &mut kept, k, k);
        // The diagonal holds the reciprocal of the pivot.
        kept[k][k] = false;
        let mut checks: Vec<Expr> = Vec::new();
        let d = match &p {
            Val::Const(c) => {
                assert!(c.is_finite() && *c != 0.0, "constant pivot {c} in order {which}");
                Val::Const(1.0 / c)
            }
            Val::Run(..) => {
                let pn = ident(&format!("p{k}"));
                let pivot = bind(&mut stmts, pn.clone(), p.clone());
                checks.push(parse_quote!(#pn.is_finite()));
                let d = bind(&mut stmts, local(k, k), Val::Const(1.0).div(&pivot));
                store(&mut stmts, k, k, &d);
                d
            }
        };
        f.vals[k][k] = Some(d.clone());
        for i in (k + 1..n).filter(|&i| order.pattern[i].contains(&k)) {
            let v = eliminated(&f, &mut kept, i, k);
            kept[i][k] &= matches!(d, Val::Const(c) if c == 1.0);
            let v = v.mul(&d);
            let v = if kept[i][k] {
                v
            } else {
                let v = bind(&mut stmts, local(i, k), v);
                store(&mut stmts, i, k, &v);
                v
            };
            match &v {
                Val::Const(c) => assert!(
                    c.abs() <= RUNTIME_MAX_MULTIPLIER,
                    "constant multiplier {c} in order {which}"
                ),
                Val::Run(e, _) => {
                    checks.push(parse_quote!(#e.abs() <= runtime::lu::MAX_MULTIPLIER))
                }
            }
            f.vals[i][k] = Some(v);
        }
        if let Some(ok) =
            checks.into_iter().reduce(|a, b| binary(a, syn::BinOp::And(Default::default()), b))
        {
            let ok = if matches!(ok, Expr::Binary(_)) { paren(ok) } else { ok };
            stmts.push(parse_quote! {
                if !#ok {
                    return None;
                }
            });
        }
        match &p {
            Val::Const(c) => {
                let c = c.abs();
                known_pivots = Some(known_pivots.map_or((c, c), |(lo, hi)| (lo.min(c), hi.max(c))));
            }
            Val::Run(..) => {
                let pn = ident(&format!("p{k}"));
                run_pivots += 1;
                if first_run.is_none() {
                    first_run = Some((stmts.len(), parse_quote!(#pn)));
                } else {
                    stmts.push(parse_quote!(smallest = smallest.min(#pn.abs());));
                    stmts.push(parse_quote!(largest = largest.max(#pn.abs());));
                }
            }
        }
    }
    if let Some((at, e)) = &first_run {
        let mutable = if run_pivots > 1 { quote::quote!(mut) } else { quote::quote!() };
        let (lo, hi) = match known_pivots {
            Some((lo, hi)) => {
                let (lo, hi) = (literal_signed(lo), literal_signed(hi));
                (quote::quote!(#e.abs().min(#lo)), quote::quote!(#e.abs().max(#hi)))
            }
            None => (quote::quote!(#e.abs()), quote::quote!(#e.abs())),
        };
        stmts.insert(*at, parse_quote!(let #mutable largest = #hi;));
        stmts.insert(*at, parse_quote!(let #mutable smallest = #lo;));
    }
    let extremes: Expr = match (run_pivots, known_pivots) {
        (0, Some((lo, hi))) => {
            let (lo, hi) = (literal_signed(lo), literal_signed(hi));
            parse_quote!(runtime::lu::PivotInfo { smallest: #lo, largest: #hi })
        }
        _ => parse_quote!(runtime::lu::PivotInfo { smallest, largest }),
    };
    let name = ident(&format!("factor_{which}"));
    let ops = operations(&stmts);
    let nnz = order.entries();
    let run_time = f.vals.iter().flatten().filter(|v| matches!(v, Some(Val::Run(..)))).count();
    let stored = stored;
    let known = nnz - run_time;
    let rows = list(&order.rows);
    let cols = list(&order.cols);
    let doc = format!(
        " Factors Φ_q in place with static pivot order {which}: step k pivots on row `[{rows}][k]` and column `[{cols}][k]`.\n\n L and U have {nnz} entries ({fill} of them fill-in, {} known when generated); {ops} operations. The others are in `jac`: {stored} stored there, with the reciprocals of the pivots on the diagonal, and {} left as Φ_q had them.\n\n Returns the smallest and largest |pivot|, or `None` when a pivot is not finite or a multiplier exceeds [`runtime::lu::MAX_MULTIPLIER`] in magnitude; `jac` is then partly factored and must be evaluated again.",
        known,
        run_time - stored
    );
    let factor: syn::Item = parse_quote! {
        #[doc = #doc]
        #[must_use]
        pub fn #name(jac: &mut [[f64; N]; N]) -> Option<runtime::lu::PivotInfo> {
            #(#stmts)*
            Some(#extremes)
        }
    };

    // Solve: y = L⁻¹ P b, then x = Q U⁻¹ y, with the factors known when generated as literals.
    let stored_val = |k: usize, l: usize| -> Val {
        match f.vals[k][l].as_ref().expect("in the pattern") {
            Val::Const(c) => Val::Const(*c),
            Val::Run(..) => Val::Run(entry("lu", order.rows[k], order.cols[l]), Prec::Atom),
        }
    };
    let mut stmts: Vec<syn::Stmt> = Vec::new();
    let named = |prefix: &str, k: usize| {
        let name = ident(&format!("{prefix}{k}"));
        Val::Run(parse_quote!(#name), Prec::Atom)
    };
    for k in 0..n {
        let r = index(order.rows[k]);
        let mut v = Val::Run(parse_quote!(b[#r]), Prec::Atom);
        for &l in order.pattern[k].iter().filter(|&&l| l < k) {
            v = v.sub(&stored_val(k, l).mul(&named("y", l)));
        }
        let y = ident(&format!("y{k}"));
        let e = v.expr(Prec::Sum);
        stmts.push(parse_quote!(let #y = #e;));
    }
    for k in (0..n).rev() {
        let mut v = named("y", k);
        for &l in order.pattern[k].iter().filter(|&&l| l > k) {
            v = v.sub(&stored_val(k, l).mul(&named("x", l)));
        }
        let v = v.mul(&stored_val(k, k));
        let x = ident(&format!("x{k}"));
        let e = v.expr(Prec::Sum);
        stmts.push(parse_quote!(let #x = #e;));
    }
    for k in 0..n {
        let x = ident(&format!("x{k}"));
        let c = index(order.cols[k]);
        stmts.push(parse_quote!(b[#c] = #x;));
    }
    let name = ident(&format!("solve_{which}"));
    let ops = operations(&stmts);
    let doc = format!(
        " Solves Φ_q x = b in place with the factors [`factor_{which}`] left in `lu`.\n\n {ops} operations."
    );
    let solve: syn::Item = parse_quote! {
        #[doc = #doc]
        pub fn #name(lu: &[[f64; N]; N], b: &mut [f64; N]) {
            #(#stmts)*
        }
    };
    Emitted { factor, solve }
}

/// The arithmetic operations (+, −, ×, ÷ and negation) in the `let` statements of `stmts`.
fn operations(stmts: &[syn::Stmt]) -> usize {
    fn count(e: &Expr) -> usize {
        match e {
            Expr::Binary(b) => {
                let arithmetic = matches!(
                    b.op,
                    syn::BinOp::Add(_)
                        | syn::BinOp::Sub(_)
                        | syn::BinOp::Mul(_)
                        | syn::BinOp::Div(_)
                );
                usize::from(arithmetic) + count(&b.left) + count(&b.right)
            }
            Expr::Unary(u) => usize::from(matches!(u.op, syn::UnOp::Neg(_))) + count(&u.expr),
            Expr::Paren(p) => count(&p.expr),
            _ => 0,
        }
    }
    stmts
        .iter()
        .filter_map(|s| match s {
            syn::Stmt::Local(l) => l.init.as_ref().map(|i| count(&i.expr)),
            _ => None,
        })
        .sum()
}

fn list(v: &[usize]) -> String {
    v.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests;
