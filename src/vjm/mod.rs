//! The Virtual Joint Method for one chain: springs and the unloaded stiffness (paper 001 eq 9).
pub mod equilibrium;
pub mod parallelogram;
pub mod spring;
pub mod stiffness;
