//! Input files: the TOML description of a manipulator, grids and points, and their validation.
pub mod assembly_errors;
pub mod build;
mod build_msa;
mod build_urdf;
pub mod effect;
pub mod error;
pub mod grid;
pub mod schema;
pub mod urdf;

pub use build::{load_manipulator, load_model, parse_manipulator, parse_with, Model};
pub use error::InputError;
