//! The model description as the runner reads it: the project's one reader of
//! `modelDescription.xml` in Rust (the crate `fmi-description`, which xtask reads with too).

pub use fmi_description::*;
