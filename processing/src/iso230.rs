//! ISO 230-2 statistics.
