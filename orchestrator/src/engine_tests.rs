//! Engine tests: fault survival on the simulated bench.
