//! One module per subcommand.

pub mod bag;
pub mod calibrate;
pub mod convert;
pub mod demo;
pub mod detect;
pub mod evaluate;
pub mod localize;
pub mod report;
pub mod rig;
pub mod ros;
pub mod scan;
pub mod session;
pub mod simulate;
pub mod stripe;
pub mod triangulate;
