//! Frames, serial chains, their Jacobians, and inverse kinematics.
pub mod chain;
pub mod frame;
pub mod ik;
pub mod line;
