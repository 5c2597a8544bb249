//! stiff: stiffness of parallel robots by the Virtual Joint Method (see ARCHITECTURE.md).
#![warn(missing_docs)]
pub mod batch;
pub mod beam;
pub mod cli;
pub mod columns;
pub mod diagnose;
pub mod expr;
pub mod kinematics;
pub mod linalg;
pub mod model;
pub mod msa;
pub mod output;
pub mod platform;
pub mod plot;
pub mod study;
pub mod vjm;
