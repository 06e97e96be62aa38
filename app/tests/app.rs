//! The app's integration tests, one module per subject (see ARCHITECTURE.md), linked
//! into one binary: one link of the graphics stack instead of eleven, and the two test
//! threads shared by every module's tests (run one after another, a module with one
//! long test left a core idle).

mod common;

mod cli;
mod cluster;
mod fit;
mod gpu;
mod headless;
mod input;
mod interrupted;
mod lifecycle;
mod mobile;
mod paint;
mod scene_build;
mod shard;
mod tissue;
mod touch;
mod training;
