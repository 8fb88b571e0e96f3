//! The no_std, allocation-free runtime that generated mechanism solvers are compiled against.
//!
//! It will hold the `Mechanism` trait, fixed-size LU with partial pivoting and a bounded Newton
//! iteration (issue 3). It knows nothing about symbols or descriptions.

#![no_std]
