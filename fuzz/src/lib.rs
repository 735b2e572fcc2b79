//! The fuzz targets' bodies, shared with the corpus replay test (`host/tests/fuzz_corpus.rs`,
//! which includes these files by path): each takes the fuzzer's bytes and panics only on a
//! broken invariant.
pub mod frames;
pub mod host;
