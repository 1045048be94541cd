//! Integration tests of the `relief` binary, in one test binary (one link for the crate).
//! Each module is one area; `common` holds the helpers they share.

mod common;

mod cli;
mod dictionary;
mod export;
mod failures;
mod hostile_plans;
mod landscape;
mod limits;
mod messages;
mod patch;
mod sparse;
mod tile;
mod tile_flow;
mod tile_masks;
mod volume;
mod wavelet;
