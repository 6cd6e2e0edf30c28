//! Iterative reconstruction: GAP, ADMM and plug-and-play, written against [`crate::LinearOperator`].
