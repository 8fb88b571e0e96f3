//! The workspace's integration tests: the thesis' seed examples against YOUNG's output, their
//! closed forms and an independent solution; the RSSR against Appendix C; and the invariants
//! every analysis must keep.
//!
//! The reference data live in `tests/reference/seed-examples` (see `tests/reference/README.md`);
//! the tests say, at each comparison, which reference value is trusted and how far.

#[cfg(test)]
mod arm_ik;
#[cfg(test)]
mod block_orders;
#[cfg(test)]
mod block_solver;
#[cfg(test)]
mod digits;
#[cfg(test)]
mod embedded_inputs;
#[cfg(test)]
mod generated_engine;
#[cfg(test)]
mod harness;
#[cfg(test)]
mod hostile;
#[cfg(test)]
mod hostile_codegen;
#[cfg(test)]
mod large_generated;
#[cfg(test)]
mod named_outputs;
#[cfg(test)]
mod only_outputs;
#[cfg(test)]
mod random_mechanisms;
#[cfg(test)]
mod redundancy;
#[cfg(test)]
mod rssr_reference;
#[cfg(test)]
mod runtime_step;
#[cfg(test)]
mod scale_invariance;
#[cfg(test)]
mod seed_examples;
#[cfg(test)]
mod shared_expand;
#[cfg(test)]
mod single_precision;
#[cfg(test)]
mod sparse_engine;
#[cfg(test)]
mod split_modules;
#[cfg(test)]
mod stability;
#[cfg(test)]
mod stewart;
#[cfg(test)]
mod stewart_legs;
#[cfg(test)]
mod structured_lu;
#[cfg(test)]
mod substitution;
#[cfg(test)]
mod time_terms;
