//! What the commands hand to people and to the next step: the fit's JSON (also the parameter
//! file `push` reads), the diagnosis' JSON and text, the pictures, and files written whole
//! (all of a command's outputs or none), and the check that no figure is NaN or infinite.
pub mod diagnose;
pub mod diagnose_runs;
pub mod finite;
pub mod fit;
pub mod output;
pub mod params;
pub mod plot;
pub mod predict;
