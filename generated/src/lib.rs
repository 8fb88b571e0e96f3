//! Generated per-mechanism solvers, one module per shipped example.
//!
//! The code generator does not exist yet (issue 3); this crate will then hold committed,
//! `@generated` modules checked by a freshness test.

#![no_std]
