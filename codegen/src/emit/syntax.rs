//! Syntax helpers: syn nodes for names, literals, operators, statements and items, built
//! directly rather than parsed from tokens (parsing costs more than the rest of the emission
//! for large mechanisms).

use proc_macro2::{Literal, Span};
use syn::{Expr, Ident, parse_quote};

/// Binding strength of an emitted expression.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Prec {
    Sum = 1,
    Product = 2,
    Unary = 3,
    Atom = 4,
}

pub(super) fn ident(name: &str) -> Ident {
    Ident::new(name, Span::call_site())
}

pub(super) fn paren(e: Expr) -> Expr {
    Expr::Paren(syn::ExprParen {
        attrs: Vec::new(),
        paren_token: Default::default(),
        expr: Box::new(e),
    })
}

pub(super) fn binary(l: Expr, op: syn::BinOp, r: Expr) -> Expr {
    Expr::Binary(syn::ExprBinary { attrs: Vec::new(), left: Box::new(l), op, right: Box::new(r) })
}

/// The expression `name`.
pub(super) fn path(name: Ident) -> Expr {
    Expr::Path(syn::ExprPath { attrs: Vec::new(), qself: None, path: name.into() })
}

/// `let name = e;`, built directly (parsing it from tokens costs more than the rest of the
/// emission for large mechanisms).
pub(super) fn let_stmt(name: Ident, e: Expr) -> syn::Stmt {
    syn::Stmt::Local(syn::Local {
        attrs: Vec::new(),
        let_token: Default::default(),
        pat: syn::Pat::Ident(syn::PatIdent {
            attrs: Vec::new(),
            by_ref: None,
            mutability: None,
            ident: name,
            subpat: None,
        }),
        init: Some(syn::LocalInit {
            eq_token: Default::default(),
            expr: Box::new(e),
            diverge: None,
        }),
        semi_token: Default::default(),
    })
}

/// `target = value;`, or `target op= rhs;` when value is `target op rhs` (clippy's
/// `assign_op_pattern`); the same floating-point operation either way.
pub(super) fn assign(target: Expr, value: Expr) -> syn::Stmt {
    use quote::ToTokens;
    let same = |e: &Expr| e.to_token_stream().to_string() == target.to_token_stream().to_string();
    if let Expr::Binary(b) = &value
        && same(&b.left)
    {
        let op = match b.op {
            syn::BinOp::Add(_) => Some(syn::BinOp::AddAssign(Default::default())),
            syn::BinOp::Sub(_) => Some(syn::BinOp::SubAssign(Default::default())),
            syn::BinOp::Mul(_) => Some(syn::BinOp::MulAssign(Default::default())),
            syn::BinOp::Div(_) => Some(syn::BinOp::DivAssign(Default::default())),
            _ => None,
        };
        if let Some(op) = op {
            return syn::Stmt::Expr(
                binary(target, op, (*b.right).clone()),
                Some(Default::default()),
            );
        }
    }
    syn::Stmt::Expr(
        Expr::Assign(syn::ExprAssign {
            attrs: Vec::new(),
            left: Box::new(target),
            eq_token: Default::default(),
            right: Box::new(value),
        }),
        Some(Default::default()),
    )
}

/// `array[i]`, `array[i][j]`, … .
pub(super) fn element(array: &str, indices: &[usize]) -> Expr {
    indices.iter().fold(path(ident(array)), |e, &k| {
        Expr::Index(syn::ExprIndex {
            attrs: Vec::new(),
            expr: Box::new(e),
            bracket_token: Default::default(),
            index: Box::new(Expr::Lit(syn::ExprLit {
                attrs: Vec::new(),
                lit: syn::Lit::Int(syn::LitInt::from(index(k))),
            })),
        })
    })
}

/// A function item with `stmts` as its body, the signature parsed from `signature` (the
/// statements are not turned into tokens and parsed again).
pub(super) fn item_fn(mut signature: syn::ItemFn, stmts: Vec<syn::Stmt>) -> syn::Item {
    signature.block.stmts = stmts;
    syn::Item::Fn(signature)
}

pub(super) fn neg(e: Expr) -> Expr {
    Expr::Unary(syn::ExprUnary {
        attrs: Vec::new(),
        op: syn::UnOp::Neg(Default::default()),
        expr: Box::new(e),
    })
}

/// `runtime::math::name(arg)`: `core` has no sin, cos or sqrt under no_std.
pub(super) fn call(name: &str, arg: Expr) -> Expr {
    let name = ident(name);
    parse_quote!(runtime::math::#name(#arg))
}

/// The constants clippy's `approx_constant` (a deny lint) knows, with the number of
/// characters a literal needs before it is compared (clippy's `min_digits`).
pub(super) const KNOWN: [(f64, &str, usize); 19] = [
    (std::f64::consts::E, "E", 4),
    (std::f64::consts::FRAC_1_PI, "FRAC_1_PI", 4),
    (std::f64::consts::FRAC_1_SQRT_2, "FRAC_1_SQRT_2", 5),
    (std::f64::consts::FRAC_2_PI, "FRAC_2_PI", 5),
    (std::f64::consts::FRAC_2_SQRT_PI, "FRAC_2_SQRT_PI", 5),
    (std::f64::consts::FRAC_PI_2, "FRAC_PI_2", 5),
    (std::f64::consts::FRAC_PI_3, "FRAC_PI_3", 5),
    (std::f64::consts::FRAC_PI_4, "FRAC_PI_4", 5),
    (std::f64::consts::FRAC_PI_6, "FRAC_PI_6", 5),
    (std::f64::consts::FRAC_PI_8, "FRAC_PI_8", 5),
    (std::f64::consts::LN_10, "LN_10", 5),
    (std::f64::consts::LN_2, "LN_2", 5),
    (std::f64::consts::LOG10_E, "LOG10_E", 5),
    (std::f64::consts::LOG2_E, "LOG2_E", 5),
    (std::f64::consts::LOG2_10, "LOG2_10", 5),
    (std::f64::consts::LOG10_2, "LOG10_2", 5),
    (std::f64::consts::PI, "PI", 3),
    (std::f64::consts::SQRT_2, "SQRT_2", 5),
    (std::f64::consts::TAU, "TAU", 3),
];

/// Whether clippy would read the literal `text` as an approximation of `c`: it is longer
/// than `min_digits` and is a prefix of `c`'s digits or `c` rounded to as many decimals.
pub(super) fn looks_like(text: &str, c: f64, min_digits: usize) -> bool {
    if text.len() <= min_digits {
        return false;
    }
    if c.to_string().starts_with(text) {
        return true;
    }
    text.find('.').is_some_and(|dot| format!("{c:.*}", text.len() - dot - 1) == text)
}

/// A non-negative float literal: `{:?}` (shortest round trip), the named constant when it is
/// one exactly, and `f64::from_bits` for values that merely look like one.
pub(super) fn literal(v: f64) -> Expr {
    debug_assert!(v >= 0.0 && v.is_finite());
    let text = format!("{v:?}");
    for &(c, name, min_digits) in &KNOWN {
        if v == c {
            let name = ident(name);
            return parse_quote!(core::f64::consts::#name);
        }
        if looks_like(&text, c, min_digits) {
            let bits = Literal::u64_unsuffixed(v.to_bits());
            return parse_quote!(f64::from_bits(#bits));
        }
    }
    Expr::Lit(syn::ExprLit {
        attrs: Vec::new(),
        lit: syn::Lit::Float(syn::LitFloat::new(&text, Span::call_site())),
    })
}

pub(super) fn param(name: &str, used: bool) -> Ident {
    ident(&if used { name.to_owned() } else { format!("_{name}") })
}

pub(super) fn index(k: usize) -> Literal {
    Literal::usize_unsuffixed(k)
}

/// A literal for any finite value (negative ones as unary minus).
pub(super) fn literal_signed(v: f64) -> Expr {
    if v < 0.0 { neg(literal(-v)) } else { literal(v) }
}
