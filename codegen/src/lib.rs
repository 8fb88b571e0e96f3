//! mechgen: kinematic analysis of spatial mechanisms described in Cartesian coordinates and
//! Euler parameters (7 per body), after the thesis' program YOUNG, done right.
//!
//! Pipeline: a description file (`desc`, TOML or JSON) is validated into a
//! `model::Mechanism` (`validate`), then analysed by the generic engine (`generic`), which
//! assembles Φ, Φ_q, ν and γ at run time and solves positions by Newton–Raphson, velocities
//! from Φ_q q̇ = ν and accelerations from Φ_q q̈ = γ. `young` imports the thesis' legacy decks;
//! `report` writes the results as the contract's table, CSV or JSON.
//!
//! The feature `cli` (on by default) adds the `mechgen` command line (`cli`) and its charts
//! (`chart`, `plot`); without it, the crate is the model, both engines and the generator, which
//! is what a build script calling [`build::Builder`] needs.

pub mod blocks;
pub mod build;
#[cfg(feature = "cli")]
pub mod chart;
#[cfg(feature = "cli")]
pub mod cli;
pub mod desc;
pub mod diag;
#[cfg(feature = "cli")]
pub mod draw;
pub mod emit;
pub mod engine;
pub mod expr;
pub mod generic;
pub mod inputs;
#[cfg(test)]
mod layers;
pub mod model;
#[cfg(feature = "cli")]
pub mod output;
pub mod pivot;
#[cfg(feature = "cli")]
pub mod plot;
#[cfg(feature = "cli")]
pub mod reference;
pub mod report;
pub mod scale;
pub mod stepping;
pub mod symbolic;
pub mod sync;
#[cfg(any(test, feature = "test-support"))]
pub mod testing;
pub mod validate;
pub mod young;
