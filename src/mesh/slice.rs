//! Slicing.
