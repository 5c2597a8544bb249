//! Batch jobs that turn a request into rows: one point, a map, a design sweep.
pub mod assemble;
pub mod compensate;
pub mod curve;
pub mod map;
pub mod point;
pub mod sweep;
pub mod warm_start;
