//! CSV rows, text reports, and files written atomically.
pub mod diagnosis;
pub mod report;
pub mod sink;
pub mod table;
