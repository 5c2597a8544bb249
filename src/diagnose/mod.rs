//! `stiff diagnose` and `stiff synth`: where measured deflections and the model disagree, which physical
//! effect of a library explains it (with the statistics to back the name), and synthetic measurements with
//! hidden effects to test the workflow and plan experiments.
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
