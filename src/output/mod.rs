//! CSV rows, text reports, and files written atomically.
pub mod report;
pub mod sink;
pub mod table;
