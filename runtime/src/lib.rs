//! The `no_std`, allocation-free runtime that generated mechanism solvers are compiled against.
//!
//! It holds the [`Mechanism`] trait that generated code implements, an in-place LU
//! factorisation with partial pivoting ([`lu`]) and a bounded Newton iteration ([`newton`]);
//! the step-by-step solver follows.
//! It knows nothing about symbols, descriptions or bodies: a mechanism is a square system of
//! `N` equations in `N` unknowns, with `N` from 1 to several hundred.
//!
//! The crate has no dependencies and uses neither `alloc` nor `unsafe`, so nothing here
//! allocates, by construction.

#![no_std]

pub mod lu;
mod mechanism;
pub mod newton;

#[cfg(test)]
mod fixtures;

pub use mechanism::Mechanism;
pub use newton::{NewtonError, NewtonOptions, NewtonReport};
