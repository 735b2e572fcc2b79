//! The host side of the strain wave gear tool chain: readers for bench data, the model fit,
//! its baselines, simulation and plots. The `swg-host` binary is a thin layer over this.
// Small dense matrix code reads better with indices, and `!(x > 0.0)` is how NaN is refused.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]
pub mod baselines;
pub mod diagnose;
pub mod effects;
pub mod fit;
pub mod input;
pub mod linalg;
pub mod link;
pub mod optimize;
pub mod output;
pub mod paramsfile;
pub mod plot;
pub mod prepare;
pub mod report;
pub mod segment;
pub mod simulate;
pub mod table;
