//! Evaluation of reconstruction and self-calibration: the four-scenario
//! protocol (Ideal, Assumed, Corrected, Oracle) per scene, summaries,
//! tables, figures and a report. Above `cassi-core` and `cassi-io`; the CLI
//! (`cassi eval`) is a thin layer over it. Learned methods (MST-S/L, HDNet,
//! PnP-HSICNN) run with the `nets` feature.

#![forbid(unsafe_code)]

pub mod digests;
pub mod figures;
pub mod jobs;
pub mod learned;
pub mod machine;
pub mod method;
pub mod protocol;
pub mod records;
pub mod report;
pub mod shard;
pub mod study;
pub mod study_figures;
pub mod summary;
pub mod sweep;
pub mod sweep_rows;
pub mod tables;
pub mod weights;
