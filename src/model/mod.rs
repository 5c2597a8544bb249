//! Input files: the TOML description of a manipulator, grids and points, and their validation.
pub mod build;
mod build_msa;
pub mod error;
pub mod errors;
pub mod expr;
pub mod grid;
pub mod schema;

pub use build::{load_manipulator, parse_manipulator, parse_with};
pub use error::InputError;
