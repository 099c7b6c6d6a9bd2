//! The fuzzing harness shared by `tests/suite/fuzz.rs` (the test suite's 5,000 mutants) and
//! `examples/fuzz.rs` (the long campaign of scripts/fuzz-campaign.sh): a deterministic
//! mutator of every format's example files, and a runner that sends each mutant through
//! the library under a watchdog, a panic catcher and a counting allocator.
#![allow(dead_code)] // the test and the example use different parts

pub mod alloc;
pub mod corpus;
pub mod mutate;
pub mod run;

#[global_allocator]
static ALLOCATOR: alloc::Counting = alloc::Counting;
