//! Model tests, built into one binary with the shared harness.

mod harness;

mod camera;
mod laser;
