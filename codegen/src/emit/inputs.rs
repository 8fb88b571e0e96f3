//! What a module with input drivers (`law = "input"`) adds: the `Inputs` type with one named
//! field per input driver, the inputs the initial estimates stand at, and a mechanism type
//! that holds the inputs' [`runtime::input::Segment`] and implements `runtime::input::Driven`,
//! so that `runtime::Solver::advance_with` moves its inputs under step control.
//!
//! Input driver names reach the code as field names: validation allows only lower-case
//! identifiers that are not keywords for them (`validate::names::input_name_problem`).

use syn::parse_quote;

use super::syntax::{ident, index, literal_signed};
use crate::model::{Mechanism, type_name};
use crate::symbolic::Symbolic;

/// `Inputs`, its conversions and `INITIAL_INPUTS` (nothing without input drivers). `INPUTS`
/// and `INPUT_NAMES` are among the name tables (`outputs::names`).
pub(super) fn items(mech: &Mechanism, sys: &Symbolic) -> Vec<syn::Item> {
    if sys.inputs.is_empty() {
        return Vec::new();
    }
    let names: Vec<syn::Ident> =
        sys.inputs.iter().map(|d| ident(&mech.drivers[d.driver].name)).collect();
    let docs = sys
        .inputs
        .iter()
        .map(|d| format!(" s, ṡ and s̈ of the input driver `{}`.", mech.drivers[d.driver].name));
    let slots = (0..names.len()).map(index);
    let initial = sys.inputs.iter().map(|d| literal_signed(d.initial));
    vec![
        parse_quote! {
            /// The values of the input drivers at one instant, one field per input driver
            /// (in [`INPUT_NAMES`] order).
            #[derive(Clone, Copy, Debug, Default, PartialEq)]
            pub struct Inputs {
                #(#[doc = #docs] pub #names: runtime::input::Input<f64>,)*
            }
        },
        parse_quote! {
            impl Inputs {
                /// `[s, ṡ, s̈]` of every input driver, in [`INPUT_NAMES`] order (what
                /// `runtime::Solver::advance_with` takes).
                #[must_use]
                pub const fn to_array(&self) -> [[f64; 3]; INPUTS] {
                    [#(self.#names.to_array()),*]
                }

                /// The inputs of `u`, `[s, ṡ, s̈]` per input driver in [`INPUT_NAMES`] order.
                #[must_use]
                pub const fn from_array(u: [[f64; 3]; INPUTS]) -> Self {
                    Inputs { #(#names: runtime::input::Input::from_array(u[#slots]),)* }
                }
            }
        },
        parse_quote! {
            /// The inputs the initial estimates [`Q0`] stand at: the value each input driver
            /// prescribes there, at rest (ṡ = s̈ = 0).
            pub const INITIAL_INPUTS: Inputs = Inputs {
                #(#names: runtime::input::Input { value: #initial, rate: 0.0, acceleration: 0.0 },)*
            };
        },
    ]
}

/// The mechanism type of a module with input drivers, with its `runtime::Mechanism` and
/// `runtime::input::Driven` impls and the structured LU's items.
pub(super) fn mechanism_type(mech: &Mechanism, structured: Vec<syn::ImplItem>) -> Vec<syn::Item> {
    let ty = ident(&type_name(&mech.name));
    let doc = format!(
        " The mechanism `{}` as a [`runtime::Mechanism`] whose input drivers take their values \
         from the segment it holds: the inputs where the solver stands and where it is asked \
         to go, interpolated in between (`runtime::input::Segment`). Move them with \
         `runtime::Solver::advance_with`.",
        mech.name
    );
    vec![
        parse_quote! {
            #[doc = #doc]
            #[derive(Clone, Copy, Debug, PartialEq)]
            pub struct #ty {
                segment: runtime::input::Segment<f64, INPUTS>,
            }
        },
        parse_quote! {
            impl #ty {
                /// The mechanism standing at time `t` with the inputs `inputs`.
                #[must_use]
                pub const fn new(t: f64, inputs: &Inputs) -> Self {
                    Self { segment: runtime::input::Segment::new(t, inputs.to_array()) }
                }

                /// The inputs at `t`: those of the last call at its time, interpolated between
                /// it and the point the solver stood on before.
                #[must_use]
                pub fn inputs(&self, t: f64) -> Inputs {
                    Inputs::from_array(self.segment.at(t))
                }
            }
        },
        parse_quote! {
            impl Default for #ty {
                /// The mechanism at the grid's first time point, at [`INITIAL_INPUTS`].
                fn default() -> Self {
                    Self::new(T_START, &INITIAL_INPUTS)
                }
            }
        },
        parse_quote! {
            impl runtime::input::Driven<INPUTS, f64> for #ty {
                fn segment(&self) -> &runtime::input::Segment<f64, INPUTS> {
                    &self.segment
                }
                fn segment_mut(&mut self) -> &mut runtime::input::Segment<f64, INPUTS> {
                    &mut self.segment
                }
            }
        },
        parse_quote! {
            impl runtime::Mechanism<N> for #ty {
                fn residual(&self, q: &[f64; N], t: f64, phi: &mut [f64; N]) {
                    residual(q, t, &self.inputs(t), phi);
                }
                fn jacobian(&self, q: &[f64; N], t: f64, jac: &mut [[f64; N]; N]) {
                    jacobian(q, t, &self.inputs(t), jac);
                }
                fn residual_jacobian(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian(q, t, &self.inputs(t), phi, jac);
                }
                fn velocity_rhs(&self, q: &[f64; N], t: f64, nu: &mut [f64; N]) {
                    velocity_rhs(q, t, &self.inputs(t), nu);
                }
                fn acceleration_rhs(&self, q: &[f64; N], qd: &[f64; N], t: f64, gamma: &mut [f64; N]) {
                    acceleration_rhs(q, qd, t, &self.inputs(t), gamma);
                }
                fn normalize(&self, q: &mut [f64; N]) {
                    normalize(q);
                }
                #(#structured)*
            }
        },
    ]
}
