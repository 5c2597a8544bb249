//! CSV rows and Parquet tables, text reports, and files written atomically.
pub mod calibration;
pub mod diagnosis;
pub mod parquet;
pub mod report;
pub mod sink;
pub mod table;
