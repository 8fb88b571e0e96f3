//! The floating-point type of an emitted module, and the rewrite of a double-precision module
//! into single precision.
//!
//! The emitter writes every module in `f64`; [`to_f32`] then rewrites the syn items: the type
//! `f64` becomes `f32`, every float literal is rounded to the nearest `f32` (and written so that
//! clippy's `approx_constant` accepts it), `core::f64::consts` becomes `core::f32::consts`, and
//! the runtime's types take `f32` as their scalar parameter. The arithmetic is the same
//! expression tree, evaluated in single precision; the static pivot orders and the constant
//! entries of the structured LU are those chosen in double precision.

use proc_macro2::{Literal, Span};
use syn::visit_mut::{self, VisitMut};
use syn::{Expr, parse_quote};

use super::syntax::{KNOWN, looks_like};

/// The floating-point type a module is emitted in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Scalar {
    /// Double precision, the default: the generated solver reaches the description's tolerance.
    #[default]
    F64,
    /// Single precision: about 7 significant digits, for control loops whose accuracy needs
    /// stop around 1e-5 of the mechanism's size.
    F32,
}

impl Scalar {
    /// The Rust name of the type.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Scalar::F64 => "f64",
            Scalar::F32 => "f32",
        }
    }
}

impl std::str::FromStr for Scalar {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "f64" => Ok(Scalar::F64),
            "f32" => Ok(Scalar::F32),
            _ => Err(format!("unknown scalar type {s:?}, expected f64 or f32")),
        }
    }
}

/// Rewrites an item emitted in `f64` into `f32` (see the module docs).
pub fn to_f32(item: &mut syn::Item) {
    ToF32.visit_item_mut(item);
}

/// The visitor behind [`to_f32`].
struct ToF32;

/// Whether `path` is the single identifier `name`.
fn is_ident(path: &syn::Path, name: &str) -> bool {
    path.leading_colon.is_none() && path.segments.len() == 1 && path.segments[0].ident == name
}

/// The path's segments as strings, without generic arguments.
fn segments(path: &syn::Path) -> Vec<String> {
    path.segments.iter().map(|s| s.ident.to_string()).collect()
}

/// A non-negative `f32` literal: the shortest round-trip text, the named `f32` constant when
/// it is one exactly, and `f32::from_bits` when clippy would take the text for a constant.
fn literal(v: f32) -> Expr {
    debug_assert!(v >= 0.0 && v.is_finite());
    let text = format!("{v:?}");
    for &(c, name, min_digits) in &KNOWN {
        #[expect(clippy::cast_possible_truncation, reason = "the f32 constant is wanted")]
        let c32 = c as f32;
        if v == c32 {
            let name = syn::Ident::new(name, Span::call_site());
            return parse_quote!(core::f32::consts::#name);
        }
        if looks_like(&text, c, min_digits) || looks_like(&text, f64::from(c32), min_digits) {
            let bits = Literal::u32_unsuffixed(v.to_bits());
            return parse_quote!(f32::from_bits(#bits));
        }
    }
    Expr::Lit(syn::ExprLit {
        attrs: Vec::new(),
        lit: syn::Lit::Float(syn::LitFloat::new(&text, Span::call_site())),
    })
}

/// The `f32` nearest to an `f64`.
#[expect(clippy::cast_possible_truncation, reason = "rounding to f32 is the point")]
fn round(v: f64) -> f32 {
    v as f32
}

impl VisitMut for ToF32 {
    fn visit_type_path_mut(&mut self, ty: &mut syn::TypePath) {
        if ty.qself.is_none() && is_ident(&ty.path, "f64") {
            ty.path = parse_quote!(f32);
            return;
        }
        let names = segments(&ty.path);
        if names == ["runtime", "lu", "PivotInfo"] {
            ty.path = parse_quote!(runtime::lu::PivotInfo<f32>);
            return;
        }
        if names == ["runtime", "lu", "Singular"] {
            ty.path = parse_quote!(runtime::lu::Singular<f32>);
            return;
        }
        visit_mut::visit_type_path_mut(self, ty);
    }

    fn visit_path_mut(&mut self, path: &mut syn::Path) {
        // `impl runtime::Mechanism<N> for …`: the scalar parameter follows N.
        if segments(path) == ["runtime", "Mechanism"] {
            *path = parse_quote!(runtime::Mechanism<N, f32>);
            return;
        }
        visit_mut::visit_path_mut(self, path);
    }

    fn visit_expr_mut(&mut self, expr: &mut Expr) {
        match expr {
            Expr::Lit(syn::ExprLit { lit: syn::Lit::Float(f), .. }) => {
                if let Ok(v) = f.base10_parse::<f64>() {
                    *expr = literal(round(v));
                }
                return;
            }
            Expr::Call(call) => {
                // `f64::from_bits(b)`: a literal clippy would have misread, rounded anew.
                if let (Expr::Path(func), [Expr::Lit(arg)]) =
                    (&*call.func, &call.args.iter().collect::<Vec<_>>()[..])
                    && segments(&func.path) == ["f64", "from_bits"]
                    && let syn::Lit::Int(bits) = &arg.lit
                    && let Ok(bits) = bits.base10_parse::<u64>()
                {
                    *expr = literal(round(f64::from_bits(bits)));
                    return;
                }
            }
            Expr::Path(p) => {
                let names = segments(&p.path);
                if names.len() == 4 && names[..3] == ["core", "f64", "consts"] {
                    let name = syn::Ident::new(&names[3], Span::call_site());
                    *expr = parse_quote!(core::f32::consts::#name);
                    return;
                }
                if names == ["runtime", "lu", "MAX_MULTIPLIER"] {
                    // 10 is exact in both types.
                    *expr = parse_quote!((runtime::lu::MAX_MULTIPLIER as f32));
                    return;
                }
            }
            _ => {}
        }
        visit_mut::visit_expr_mut(self, expr);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rewrite(item: syn::Item) -> String {
        let mut item = item;
        to_f32(&mut item);
        prettyplease::unparse(&syn::File { shebang: None, attrs: Vec::new(), items: vec![item] })
    }

    #[test]
    fn types_literals_and_runtime_paths_become_single_precision() {
        let text = rewrite(parse_quote! {
            pub fn f(q: &[f64; N], jac: &mut [[f64; N]; N]) -> Option<runtime::lu::PivotInfo> {
                let a = 0.1 * q[0] + core::f64::consts::PI + f64::from_bits(4614256656552045848);
                if a.abs() <= runtime::lu::MAX_MULTIPLIER { jac[0][0] = a; }
                None
            }
        });
        assert!(!text.contains("f64"), "{text}");
        // 0.1 rounds to the f32 0.1, whose shortest text is again 0.1.
        assert!(text.contains("0.1 * q[0]"), "{text}");
        assert!(text.contains("core::f32::consts::PI"), "{text}");
        assert!(text.contains("PivotInfo<f32>"), "{text}");
        assert!(text.contains("runtime::lu::MAX_MULTIPLIER as f32"), "{text}");
        // f64::from_bits(4614256656552045848) is π itself, so it becomes the f32 constant.
        assert_eq!(text.matches("core::f32::consts::PI").count(), 2, "{text}");
    }

    #[test]
    fn literals_round_to_the_nearest_f32() {
        let text = rewrite(parse_quote!(
            const X: f64 = 0.123456789012345;
        ));
        assert!(text.contains("0.12345679"), "{text}");
    }

    #[test]
    fn the_mechanism_impl_takes_f32() {
        let text = rewrite(parse_quote! {
            impl runtime::Mechanism<N> for M {}
        });
        assert!(text.contains("runtime::Mechanism<N, f32>"), "{text}");
    }
}
