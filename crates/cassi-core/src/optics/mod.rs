//! The CASSI optics model.
