//! Embedded synthetic data: procedural scenes and random masks.
