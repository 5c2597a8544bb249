//! Input files: the TOML description of a manipulator, grids and points, and their validation.
pub mod build;
pub mod error;
pub mod expr;
pub mod grid;
pub mod schema;

pub use build::{load_manipulator, parse_manipulator};
pub use error::InputError;
