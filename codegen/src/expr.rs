//! The expression IR of the code generator: a hash-consed arena of scalar expressions in the
//! unknowns q, their rates q̇ and the time t.
//!
//! Invariants (after egg's `RecExpr`): children are interned before their parents, so node
//! order is topological and every pass is one forward sweep; equal nodes share one id, so
//! common subexpressions are shared across Φ, Φ_q, ν and γ for free. The smart constructors
//! fold constants, drop neutral elements (x + 0, x·1), turn x·0 into 0 (all values are
//! finite by construction, so IEEE's 0·∞ = NaN cannot arise) and order the operands of
//! commutative operators by id, so that a·b and b·a are one node. A fold whose result would
//! overflow is not made: the operation stays in the expression, and evaluating it gives the
//! infinity that stops an analysis as a non-finite value, never a panic while generating.

use std::collections::HashMap;
use std::fmt;
use std::ops::Index;

/// A number type expressions evaluate in ([`ExprPool::eval_in`]): `f64` for the engines and
/// the generator, an extended-precision type for the reference solution (`crate::reference`).
pub trait Scalar:
    Copy
    + From<f64>
    + std::ops::Neg<Output = Self>
    + std::ops::Add<Output = Self>
    + std::ops::Mul<Output = Self>
{
    /// sin x.
    #[must_use]
    fn sin(self) -> Self;
    /// cos x.
    #[must_use]
    fn cos(self) -> Self;
}

impl Scalar for f64 {
    fn sin(self) -> Self {
        f64::sin(self)
    }
    fn cos(self) -> Self {
        f64::cos(self)
    }
}

/// Index of a node in an [`ExprPool`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ExprId(u32);

impl ExprId {
    /// The position of the node in the pool (topological order).
    #[must_use]
    pub fn index(self) -> usize {
        self.0 as usize
    }

    /// The id of the node at `index` (ids are indices).
    pub(crate) fn from_index(index: usize) -> Self {
        Self(u32::try_from(index).expect("fewer than 2³² nodes"))
    }
}

/// A leaf symbol.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Var {
    /// Unknown q_k.
    Q(u32),
    /// Rate q̇_k (appears only in γ and in outputs).
    Qd(u32),
    /// Acceleration q̈_k (outputs only: Φ, ν and γ never contain it).
    Qdd(u32),
    /// Time t.
    T,
    /// Input s_k of the k-th input driver (`law = "input"`), supplied at run time.
    S(u32),
    /// Its rate ṡ_k.
    Sd(u32),
    /// Its acceleration s̈_k.
    Sdd(u32),
    /// Parameter k of a function shared by several blocks: a constant whose value differs
    /// between them, read from their table at run time. Only the emitter's templates hold it
    /// (`emit::shared`), never a system's expressions; it evaluates to NaN.
    Param(u32),
}

/// One node of the arena.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Node {
    /// A finite constant, stored as bits with −0.0 normalised to 0.0.
    Const(u64),
    /// A symbol.
    Var(Var),
    /// −a.
    Neg(ExprId),
    /// a + b.
    Add(ExprId, ExprId),
    /// a · b.
    Mul(ExprId, ExprId),
    /// sin a.
    Sin(ExprId),
    /// cos a.
    Cos(ExprId),
}

impl Node {
    /// The children, in order.
    pub fn children(&self) -> impl Iterator<Item = ExprId> {
        let (a, b) = match *self {
            Self::Const(_) | Self::Var(_) => (None, None),
            Self::Neg(a) | Self::Sin(a) | Self::Cos(a) => (Some(a), None),
            Self::Add(a, b) | Self::Mul(a, b) => (Some(a), Some(b)),
        };
        a.into_iter().chain(b)
    }
}

/// The arena.
#[derive(Clone, Debug, Default)]
pub struct ExprPool {
    nodes: Vec<Node>,
    // Interning only: iteration order never reaches any output.
    #[allow(clippy::disallowed_types)]
    index: HashMap<Node, ExprId>,
    #[allow(clippy::disallowed_types)]
    derivatives: HashMap<(ExprId, Var), ExprId>,
    #[allow(clippy::disallowed_types)]
    rates: HashMap<ExprId, ExprId>,
}

impl Index<ExprId> for ExprPool {
    type Output = Node;
    fn index(&self, id: ExprId) -> &Node {
        &self.nodes[id.index()]
    }
}

impl ExprPool {
    /// An empty pool.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of nodes.
    #[must_use]
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether the pool is empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// All nodes in topological order.
    #[must_use]
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    fn intern(&mut self, node: Node) -> ExprId {
        if let Some(&id) = self.index.get(&node) {
            return id;
        }
        let id = ExprId(u32::try_from(self.nodes.len()).expect("fewer than 2³² nodes"));
        self.nodes.push(node);
        self.index.insert(node, id);
        id
    }

    /// `node` as it is, without folding or reordering (its children must be in the pool):
    /// for copying another pool's nodes one to one (the emitter's templates, `emit::shared`).
    pub(crate) fn node(&mut self, node: Node) -> ExprId {
        self.intern(node)
    }

    /// A constant.
    ///
    /// # Panics
    /// If `v` is not finite (descriptions are validated, so this is a bug).
    pub fn constant(&mut self, v: f64) -> ExprId {
        assert!(v.is_finite(), "expression constants are finite");
        let v = if v == 0.0 { 0.0 } else { v };
        self.intern(Node::Const(v.to_bits()))
    }

    /// A symbol.
    pub fn var(&mut self, v: Var) -> ExprId {
        self.intern(Node::Var(v))
    }

    /// The value of a constant node.
    #[must_use]
    pub fn as_const(&self, id: ExprId) -> Option<f64> {
        match self[id] {
            Node::Const(bits) => Some(f64::from_bits(bits)),
            _ => None,
        }
    }

    /// Whether a node is a constant or a symbol (no operation).
    #[must_use]
    pub fn is_leaf(&self, id: ExprId) -> bool {
        matches!(self[id], Node::Const(_) | Node::Var(_))
    }

    /// −a.
    pub fn neg(&mut self, a: ExprId) -> ExprId {
        match self[a] {
            Node::Const(_) => {
                let v = self.as_const(a).expect("constant");
                self.constant(-v)
            }
            Node::Neg(inner) => inner,
            _ => self.intern(Node::Neg(a)),
        }
    }

    /// a + b.
    pub fn add(&mut self, a: ExprId, b: ExprId) -> ExprId {
        match (self.as_const(a), self.as_const(b)) {
            (Some(x), Some(y)) if (x + y).is_finite() => return self.constant(x + y),
            (Some(0.0), None) => return b,
            (None, Some(0.0)) => return a,
            _ => {}
        }
        // a + (−a) = 0.
        if self[b] == Node::Neg(a) || self[a] == Node::Neg(b) {
            return self.constant(0.0);
        }
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        self.intern(Node::Add(a, b))
    }

    /// a − b.
    pub fn sub(&mut self, a: ExprId, b: ExprId) -> ExprId {
        let nb = self.neg(b);
        self.add(a, nb)
    }

    /// a · b.
    pub fn mul(&mut self, a: ExprId, b: ExprId) -> ExprId {
        match (self.as_const(a), self.as_const(b)) {
            (Some(x), Some(y)) if (x * y).is_finite() => return self.constant(x * y),
            (Some(0.0), _) | (_, Some(0.0)) => return self.constant(0.0),
            (Some(1.0), None) => return b,
            (None, Some(1.0)) => return a,
            (Some(-1.0), None) => return self.neg(b),
            (None, Some(-1.0)) => return self.neg(a),
            _ => {}
        }
        // Pull negations out so that −a·b and a·(−b) share the node a·b.
        match (self[a], self[b]) {
            (Node::Neg(x), Node::Neg(y)) => return self.mul(x, y),
            (Node::Neg(x), _) => {
                let m = self.mul(x, b);
                return self.neg(m);
            }
            (_, Node::Neg(y)) => {
                let m = self.mul(a, y);
                return self.neg(m);
            }
            _ => {}
        }
        // Constants times constant-scaled terms fold: c·(d·x) = (cd)·x.
        for (k, m) in [(a, b), (b, a)] {
            if let Some(c) = self.as_const(k)
                && let Node::Mul(x, y) = self[m]
                && let Some(d) = self.as_const(x)
                && (c * d).is_finite()
            {
                let cd = self.constant(c * d);
                return self.mul(cd, y);
            }
        }
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        // Keep a constant factor first (the pool orders constants by id otherwise).
        let (a, b) = if self.as_const(b).is_some() { (b, a) } else { (a, b) };
        self.intern(Node::Mul(a, b))
    }

    /// sin a.
    pub fn sin(&mut self, a: ExprId) -> ExprId {
        match self.as_const(a) {
            Some(x) => self.constant(x.sin()),
            None => self.intern(Node::Sin(a)),
        }
    }

    /// cos a.
    pub fn cos(&mut self, a: ExprId) -> ExprId {
        match self.as_const(a) {
            Some(x) => self.constant(x.cos()),
            None => self.intern(Node::Cos(a)),
        }
    }

    /// Σ terms (0 for none).
    pub fn sum(&mut self, terms: impl IntoIterator<Item = ExprId>) -> ExprId {
        let zero = self.constant(0.0);
        terms.into_iter().fold(zero, |acc, t| self.add(acc, t))
    }

    /// ∂e/∂v, memoised.
    pub fn diff(&mut self, e: ExprId, v: Var) -> ExprId {
        if let Some(&d) = self.derivatives.get(&(e, v)) {
            return d;
        }
        let d = match self[e] {
            Node::Const(_) => self.constant(0.0),
            Node::Var(w) => self.constant(if w == v { 1.0 } else { 0.0 }),
            Node::Neg(a) => {
                let da = self.diff(a, v);
                self.neg(da)
            }
            Node::Add(a, b) => {
                let (da, db) = (self.diff(a, v), self.diff(b, v));
                self.add(da, db)
            }
            Node::Mul(a, b) => {
                let (da, db) = (self.diff(a, v), self.diff(b, v));
                let (x, y) = (self.mul(da, b), self.mul(a, db));
                self.add(x, y)
            }
            Node::Sin(a) => {
                let da = self.diff(a, v);
                let c = self.cos(a);
                self.mul(c, da)
            }
            Node::Cos(a) => {
                let da = self.diff(a, v);
                let s = self.sin(a);
                let m = self.mul(s, da);
                self.neg(m)
            }
        };
        self.derivatives.insert((e, v), d);
        d
    }

    /// The total time derivative of `e` along the motion with q̈ = 0: q_k ↦ q̇_k, q̇_k ↦ 0,
    /// t ↦ 1, by the chain rule node by node (forward mode), memoised. One derivative node
    /// per node of `e`, so Φ̇ = Φ_q q̇ + Φ_t and Φ̈* = (Φ_q q̇)_q q̇ + 2 Φ_qt q̇ + Φ_tt stay the size
    /// of Φ instead of growing with the number of unknowns.
    pub fn rate(&mut self, e: ExprId) -> ExprId {
        if let Some(&d) = self.rates.get(&e) {
            return d;
        }
        let d = match self[e] {
            Node::Const(_) | Node::Var(Var::Qd(_) | Var::Qdd(_) | Var::Param(_)) => {
                self.constant(0.0)
            }
            Node::Var(Var::Q(k)) => self.var(Var::Qd(k)),
            Node::Var(Var::T) => self.constant(1.0),
            Node::Var(Var::S(k)) => self.var(Var::Sd(k)),
            Node::Var(Var::Sd(k)) => self.var(Var::Sdd(k)),
            // Φ holds s_k only (driver rows and driven coordinates), so Φ̇ holds ṡ_k and Φ̈*
            // s̈_k: the third derivative of an input never enters ν or γ.
            Node::Var(Var::Sdd(_)) => self.constant(0.0),
            Node::Neg(a) => {
                let da = self.rate(a);
                self.neg(da)
            }
            Node::Add(a, b) => {
                let (da, db) = (self.rate(a), self.rate(b));
                self.add(da, db)
            }
            Node::Mul(a, b) => {
                let (da, db) = (self.rate(a), self.rate(b));
                let (x, y) = (self.mul(da, b), self.mul(a, db));
                self.add(x, y)
            }
            Node::Sin(a) => {
                let da = self.rate(a);
                let c = self.cos(a);
                self.mul(c, da)
            }
            Node::Cos(a) => {
                let da = self.rate(a);
                let s = self.sin(a);
                let m = self.mul(s, da);
                self.neg(m)
            }
        };
        self.rates.insert(e, d);
        d
    }

    /// `e` with the variables of `map` replaced by their expressions, rebuilt through the
    /// folding constructors (so a replacement by a constant folds away what it zeroes).
    pub fn substitute(
        &mut self,
        e: ExprId,
        map: &std::collections::BTreeMap<Var, ExprId>,
    ) -> ExprId {
        // The nodes `e` reaches, children before parents (the arena is in topological order).
        let mut reached = std::collections::BTreeSet::new();
        let mut stack = vec![e];
        while let Some(x) = stack.pop() {
            if reached.insert(x) {
                stack.extend(self[x].children());
            }
        }
        let mut new: HashMap<ExprId, ExprId> = HashMap::with_capacity(reached.len());
        for x in reached {
            let y = match self[x] {
                Node::Var(v) => map.get(&v).copied().unwrap_or(x),
                Node::Const(_) => x,
                Node::Neg(a) => self.neg(new[&a]),
                Node::Add(a, b) => self.add(new[&a], new[&b]),
                Node::Mul(a, b) => self.mul(new[&a], new[&b]),
                Node::Sin(a) => self.sin(new[&a]),
                Node::Cos(a) => self.cos(new[&a]),
            };
            new.insert(x, y);
        }
        new[&e]
    }

    /// Marks the nodes reachable from `root` with `stamp` in `marks` (one entry per node) and
    /// returns how many of them are operations (not constants or variables) not marked before.
    pub fn new_operations(&self, root: ExprId, marks: &mut [u32], stamp: u32) -> usize {
        let mut stack = vec![root];
        let mut count = 0;
        while let Some(x) = stack.pop() {
            if std::mem::replace(&mut marks[x.index()], stamp) == stamp {
                continue;
            }
            if !matches!(self[x], Node::Const(_) | Node::Var(_)) {
                count += 1;
            }
            stack.extend(self[x].children());
        }
        count
    }

    /// Whether `e` depends on `v` (a cheap structural test used to skip zero derivatives).
    #[must_use]
    pub fn depends_on(&self, e: ExprId, v: Var) -> bool {
        let mut seen = vec![false; e.index() + 1];
        let mut stack = vec![e];
        while let Some(x) = stack.pop() {
            if std::mem::replace(&mut seen[x.index()], true) {
                continue;
            }
            match self[x] {
                Node::Var(w) if w == v => return true,
                node => stack.extend(node.children()),
            }
        }
        false
    }

    /// Evaluates `roots` numerically (tests and the generator's own checks).
    #[must_use]
    pub fn eval(&self, roots: &[ExprId], q: &[f64], qd: &[f64], t: f64) -> Vec<f64> {
        self.eval_with(roots, [q, qd, &[]], t)
    }

    /// [`ExprPool::eval`] with q̈ too: `state` is `[q, q̇, q̈]`.
    #[must_use]
    pub fn eval_with(&self, roots: &[ExprId], state: [&[f64]; 3], t: f64) -> Vec<f64> {
        self.eval_inputs(roots, state, t, &[])
    }

    /// [`ExprPool::eval_with`] with the inputs `[s, ṡ, s̈]` of the input drivers (an input
    /// symbol beyond `inputs` evaluates to NaN).
    #[must_use]
    pub fn eval_inputs(
        &self,
        roots: &[ExprId],
        state: [&[f64]; 3],
        t: f64,
        inputs: &[[f64; 3]],
    ) -> Vec<f64> {
        self.eval_in(roots, state, t, inputs)
    }

    /// [`ExprPool::eval_inputs`] over any [`Scalar`]: the same operations in the same order,
    /// each rounded as `T` rounds (constants are the pool's doubles, taken exactly).
    #[must_use]
    pub fn eval_in<T: Scalar>(
        &self,
        roots: &[ExprId],
        state: [&[T]; 3],
        t: T,
        inputs: &[[T; 3]],
    ) -> Vec<T> {
        let [q, qd, qdd] = state;
        let input = |k: u32, d: usize| inputs.get(k as usize).map_or(T::from(f64::NAN), |u| u[d]);
        let last = roots.iter().map(|r| r.index()).max().map_or(0, |m| m + 1);
        // Only nodes reachable from the roots are evaluated: others may name symbols (q̇)
        // the caller does not provide.
        let mut live = vec![false; last];
        let mut stack: Vec<ExprId> = roots.to_vec();
        while let Some(x) = stack.pop() {
            if !std::mem::replace(&mut live[x.index()], true) {
                stack.extend(self[x].children());
            }
        }
        let zero = T::from(0.0);
        let mut val = vec![zero; last];
        for (k, node) in self.nodes[..last].iter().enumerate() {
            if !live[k] {
                continue;
            }
            val[k] = match *node {
                Node::Const(bits) => T::from(f64::from_bits(bits)),
                Node::Var(Var::Q(i)) => q[i as usize],
                Node::Var(Var::Qd(i)) => qd[i as usize],
                Node::Var(Var::Qdd(i)) => qdd[i as usize],
                Node::Var(Var::T) => t,
                Node::Var(Var::S(k)) => input(k, 0),
                Node::Var(Var::Sd(k)) => input(k, 1),
                Node::Var(Var::Sdd(k)) => input(k, 2),
                Node::Var(Var::Param(_)) => T::from(f64::NAN),
                Node::Neg(a) => -val[a.index()],
                Node::Add(a, b) => val[a.index()] + val[b.index()],
                Node::Mul(a, b) => val[a.index()] * val[b.index()],
                Node::Sin(a) => val[a.index()].sin(),
                Node::Cos(a) => val[a.index()].cos(),
            };
        }
        roots.iter().map(|r| val[r.index()]).collect()
    }

    /// A displayable view of `e` in infix form.
    #[must_use]
    pub fn display(&self, e: ExprId) -> Display<'_> {
        Display { pool: self, e }
    }
}

/// Infix rendering of an expression (used by tests).
pub struct Display<'p> {
    pool: &'p ExprPool,
    e: ExprId,
}

impl fmt::Display for Display<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.pool;
        let sub = |e| Display { pool: p, e };
        match p[self.e] {
            Node::Const(bits) => write!(f, "{:?}", f64::from_bits(bits)),
            Node::Var(Var::Q(k)) => write!(f, "q{k}"),
            Node::Var(Var::Qd(k)) => write!(f, "qd{k}"),
            Node::Var(Var::Qdd(k)) => write!(f, "qdd{k}"),
            Node::Var(Var::T) => write!(f, "t"),
            Node::Var(Var::S(k)) => write!(f, "s{k}"),
            Node::Var(Var::Sd(k)) => write!(f, "sd{k}"),
            Node::Var(Var::Sdd(k)) => write!(f, "sdd{k}"),
            Node::Var(Var::Param(k)) => write!(f, "c{k}"),
            Node::Neg(a) => write!(f, "-({})", sub(a)),
            Node::Add(a, b) => write!(f, "({} + {})", sub(a), sub(b)),
            Node::Mul(a, b) => write!(f, "{} * {}", sub(a), sub(b)),
            Node::Sin(a) => write!(f, "sin({})", sub(a)),
            Node::Cos(a) => write!(f, "cos({})", sub(a)),
        }
    }
}

#[cfg(test)]
mod tests;
