//! The `cloth` tool's library part: the hard-case suite, shared by
//! `cloth study stability` and this crate's `stability` test.

pub mod stability;
