//! Axis location.
