//! Named constants for the coefficients of the drivers' laws, so that the emitted equations
//! read `LAW_CRANK_VELOCITY * t` where the description says so, and not an anonymous literal.
//!
//! Only coefficients that reach the code unfolded can be named (a product such as
//! amplitude × frequency in ν is a new number and stays a literal). A literal is named when
//! its value is exactly that of one coefficient: the constant has the same bits, so the code
//! computes exactly what it computed with the literal. Values that the equations produce by
//! themselves (0, ±½, ±1, ±2) and values two coefficients share are never named, so that
//! what a name says is almost always where the number came from; a geometric constant that
//! happens to equal a coefficient to the last bit shows under the coefficient's name.

use std::collections::BTreeMap;

use syn::visit_mut::VisitMut;
use syn::{Expr, Ident, parse_quote};

use super::docs::markdown_escaped;
use super::syntax::{ident, literal_signed};
use crate::model::{Law, Mechanism};

/// The functions whose literals are named: the equations and `expand`, not the LU, whose
/// folded entries are products of several description values.
const NAMED_IN: [&str; 5] = ["residual", "jacobian", "velocity_rhs", "acceleration_rhs", "expand"];

/// One named coefficient.
struct Coefficient {
    name: Ident,
    value: f64,
    doc: String,
    used: bool,
}

/// The law coefficients that may be named, by the bits of their value.
pub(super) struct LawNames {
    coefficients: Vec<Coefficient>,
    by_bits: BTreeMap<u64, usize>,
}

impl LawNames {
    /// The coefficients of `mech`'s driver laws that can be named (see the module docs).
    pub(super) fn new(mech: &Mechanism) -> Self {
        let mut all: Vec<Coefficient> = Vec::new();
        for (k, d) in mech.drivers.iter().enumerate() {
            let stem = stem(&d.name, k);
            let fields: Vec<(&str, f64)> = match d.law {
                Law::Polynomial { start, velocity, acceleration } => {
                    vec![("start", start), ("velocity", velocity), ("acceleration", acceleration)]
                }
                Law::Harmonic { offset, amplitude, frequency, phase } => vec![
                    ("offset", offset),
                    ("amplitude", amplitude),
                    ("frequency", frequency),
                    ("phase", phase),
                ],
            };
            for (field, value) in fields {
                let doc = format!(
                    " The `{field}` of the law of driver \"{}\".",
                    markdown_escaped(&d.name)
                );
                let name = ident(&format!("{stem}_{}", field.to_ascii_uppercase()));
                all.push(Coefficient { name, value, doc, used: false });
            }
        }
        let mut count: BTreeMap<u64, usize> = BTreeMap::new();
        for c in &all {
            *count.entry(c.value.to_bits()).or_default() += 1;
        }
        let coefficients: Vec<Coefficient> = all
            .into_iter()
            .filter(|c| count[&c.value.to_bits()] == 1 && !trivial(c.value))
            .collect();
        let by_bits =
            coefficients.iter().enumerate().map(|(k, c)| (c.value.to_bits(), k)).collect();
        LawNames { coefficients, by_bits }
    }

    /// Replaces the literals of the coefficients in `item` by their names, when `item` is one
    /// of the functions that name them (see [`NAMED_IN`]).
    pub(super) fn apply(&mut self, item: &mut syn::Item) {
        if self.coefficients.is_empty() {
            return;
        }
        if let syn::Item::Fn(f) = item {
            let name = f.sig.ident.to_string();
            if NAMED_IN.iter().any(|n| name == *n || name.starts_with(&format!("{n}_"))) {
                self.visit_item_fn_mut(f);
            }
        }
    }

    /// `pub const` items for the coefficients some function reads, in the drivers' order.
    pub(super) fn items(&self) -> Vec<syn::Item> {
        self.coefficients
            .iter()
            .filter(|c| c.used)
            .map(|c| {
                let (doc, name, value) = (&c.doc, &c.name, literal_signed(c.value));
                parse_quote! {
                    #[doc = #doc]
                    pub const #name: f64 = #value;
                }
            })
            .collect()
    }

    /// The name of the coefficient whose value is `v`, marking it used.
    fn name_of(&mut self, v: f64) -> Option<Expr> {
        let &k = self.by_bits.get(&v.to_bits())?;
        let c = &mut self.coefficients[k];
        c.used = true;
        let name = &c.name;
        Some(parse_quote!(#name))
    }
}

impl VisitMut for LawNames {
    fn visit_expr_mut(&mut self, e: &mut Expr) {
        // A literal is named as a whole, sign included: the 0.2 of a −0.2 (say a folded
        // −a/2) is not the coefficient 0.2.
        if let Some(v) = value(e) {
            if let Some(name) = self.name_of(v) {
                *e = name;
            }
            return;
        }
        syn::visit_mut::visit_expr_mut(self, e);
    }
}

/// The value of a literal as the emitter writes them (`1.5`, `-1.5`, `f64::from_bits(…)`).
fn value(e: &Expr) -> Option<f64> {
    match e {
        Expr::Lit(syn::ExprLit { lit: syn::Lit::Float(f), .. }) => f.base10_parse().ok(),
        Expr::Unary(u) if matches!(u.op, syn::UnOp::Neg(_)) => value(&u.expr).map(|v| -v),
        Expr::Call(c) if c.args.len() == 1 => {
            let Expr::Path(p) = &*c.func else { return None };
            let is_from_bits = p.path.segments.len() == 2
                && p.path.segments[0].ident == "f64"
                && p.path.segments[1].ident == "from_bits";
            match c.args.first() {
                Some(Expr::Lit(syn::ExprLit { lit: syn::Lit::Int(i), .. })) if is_from_bits => {
                    i.base10_parse::<u64>().ok().map(f64::from_bits)
                }
                _ => None,
            }
        }
        _ => None,
    }
}

/// Values the equations produce by themselves, which a name would misattribute.
fn trivial(v: f64) -> bool {
    [0.0, 0.5, 1.0, 2.0].contains(&v.abs())
}

/// `LAW_CRANK` for a driver named `crank`; `LAW_3` for the fourth driver when its name is
/// not a lower-case identifier.
fn stem(name: &str, k: usize) -> String {
    let identifier = name.len() <= 40
        && name.starts_with(|c: char| c.is_ascii_lowercase())
        && name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    if identifier { format!("LAW_{}", name.to_ascii_uppercase()) } else { format!("LAW_{k}") }
}
