//! The integration tests, one module per file of `tests/`, linked into one binary (a link per file cost
//! a newcomer's first `cargo test` 24 links of the whole library). Run one file's tests with
//! `cargo test --test suite FILE::` (e.g. `cargo test --release --test suite fuzz::`).

mod common;

mod allocation;
mod architecture;
mod assemble;
mod calibrate;
mod calibrate_legs;
mod cli;
mod cli_surface;
mod closed_forms;
mod compensate;
mod diagnose;
mod fuzz;
mod hessians;
mod jacobians;
mod loaded;
mod loaded_trust;
mod msa;
mod orthoglide;
mod parquet;
mod plan;
mod plot;
mod robustness;
mod serial;
mod serial_tips;
mod serial_tree;
mod shard;
mod status;
mod stewart;
mod sweep;
mod writeback;
