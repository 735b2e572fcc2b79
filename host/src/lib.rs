//! The host side of the strain wave gear tool chain, one folder per step of the data path
//! (see ARCHITECTURE.md): `input` reads files, `prepare` turns samples into fit data, `fit`
//! identifies the model, `diagnose` finds the physics it misses, `report` writes what people
//! and `push` read, `simulate` makes recordings, `link` talks to the joint, `hil` runs the
//! joint's firmware against a simulated joint in lockstep. The `swg-host` binary (`cli/`)
//! parses arguments and prints.
// Small dense matrix code reads better with indices, and `!(x > 0.0)` is how NaN is refused.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]
pub mod diagnose;
pub mod fit;
pub mod gear;
pub mod hil;
pub mod input;
pub mod link;
pub mod numeric;
pub mod predict;
pub mod prepare;
pub mod record;
pub mod report;
pub mod simulate;
