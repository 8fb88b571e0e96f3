//! One emitted function per block *structure*: blocks whose code is the same up to numeric
//! constants and indices (the 34 loops of `benches/scale/rssr_loops_34.toml`, the links of a
//! chain, the arms of a robot) run one function, which reads what differs from a per-block
//! table, so that every copy runs the same machine code and stays in the instruction cache.
//!
//! The canonical form is decided on the expression IR, not on the token stream. A block
//! function's outputs are copied node by node (`ExprPool::node`, no folding, no reordering)
//! into a pool of their own, in a canonical order (depth first from the outputs in their
//! order, children in order), every constant becoming a parameter `Var::Param(i)` and every
//! unknown q_k and input s_k a local slot, numbered in order of first use; the outputs keep
//! their arrays (Φ, the packed Φ_q, the rotation coefficients) but not their indices. Two
//! blocks whose copies are equal node for node have isomorphic expression graphs, so the
//! copy with one block's constants and indices put back performs exactly that block's
//! floating-point operations in the same order: sharing changes no bit of any result, and
//! what is equal is decided on the same graph the emitter prints, with its shared
//! subexpressions. On the token stream the same decision would have to tell an index from a
//! constant in printed code, and the temporaries (numbered in pool order, which differs
//! between copies that share nodes with earlier blocks) would hide equal structures.
//!
//! What a group of blocks with one structure leaves to the table, slot by slot:
//! - a constant equal in every block stays an immediate; the others are read from a
//!   `static …_C: [[f64; C]; M]`, one row per block;
//! - an index equal in every block stays a literal; the indices that differ by one offset per
//!   block (`q[base + k]`, the usual case: the copies' unknowns, rows and packed entries lie
//!   alike) are read through a window `&q[base..base + W]` whose start is the block's entry of
//!   `static …_AT: [[usize; A]; M]` (one bounds check per window, none per entry); any other
//!   index is a column of that table of its own.
//!
//! What is shared, in a module solved by Newton block by block: the expression functions
//! `block_b` (Φ and Φ_q of the block's rows), `block_residual_b`, `rotation_b` (the closed
//! form's coefficients) and `rows_residual_k`, `rows_velocity_k` and `rows_acceleration_k`
//! (Φ, ν and γ of a run of blocks: an implicit or rotation block and the affine blocks after
//! it), of which `residual`, `velocity_rhs` and `acceleration_rhs` are made when some runs
//! share them ([`Sharing`], keyed on the IR as above); and the LU code of the blocks, Newton's
//! `factor_block`/`solve_block` arms and the parts of `factor_blocks`/`solve_blocks` for blocks
//! of two rows or more ([`Gathers`], keyed on the code with its indices as holes: that code
//! has no constants, and every index goes through a hole, so equal text is equal code).
//! Calls pass the block's place `m` among the blocks of its structure as a literal; the whole
//! Jacobian, Φ, ν and γ call each shared function in a loop over `m` (the blocks write apart).
//!
//! A structure with one block keeps today's function with immediates, so small or irregular
//! mechanisms emit what they did; with no structure shared by Φ, ν or γ, `residual`,
//! `velocity_rhs` and `acceleration_rhs` stay whole-system functions.

use std::collections::HashMap;

use syn::{Expr, parse_quote};

use super::function::{Reads, Signature, Used};
use super::syntax::{ident, index, literal_signed};
use crate::expr::{ExprId, ExprPool, Node, Var};

/// The array an output goes to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Array {
    /// Φ, `phi[r]`.
    Phi,
    /// Φ_q in its packed storage, `jac.as_flattened()[k]`.
    Jac,
    /// The coefficients of a rotation block, `k[i]`.
    K,
    /// ν, `nu[r]`.
    Nu,
    /// γ, `gamma[r]`.
    Gamma,
    /// The full coordinates of `expand`, `out.as_flattened_mut().as_flattened_mut()[k]` (k =
    /// 21 b + 7 d + i for body b's coordinate i, d = 0, 1, 2 its value, rate, acceleration).
    Out,
}

impl Array {
    fn name(self) -> &'static str {
        match self {
            Array::Phi => "phi",
            Array::Jac => "jac",
            Array::K => "k",
            Array::Nu => "nu",
            Array::Gamma => "gamma",
            Array::Out => "out",
        }
    }
}

/// One output of a block function: its array, its index there, and its value (`None`: the
/// literal 0, a structural zero of Φ_q the factors filled in).
pub(super) type Output = (Array, usize, Option<ExprId>);

/// A block function's code up to its constants and indices.
#[derive(PartialEq, Eq, Hash)]
struct Shape {
    nodes: Vec<Node>,
    outputs: Vec<(Array, Option<ExprId>)>,
}

/// What the shape leaves out, for one block: the values of its parameters, the unknowns and
/// inputs of its slots, the indices of its outputs.
struct Instance {
    constants: Vec<f64>,
    q: Vec<usize>,
    inputs: Vec<usize>,
    outputs: Vec<usize>,
}

/// Blocks of one shape.
struct Group {
    /// The blocks, increasing.
    members: Vec<usize>,
    /// The shape's nodes.
    pool: ExprPool,
    outputs: Vec<(Array, Option<ExprId>)>,
    /// Per member.
    instances: Vec<Instance>,
}

/// The blocks of one kind of function, grouped by shape.
pub(super) struct Sharing {
    groups: Vec<Group>,
    /// Per block: its group and its place among the members, when it has the function.
    of: Vec<Option<(usize, usize)>>,
    /// Per group: its number among the shared ones (two members or more).
    number: Vec<Option<usize>>,
}

/// A hash of the shape of the expression at `x`: its operations and the kinds of its leaves,
/// not their values or indices, commutative operands in the order of their shapes.
fn shape(pool: &ExprPool, x: ExprId, memo: &mut HashMap<ExprId, u64>) -> u64 {
    use std::hash::{Hash, Hasher};
    if let Some(&h) = memo.get(&x) {
        return h;
    }
    let mut stack = vec![(x, false)];
    while let Some((y, expanded)) = stack.pop() {
        if memo.contains_key(&y) {
            continue;
        }
        let children: Vec<ExprId> = pool[y].children().collect();
        if !expanded && children.iter().any(|c| !memo.contains_key(c)) {
            stack.push((y, true));
            stack.extend(children.iter().map(|&c| (c, false)));
            continue;
        }
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        let mut kids: Vec<u64> = children.iter().map(|c| memo[c]).collect();
        match pool[y] {
            Node::Const(_) => 0u8.hash(&mut hasher),
            Node::Var(Var::Q(_)) => 1u8.hash(&mut hasher),
            Node::Var(Var::Qd(_)) => 2u8.hash(&mut hasher),
            Node::Var(Var::Qdd(_)) => 3u8.hash(&mut hasher),
            Node::Var(Var::T) => 4u8.hash(&mut hasher),
            Node::Var(Var::S(_)) => 5u8.hash(&mut hasher),
            Node::Var(Var::Sd(_)) => 6u8.hash(&mut hasher),
            Node::Var(Var::Sdd(_)) => 7u8.hash(&mut hasher),
            Node::Var(Var::Param(_)) => 8u8.hash(&mut hasher),
            Node::Neg(_) => 9u8.hash(&mut hasher),
            Node::Add(..) => {
                kids.sort_unstable();
                10u8.hash(&mut hasher);
            }
            Node::Mul(..) => {
                kids.sort_unstable();
                11u8.hash(&mut hasher);
            }
            Node::Sin(_) => 12u8.hash(&mut hasher),
            Node::Cos(_) => 13u8.hash(&mut hasher),
        }
        kids.hash(&mut hasher);
        memo.insert(y, hasher.finish());
    }
    memo[&x]
}

/// A copy of `outputs` in a pool of its own (see the module docs), q_k and q̇_k in one slot,
/// or `None` when it reads q̈ (no block function does). Every use of a constant by a node is
/// a parameter of its own (two constants equal in one block may differ in another), and the
/// operands of a sum or a product are copied in the order of their shapes (the arena orders
/// them by id, which depends on what came before the block): both exact, since addition and
/// multiplication commute in floating point.
fn canonical(pool: &ExprPool, outputs: &[Output]) -> Option<(Shape, ExprPool, Instance)> {
    let mut copy = ExprPool::new();
    let mut map: HashMap<ExprId, ExprId> = HashMap::new();
    let mut shapes: HashMap<ExprId, u64> = HashMap::new();
    let mut constants: Vec<f64> = Vec::new();
    let (mut q, mut q_slot) = (Vec::new(), HashMap::new());
    let (mut inputs, mut input_slot) = (Vec::new(), HashMap::new());
    let slot = |k: u32, all: &mut Vec<usize>, slots: &mut HashMap<u32, u32>| -> u32 {
        *slots.entry(k).or_insert_with(|| {
            all.push(k as usize);
            u32::try_from(all.len() - 1).expect("fewer than 2³² slots")
        })
    };
    // The operands of `x` in canonical order.
    let operands = |x: ExprId, shapes: &mut HashMap<ExprId, u64>| -> Vec<ExprId> {
        let mut children: Vec<ExprId> = pool[x].children().collect();
        if matches!(pool[x], Node::Add(..) | Node::Mul(..)) {
            let keys: Vec<u64> = children.iter().map(|&c| shape(pool, c, shapes)).collect();
            if keys[1] < keys[0] {
                children.swap(0, 1);
            }
        }
        children
    };
    let mut roots = Vec::with_capacity(outputs.len());
    for &(array, _, value) in outputs {
        let Some(root) = value else {
            roots.push((array, None));
            continue;
        };
        if let Node::Const(bits) = pool[root] {
            // A constant output: a parameter of its own too.
            constants.push(f64::from_bits(bits));
            let k = u32::try_from(constants.len() - 1).expect("fewer than 2³² constants");
            roots.push((array, Some(copy.node(Node::Var(Var::Param(k))))));
            continue;
        }
        let mut stack = vec![(root, false)];
        while let Some((x, expanded)) = stack.pop() {
            if map.contains_key(&x) {
                continue;
            }
            let children = operands(x, &mut shapes);
            if !expanded {
                stack.push((x, true));
                stack.extend(
                    children
                        .iter()
                        .rev()
                        .filter(|&&c| !matches!(pool[c], Node::Const(_)))
                        .map(|&c| (c, false)),
                );
                continue;
            }
            // A constant child: a parameter of its own.
            let mut child = |c: ExprId| -> ExprId {
                if let Node::Const(bits) = pool[c] {
                    constants.push(f64::from_bits(bits));
                    let k = u32::try_from(constants.len() - 1).expect("fewer than 2³² constants");
                    copy.node(Node::Var(Var::Param(k)))
                } else {
                    map[&c]
                }
            };
            let node = match pool[x] {
                Node::Const(_) => {
                    let c = child(x);
                    map.insert(x, c);
                    continue;
                }
                Node::Var(Var::Q(k)) => Node::Var(Var::Q(slot(k, &mut q, &mut q_slot))),
                Node::Var(Var::Qd(k)) => Node::Var(Var::Qd(slot(k, &mut q, &mut q_slot))),
                Node::Var(Var::T) => Node::Var(Var::T),
                Node::Var(Var::S(k)) => Node::Var(Var::S(slot(k, &mut inputs, &mut input_slot))),
                Node::Var(Var::Sd(k)) => Node::Var(Var::Sd(slot(k, &mut inputs, &mut input_slot))),
                Node::Var(Var::Sdd(k)) => {
                    Node::Var(Var::Sdd(slot(k, &mut inputs, &mut input_slot)))
                }
                Node::Var(Var::Qdd(_) | Var::Param(_)) => return None,
                Node::Neg(_) => Node::Neg(child(children[0])),
                Node::Add(..) => Node::Add(child(children[0]), child(children[1])),
                Node::Mul(..) => Node::Mul(child(children[0]), child(children[1])),
                Node::Sin(_) => Node::Sin(child(children[0])),
                Node::Cos(_) => Node::Cos(child(children[0])),
            };
            map.insert(x, copy.node(node));
        }
        roots.push((array, Some(map[&root])));
    }
    let shape = Shape { nodes: copy.nodes().to_vec(), outputs: roots };
    let instance =
        Instance { constants, q, inputs, outputs: outputs.iter().map(|&(_, at, _)| at).collect() };
    Some((shape, copy, instance))
}

impl Sharing {
    /// The blocks' functions (`None` for a block without one) grouped by shape, groups in the
    /// order of their first block.
    pub(super) fn of(pool: &ExprPool, functions: &[Option<Vec<Output>>]) -> Sharing {
        let mut groups: Vec<Group> = Vec::new();
        let mut by_shape: HashMap<Shape, usize> = HashMap::new();
        let mut of = vec![None; functions.len()];
        for (b, outputs) in functions.iter().enumerate() {
            let Some((shape, copy, instance)) =
                outputs.as_ref().and_then(|outputs| canonical(pool, outputs))
            else {
                continue;
            };
            let g = match by_shape.get(&shape) {
                Some(&g) => g,
                None => {
                    groups.push(Group {
                        members: Vec::new(),
                        pool: copy,
                        outputs: shape.outputs.clone(),
                        instances: Vec::new(),
                    });
                    by_shape.insert(shape, groups.len() - 1);
                    groups.len() - 1
                }
            };
            of[b] = Some((g, groups[g].members.len()));
            groups[g].members.push(b);
            groups[g].instances.push(instance);
        }
        let mut count = 0;
        let number = groups
            .iter()
            .map(|g| {
                (g.members.len() > 1).then(|| {
                    count += 1;
                    count - 1
                })
            })
            .collect();
        Sharing { groups, of, number }
    }

    /// Whether some blocks share a function.
    pub(super) fn any(&self) -> bool {
        self.number.iter().any(Option::is_some)
    }

    /// No sharing: every block its own function.
    pub(super) fn none(blocks: usize) -> Sharing {
        Sharing { groups: Vec::new(), of: vec![None; blocks], number: Vec::new() }
    }

    /// For a block whose function is shared: the shared function's number and the block's
    /// place among its members (the `m` it is called with).
    pub(super) fn shared(&self, b: usize) -> Option<(usize, usize)> {
        let (g, m) = self.of[b]?;
        Some((self.number[g]?, m))
    }

    /// The call of block `b`'s function, named `name_b` or `name_shared_s(m, …)`, with
    /// `args` after the member.
    pub(super) fn call(
        &self,
        name: &str,
        b: usize,
        args: &proc_macro2::TokenStream,
    ) -> proc_macro2::TokenStream {
        match self.shared(b) {
            Some((s, m)) => {
                let (f, m) = (ident(&format!("{name}_shared_{s}")), index(m));
                quote::quote!(#f(#m, #args))
            }
            None => {
                let f = ident(&format!("{name}_{b}"));
                quote::quote!(#f(#args))
            }
        }
    }

    /// The calls of every block's function in turn (`name_b(args)`), each shared function
    /// called once for all its blocks, `for m in 0..M`, where its first block comes: the
    /// blocks write apart, so their order does not matter.
    pub(super) fn calls_all(
        &self,
        name: &str,
        args: &proc_macro2::TokenStream,
    ) -> Vec<proc_macro2::TokenStream> {
        let mut calls = Vec::new();
        for (b, of) in self.of.iter().enumerate() {
            match (self.shared(b), of) {
                (Some((s, 0)), Some((g, _))) => calls.push(self.loop_call(name, *g, s, args)),
                (Some(_), _) => {}
                (None, _) => {
                    let f = ident(&format!("{name}_{b}"));
                    calls.push(quote::quote!(#f(#args);));
                }
            }
        }
        calls
    }

    /// The calls of the shared functions alone, each `for m in 0..M` (see [`Sharing::calls_all`]).
    pub(super) fn calls_shared(
        &self,
        name: &str,
        args: &proc_macro2::TokenStream,
    ) -> Vec<proc_macro2::TokenStream> {
        (0..self.groups.len())
            .filter_map(|g| Some(self.loop_call(name, g, self.number[g]?, args)))
            .collect()
    }

    /// `for m in 0..M { name_shared_s(m, args); }` for group `g`, shared function `s`.
    fn loop_call(
        &self,
        name: &str,
        g: usize,
        s: usize,
        args: &proc_macro2::TokenStream,
    ) -> proc_macro2::TokenStream {
        let f = ident(&format!("{name}_shared_{s}"));
        let count = index(self.groups[g].members.len());
        quote::quote!(for m in 0..#count { #f(m, #args); })
    }

    /// The shared functions `name_shared_s` with their tables, for the signature `sig` (its
    /// targets among "phi", "jac" and "k"), each documented as doing `what` for its blocks.
    pub(super) fn items(&self, name: &str, sig: &Signature<'_>, what: &str) -> Vec<syn::Item> {
        let mut items = Vec::new();
        for (g, group) in self.groups.iter().enumerate() {
            if let Some(s) = self.number[g] {
                items.extend(group.items(&format!("{name}_shared_{s}"), sig, what));
            }
        }
        items
    }
}

/// Where a shared function finds one slot of an array.
#[derive(Clone, Copy)]
enum Place {
    /// The same index in every block: a literal.
    Fixed(usize),
    /// At this offset in the block's window `w` (of [`Indexing::windows`]).
    Window { w: usize, offset: usize },
    /// At the index in this column of the block's row of the `…_AT` table.
    Column(usize),
}

/// How a shared function indexes one array: its slots' places, and its windows (the column
/// of their start in the `…_AT` table, and their width).
struct Indexing {
    places: Vec<Place>,
    windows: Vec<(usize, usize)>,
}

/// The places of the slots whose values, per member, are `values`, adding the columns they
/// need to the members' rows of the index table `table`: the slots that move alike from block
/// to block (the same difference to the first block's index, block by block) share a window
/// when there are two or more of them.
fn indexing(values: &[&[usize]], table: &mut [Vec<usize>]) -> Indexing {
    let slots = values[0].len();
    let moves = |j: usize| -> Vec<usize> {
        values.iter().map(|v| v[j].wrapping_sub(values[0][j])).collect()
    };
    let mut classes: Vec<(Vec<usize>, Vec<usize>)> = Vec::new();
    let mut places: Vec<Place> = (0..slots).map(|j| Place::Fixed(values[0][j])).collect();
    for j in 0..slots {
        let m = moves(j);
        if m.iter().all(|&d| d == 0) {
            continue;
        }
        match classes.iter_mut().find(|(k, _)| *k == m) {
            Some((_, members)) => members.push(j),
            None => classes.push((m, vec![j])),
        }
    }
    let mut windows = Vec::new();
    for (_, class) in &classes {
        let column = table[0].len();
        let start = |v: &[usize]| class.iter().map(|&j| v[j]).min().expect("a slot");
        for (row, v) in table.iter_mut().zip(values) {
            row.push(start(v));
        }
        if let [j] = class.as_slice() {
            places[*j] = Place::Column(column);
            continue;
        }
        let mut width = 0;
        for &j in class {
            let offset = values[0][j] - start(values[0]);
            places[j] = Place::Window { w: windows.len(), offset };
            width = width.max(offset + 1);
        }
        windows.push((column, width));
    }
    Indexing { places, windows }
}

/// `at[c]`, or `at[c] + offset`.
fn at(column: usize, offset: usize) -> Expr {
    let c = index(column);
    if offset == 0 {
        parse_quote!(at[#c])
    } else {
        let o = index(offset);
        parse_quote!(at[#c] + #o)
    }
}

impl Group {
    /// The function `name` (its first parameter `m`, the member) and its tables.
    fn items(&self, name: &str, sig: &Signature<'_>, what: &str) -> Vec<syn::Item> {
        let members = self.instances.len();
        let upper = name.to_uppercase();
        let (constants_name, at_name) =
            (ident(&format!("{upper}_C")), ident(&format!("{upper}_AT")));
        // Constants: equal in every block, immediates; else columns of the table.
        let count = self.instances[0].constants.len();
        let uniform: Vec<bool> = (0..count)
            .map(|i| {
                let v = self.instances[0].constants[i].to_bits();
                self.instances.iter().all(|x| x.constants[i].to_bits() == v)
            })
            .collect();
        let mut column_of = vec![None; count];
        let mut columns = 0;
        for i in (0..count).filter(|&i| !uniform[i]) {
            column_of[i] = Some(columns);
            columns += 1;
        }
        let mut pool = ExprPool::new();
        let mut map = Vec::with_capacity(self.pool.len());
        for &node in self.pool.nodes() {
            let remap = |x: ExprId| map[x.index()];
            let node = match node {
                Node::Var(Var::Param(i)) if uniform[i as usize] => {
                    Node::Const(self.instances[0].constants[i as usize].to_bits())
                }
                Node::Neg(a) => Node::Neg(remap(a)),
                Node::Add(a, b) => Node::Add(remap(a), remap(b)),
                Node::Mul(a, b) => Node::Mul(remap(a), remap(b)),
                Node::Sin(a) => Node::Sin(remap(a)),
                Node::Cos(a) => Node::Cos(remap(a)),
                leaf => leaf,
            };
            map.push(pool.node(node));
        }
        // Indices: per array, the places of its slots.
        let mut table: Vec<Vec<usize>> = vec![Vec::new(); members];
        let q_values: Vec<&[usize]> = self.instances.iter().map(|x| x.q.as_slice()).collect();
        let q = indexing(&q_values, &mut table);
        let u_values: Vec<&[usize]> = self.instances.iter().map(|x| x.inputs.as_slice()).collect();
        let u = indexing(&u_values, &mut table);
        let mut outputs = Vec::new();
        for array in [Array::Phi, Array::Jac, Array::K, Array::Nu, Array::Gamma, Array::Out] {
            let slots: Vec<usize> =
                (0..self.outputs.len()).filter(|&o| self.outputs[o].0 == array).collect();
            if slots.is_empty() {
                continue;
            }
            let values: Vec<Vec<usize>> = self
                .instances
                .iter()
                .map(|x| slots.iter().map(|&o| x.outputs[o]).collect())
                .collect();
            let values: Vec<&[usize]> = values.iter().map(Vec::as_slice).collect();
            outputs.push((array, slots, indexing(&values, &mut table)));
        }
        let mut stmts: Vec<syn::Stmt> = Vec::new();
        let width = table[0].len();
        if width > 0 {
            stmts.push(parse_quote!(let at = &#at_name[m];));
        }
        // The windows of q and q̇ the code reads.
        let mut read = std::collections::BTreeSet::new();
        for node in pool.nodes() {
            if let Node::Var(Var::Q(j) | Var::Qd(j)) = *node
                && let Place::Window { w, .. } = q.places[j as usize]
            {
                let rate = matches!(node, Node::Var(Var::Qd(_)));
                read.insert((rate, w));
            }
        }
        for (rate, k) in read {
            let (c, w) = q.windows[k];
            let (start, end) = (at(c, 0), at(c, w));
            let (array, name) = if rate { ("qd", "qd_window") } else { ("q", "window") };
            let (array, name) = (ident(array), ident(&format!("{name}{k}")));
            stmts.push(parse_quote!(let #name = &#array[#start..#end];));
        }
        // The outputs' targets; an array's window when every slot is in it, else whole.
        let mut targets: Vec<Option<Expr>> = vec![None; self.outputs.len()];
        for (array, slots, indexing) in &outputs {
            let a = ident(array.name());
            // Φ_q's packed rows and `expand`'s bodies are written through their flat storage.
            let flat: Option<Expr> = match array {
                Array::Jac => Some(parse_quote!(#a.as_flattened_mut())),
                Array::Out => Some(parse_quote!(#a.as_flattened_mut().as_flattened_mut())),
                _ => None,
            };
            let windowed = indexing.windows.len() == 1
                && indexing.places.iter().all(|p| matches!(p, Place::Window { .. }));
            match (windowed, indexing.windows.first(), &flat) {
                (true, Some(&(c, w)), Some(flat)) => {
                    let (start, end) = (at(c, 0), at(c, w));
                    stmts.push(parse_quote!(let #a = &mut #flat[#start..#end];));
                }
                (true, Some(&(c, w)), None) => {
                    let (start, end) = (at(c, 0), at(c, w));
                    stmts.push(parse_quote!(let #a = &mut #a[#start..#end];));
                }
                (_, _, Some(flat)) => stmts.push(parse_quote!(let #a = #flat;)),
                _ => {}
            }
            for (&o, place) in slots.iter().zip(&indexing.places) {
                let i: Expr = match (*place, windowed) {
                    (Place::Fixed(k), _) => {
                        let k = index(k);
                        parse_quote!(#k)
                    }
                    (Place::Window { offset, .. }, true) => {
                        let k = index(offset);
                        parse_quote!(#k)
                    }
                    (Place::Window { w, offset }, false) => at(indexing.windows[w].0, offset),
                    (Place::Column(c), _) => at(c, 0),
                };
                targets[o] = Some(parse_quote!(#a[#i]));
            }
        }
        let places_q = &q.places;
        let read = |array: &str, k: usize| -> Expr {
            match array {
                "c" => {
                    let c = index(column_of[k].expect("a parameter varies"));
                    parse_quote!(c[#c])
                }
                "u" => match u.places[k] {
                    Place::Fixed(i) => {
                        let i = index(i);
                        parse_quote!(u[#i])
                    }
                    Place::Window { w, offset } => {
                        let i = at(u.windows[w].0, offset);
                        parse_quote!(u[#i])
                    }
                    Place::Column(c) => {
                        let i = at(c, 0);
                        parse_quote!(u[#i])
                    }
                },
                _ => {
                    let (q, window) =
                        if array == "qd" { ("qd", "qd_window") } else { ("q", "window") };
                    let q = ident(q);
                    match places_q[k] {
                        Place::Fixed(i) => {
                            let i = index(i);
                            parse_quote!(#q[#i])
                        }
                        Place::Window { w, offset } => {
                            let (i, name) = (index(offset), ident(&format!("{window}{w}")));
                            parse_quote!(#name[#i])
                        }
                        Place::Column(c) => {
                            let i = at(c, 0);
                            parse_quote!(#q[#i])
                        }
                    }
                }
            }
        };
        if columns > 0 {
            stmts.push(parse_quote!(let c = &#constants_name[m];));
        }
        let values: Vec<(Expr, ExprId, Option<usize>)> = self
            .outputs
            .iter()
            .zip(&targets)
            .filter_map(|(&(_, value), target)| {
                value.map(|v| (target.clone().expect("a target"), map[v.index()], None))
            })
            .collect();
        let f = super::function::function_reading(
            &pool,
            self.instances[0].q.len(),
            &values,
            &Reads::With(&read),
            &super::function::Given::new(),
            &super::function::Given::new(),
        );
        let zeros = self.outputs.iter().zip(&targets).filter(|((_, v), _)| v.is_none()).map(
            |(_, target)| -> syn::Stmt {
                let target = target.clone().expect("a target");
                parse_quote!(#target = 0.0;)
            },
        );
        let zeros: Vec<syn::Stmt> = zeros.collect();
        let ops = f.ops;
        let arrays = vec![true; sig.targets.len()];
        let used = Used::of(&f, &arrays);
        let list = self.members.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ");
        let doc = format!(
            " {what} of the `m`th of blocks {list} (one structure: the same code up to the constants in `{constants_name}` and the places in `{at_name}`): {ops} operations."
        );
        let mut item = sig.item(&ident(name), &doc, &used, true);
        // A function the same for all its blocks (nothing in the tables) ignores `m`.
        let m = super::syntax::param("m", width > 0 || columns > 0);
        item.sig.inputs.insert(0, parse_quote!(#m: usize));
        stmts.extend(f.stmts);
        stmts.extend(zeros);
        let mut items = Vec::new();
        if columns > 0 {
            let (len, columns_lit) = (index(members), index(columns));
            let rows = self.instances.iter().map(|x| {
                let values =
                    (0..count).filter(|&i| !uniform[i]).map(|i| literal_signed(x.constants[i]));
                quote::quote!([#(#values),*])
            });
            let doc = format!(
                " The constants of `{name}` that differ between its blocks, one row per block."
            );
            items.push(parse_quote! {
                #[doc = #doc]
                static #constants_name: [[f64; #columns_lit]; #len] = [#(#rows),*];
            });
        }
        if width > 0 {
            let (len, width_lit) = (index(members), index(width));
            let rows = table.iter().map(|row| {
                let row = row.iter().map(|&k| index(k));
                quote::quote!([#(#row),*])
            });
            let doc = format!(
                " Where `{name}` reads and writes for each of its blocks: the starts of its windows and the indices that do not move with them, one row per block."
            );
            items.push(parse_quote! {
                #[doc = #doc]
                static #at_name: [[usize; #width_lit]; #len] = [#(#rows),*];
            });
        }
        items.push(super::syntax::item_fn(item, stmts));
        items
    }
}

/// One array an index-only shared function reads or writes.
pub(super) struct Slice {
    /// Its parameter's name.
    pub(super) name: &'static str,
    /// Whether it is `[[f64; N]; N]`, indexed flat.
    pub(super) square: bool,
    /// Whether the function writes it.
    pub(super) mutable: bool,
}

/// The code of one block built with its indices as holes: `hole(a, k)` is the element of
/// array `a` (an index into the slices) at index k.
pub(super) type Build<'a> =
    dyn Fn(usize, &mut dyn FnMut(usize, usize) -> Expr) -> proc_macro2::TokenStream + 'a;

/// Index-only code (the blocks' LU: gathers, scatters, row orders, substitutions) shared by
/// blocks whose code is the same token for token once its indices are holes: there a
/// token-stream key is sound, since every index goes through a hole and nothing else varies.
/// Per array, the indices of one block's holes in order.
type Holes = Vec<Vec<usize>>;

pub(super) struct Gathers {
    /// Per group: its blocks and, per block, its holes.
    groups: Vec<(Vec<usize>, Vec<Holes>)>,
    of: Vec<Option<(usize, usize)>>,
    number: Vec<Option<usize>>,
}

impl Gathers {
    /// The code `build` gives the blocks `candidates` (of `blocks` in all), grouped; with
    /// `also`, blocks are grouped together only when the code it gives them is alike too (so
    /// that two kinds of functions, a block's factors and its solve, share alike).
    pub(super) fn of(
        blocks: usize,
        candidates: &[usize],
        slices: usize,
        build: &Build<'_>,
        also: Option<&Build<'_>>,
    ) -> Gathers {
        let mut groups: Vec<(Vec<usize>, Vec<Holes>)> = Vec::new();
        let mut by_key: HashMap<String, usize> = HashMap::new();
        let mut of = vec![None; blocks];
        for &b in candidates {
            let mut values = vec![Vec::new(); slices];
            let code = build(b, &mut |a, k| {
                values[a].push(k);
                let a = ident(&format!("a{a}"));
                parse_quote!(#a[0])
            });
            let mut key = code.to_string();
            if let Some(also) = also {
                key.push_str(" ;; ");
                key.push_str(&also(b, &mut |_, _| parse_quote!(x[0])).to_string());
            }
            let g = *by_key.entry(key).or_insert_with(|| {
                groups.push((Vec::new(), Vec::new()));
                groups.len() - 1
            });
            of[b] = Some((g, groups[g].0.len()));
            groups[g].0.push(b);
            groups[g].1.push(values);
        }
        let mut count = 0;
        let number = groups
            .iter()
            .map(|g| {
                (g.0.len() > 1).then(|| {
                    count += 1;
                    count - 1
                })
            })
            .collect();
        Gathers { groups, of, number }
    }

    /// No sharing.
    pub(super) fn none(blocks: usize) -> Gathers {
        Gathers { groups: Vec::new(), of: vec![None; blocks], number: Vec::new() }
    }

    /// For a block whose code is shared: the shared function's number and the block's place
    /// among its members.
    pub(super) fn shared(&self, b: usize) -> Option<(usize, usize)> {
        let (g, m) = self.of[b]?;
        Some((self.number[g]?, m))
    }

    /// `name_shared_s(m, args)` for block `b`, whose code is shared.
    pub(super) fn call(
        &self,
        name: &str,
        b: usize,
        args: &proc_macro2::TokenStream,
    ) -> Option<proc_macro2::TokenStream> {
        let (s, m) = self.shared(b)?;
        let (f, m) = (ident(&format!("{name}_shared_{s}")), index(m));
        Some(quote::quote!(#f(#m, #args)))
    }

    /// The shared functions `name_shared_s(m: usize, params) -> output` and their index
    /// tables, each doing `what` for the `m`th of its blocks.
    pub(super) fn items(
        &self,
        name: &str,
        slices: &[Slice],
        params: &proc_macro2::TokenStream,
        output: &proc_macro2::TokenStream,
        what: &str,
        build: &Build<'_>,
    ) -> Vec<syn::Item> {
        let mut items = Vec::new();
        for (g, (members, values)) in self.groups.iter().enumerate() {
            let Some(s) = self.number[g] else { continue };
            let name = format!("{name}_shared_{s}");
            let at_name = ident(&format!("{}_AT", name.to_uppercase()));
            let mut table: Vec<Vec<usize>> = vec![Vec::new(); members.len()];
            let mut stmts: Vec<proc_macro2::TokenStream> = Vec::new();
            let mut elements: Vec<Vec<Expr>> = Vec::new();
            for (a, slice) in slices.iter().enumerate() {
                let per: Vec<&[usize]> = values.iter().map(|v| v[a].as_slice()).collect();
                let array = ident(slice.name);
                if per[0].is_empty() {
                    elements.push(Vec::new());
                    continue;
                }
                let ix = indexing(&per, &mut table);
                let windowed = ix.windows.len() == 1
                    && ix.places.iter().all(|p| matches!(p, Place::Window { .. }));
                let flat = match (slice.square, slice.mutable) {
                    (true, true) => quote::quote!(#array.as_flattened_mut()),
                    (true, false) => quote::quote!(#array.as_flattened()),
                    (false, _) => quote::quote!(#array),
                };
                if windowed {
                    let (c, w) = ix.windows[0];
                    let (start, end) = (at(c, 0), at(c, w));
                    let borrow = if slice.mutable { quote::quote!(&mut) } else { quote::quote!(&) };
                    stmts.push(quote::quote!(let #array = #borrow #flat[#start..#end];));
                } else if slice.square {
                    stmts.push(quote::quote!(let #array = #flat;));
                }
                elements.push(
                    ix.places
                        .iter()
                        .map(|&place| -> Expr {
                            let i: Expr = match place {
                                Place::Fixed(k) => {
                                    let k = index(k);
                                    parse_quote!(#k)
                                }
                                Place::Window { offset, .. } if windowed => {
                                    let k = index(offset);
                                    parse_quote!(#k)
                                }
                                Place::Window { w, offset } => at(ix.windows[w].0, offset),
                                Place::Column(c) => at(c, 0),
                            };
                            parse_quote!(#array[#i])
                        })
                        .collect(),
                );
            }
            let mut next = vec![0; slices.len()];
            let body = build(members[0], &mut |a, _| {
                next[a] += 1;
                elements[a][next[a] - 1].clone()
            });
            let width = table[0].len();
            let f = ident(&name);
            let list = members.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ");
            let doc = format!(
                " {what} for the `m`th of blocks {list} (one structure: the same code up to the places in `{at_name}`)."
            );
            if width > 0 {
                let (len, width) = (index(members.len()), index(width));
                let rows = table.iter().map(|row| {
                    let row = row.iter().map(|&k| index(k));
                    quote::quote!([#(#row),*])
                });
                let doc = format!(
                    " Where `{name}` reads and writes for each of its blocks: the starts of its windows and the indices that do not move with them, one row per block."
                );
                items.push(parse_quote! {
                    #[doc = #doc]
                    static #at_name: [[usize; #width]; #len] = [#(#rows),*];
                });
                stmts.insert(0, quote::quote!(let at = &#at_name[m];));
            }
            let m = super::syntax::param("m", width > 0);
            items.push(parse_quote! {
                #[doc = #doc]
                #[inline(never)]
                fn #f(#m: usize, #params) #output {
                    #(#stmts)*
                    #body
                }
            });
        }
        items
    }
}
