pub mod calibrate;
pub mod combine;
pub mod demo;
pub mod eval;
pub mod info;
pub mod inputs;
pub mod reconstruct;
pub mod simulate;
