//! Evaluation for cassi: the four-scenario protocol's figures (and, later,
//! scenarios, sweeps, tables and reports).

pub mod figures;
