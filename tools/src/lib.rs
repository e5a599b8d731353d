//! The `cloth` tool's library part: the hard-case suite, shared by
//! `cloth study stability` and this crate's `stability` test, and the
//! studies' CSV tables.

pub mod stability;
pub mod table;
