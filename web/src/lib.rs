//! The mechanism for a web page: the crate's plant under its co-simulation driver, the same
//! code the FMUs run, behind a handful of functions of numbers that a WebAssembly module
//! exports to JavaScript ([`exports`]). No FMI here: a page is its own master.
//!
//! - [`session`]: one run (set, initialise, step, read), in Rust terms;
//! - [`exports`]: that session as the module's functions, and the variables as JSON.

pub mod exports;
pub mod session;
