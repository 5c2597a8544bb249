//! The leg seam and the sum over legs at the platform.
pub mod assembly;
pub mod command;
pub mod compliance;
pub mod leg;
pub mod leg_state;
pub mod loaded;
pub mod manipulator;
pub mod msa_leg;
pub mod serial;
pub mod vjm_leg;
