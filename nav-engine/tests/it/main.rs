//! nav-engine's integration tests, one binary: one module per topic. They use the public API
//! only, so the filter's instantiations are compiled once, in the library.

mod errors;
mod live;
