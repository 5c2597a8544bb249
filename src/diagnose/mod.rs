//! `stiff diagnose` and `stiff synth`: where measured deflections and the model disagree, which physical
//! effect of a library explains it (with the statistics to back the name), and synthetic measurements with
//! hidden effects to test the workflow and plan experiments.
//!
//! What the folder offers, by entry point:
//! - displacements under load: `diagnose_screened` (`screen.rs`, on `fit.rs` and `select.rs`), its report
//!   and corrected description (`report.rs`), synthetic data (`synth.rs`);
//! - measured positions, a calibration: `calibrate` (`calibrate/`), read by `PositionData` (`positions.rs`);
//! - measurement plans for both: `plan.rs`;
//! - what both fit and test with: `lm.rs` (the least-squares driver) and `stats.rs`.
pub mod calibrate;
pub mod data;
pub mod error;
pub mod fit;
pub mod lm;
pub mod measurement;
pub mod plan;
pub mod positions;
pub mod report;
pub mod screen;
pub mod select;
pub mod stats;
pub mod synth;

pub use calibrate::{calibrate, Calibration, CalibrationOptions};
pub use positions::PositionData;
pub use screen::diagnose_screened;
